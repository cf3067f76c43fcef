/* webproto: HTTP/1.1 request heads and WebSocket frames, parsed and written without I/O. */
#include "tools/webcommon/webproto.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

#include <nettle/sha1.h>

#include "core/base64.h"
#include "core/err.h"

typedef struct {
    int status;
    const char *why;
} bad_t;

static int refuse(bad_t *b, int status, const char *why)
{
    b->status = status;
    b->why = why;
    return -1;
}

/* RFC 9110 tchar: the characters of a method or a header's name. */
static bool is_tchar(unsigned char c)
{
    return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
           (c && strchr("!#$%&'*+-.^_`|~", c));
}

/* The end of the head (just past its blank line), 0 if not there yet. */
static size_t head_end(const char *buf, size_t len)
{
    for (size_t i = 0; i + 1 < len; i++)
        if (buf[i] == '\n') {
            if (buf[i + 1] == '\n')
                return i + 2;
            if (buf[i + 1] == '\r' && i + 2 < len && buf[i + 2] == '\n')
                return i + 3;
        }
    return 0;
}

/* The next line of [*p, end) without its CR LF; NULL at the end or on a bare CR. */
static const char *next_line(const char **p, const char *end, size_t *n, bool *bare_cr)
{
    const char *s = *p, *nl = memchr(s, '\n', (size_t)(end - s));
    if (!nl)
        return NULL;
    *p = nl + 1;
    *n = (size_t)(nl - s);
    if (*n && s[*n - 1] == '\r')
        (*n)--;
    *bare_cr = memchr(s, '\r', *n) != NULL;
    return s;
}

static int parse_request_line(webreq_t *r, const char *s, size_t n, bad_t *b)
{
    size_t i = 0;
    while (i < n && is_tchar((unsigned char)s[i]))
        i++;
    if (i == 0 || i >= sizeof r->method || i >= n || s[i] != ' ')
        return refuse(b, 400, "malformed request line");
    memcpy(r->method, s, i);
    r->method[i] = 0;
    const char *t = s + i + 1, *sp = memchr(t, ' ', n - i - 1);
    if (!sp || *t != '/')
        return refuse(b, 400, "malformed request target");
    size_t tl = (size_t)(sp - t);
    for (size_t k = 0; k < tl; k++)
        if ((unsigned char)t[k] <= ' ' || t[k] == 0x7f)
            return refuse(b, 400, "control character in the target");
    const char *q = memchr(t, '?', tl);
    size_t pl = q ? (size_t)(q - t) : tl;
    if (tl >= 2048 || pl >= sizeof r->path)
        return refuse(b, 414, "target too long");
    memcpy(r->path, t, pl);
    r->path[pl] = 0;
    const char *v = sp + 1;
    size_t vl = n - (size_t)(v - s);
    if (vl != 8 || memcmp(v, "HTTP/", 5) != 0 || v[6] != '.' || v[5] < '0' || v[5] > '9' || v[7] < '0' || v[7] > '9')
        return refuse(b, 400, "malformed HTTP version");
    if (v[5] != '1')
        return refuse(b, 505, "HTTP version not supported");
    r->minor = v[7] - '0';
    return 0;
}

/* Whether the comma-separated list [v, v+n) holds token tok (any case). */
static bool has_token(const char *v, size_t n, const char *tok)
{
    size_t tl = strlen(tok);
    for (size_t i = 0; i < n;) {
        while (i < n && (v[i] == ' ' || v[i] == '\t' || v[i] == ','))
            i++;
        size_t j = i;
        while (j < n && v[j] != ',')
            j++;
        size_t e = j;
        while (e > i && (v[e - 1] == ' ' || v[e - 1] == '\t'))
            e--;
        if (e - i == tl && strncasecmp(v + i, tok, tl) == 0)
            return true;
        i = j;
    }
    return false;
}

static int copy_value(char *dst, size_t cap, const char *v, size_t n, bad_t *b)
{
    if (n >= cap)
        return refuse(b, 400, "header value too long");
    memcpy(dst, v, n);
    dst[n] = 0;
    return 0;
}

static int content_length(webreq_t *r, const char *v, size_t n, bad_t *b)
{
    if (n == 0 || n > 18)
        return refuse(b, 400, "malformed Content-Length");
    for (size_t i = 0; i < n; i++)
        if (v[i] < '0' || v[i] > '9')
            return refuse(b, 400, "malformed Content-Length");
    if (strspn(v, "0") < n)
        r->has_body = true;
    return 0;
}

static bool name_is(const char *s, size_t n, const char *name)
{
    return strlen(name) == n && strncasecmp(s, name, n) == 0;
}

static int take_header(webreq_t *r, const char *s, size_t nl, const char *v, size_t vl, bad_t *b)
{
    if (name_is(s, nl, "host")) {
        if (r->has_host)
            return refuse(b, 400, "two Host headers");
        r->has_host = true;
        return copy_value(r->host, sizeof r->host, v, vl, b);
    }
    if (name_is(s, nl, "origin"))
        return copy_value(r->origin, sizeof r->origin, v, vl, b);
    if (name_is(s, nl, "sec-websocket-key"))
        return copy_value(r->key, sizeof r->key, v, vl, b);
    if (name_is(s, nl, "sec-websocket-version"))
        return copy_value(r->version, sizeof r->version, v, vl, b);
    if (name_is(s, nl, "content-length"))
        return content_length(r, v, vl, b);
    if (name_is(s, nl, "transfer-encoding"))
        r->has_body = true;
    else if (name_is(s, nl, "upgrade"))
        r->upgrade_ws |= has_token(v, vl, "websocket");
    else if (name_is(s, nl, "connection")) {
        r->conn_upgrade |= has_token(v, vl, "upgrade");
        r->conn_close |= has_token(v, vl, "close");
        r->conn_keep_alive |= has_token(v, vl, "keep-alive");
    }
    return 0;
}

static int parse_header(webreq_t *r, const char *s, size_t n, bad_t *b)
{
    if (s[0] == ' ' || s[0] == '\t')
        return refuse(b, 400, "folded header line");
    size_t i = 0;
    while (i < n && is_tchar((unsigned char)s[i]))
        i++;
    if (i == 0 || i >= n || s[i] != ':')
        return refuse(b, 400, "malformed header line");
    const char *v = s + i + 1, *e = s + n;
    while (v < e && (*v == ' ' || *v == '\t'))
        v++;
    while (e > v && (e[-1] == ' ' || e[-1] == '\t'))
        e--;
    for (const char *c = v; c < e; c++)
        if (((unsigned char)*c < ' ' && *c != '\t') || *c == 0x7f)
            return refuse(b, 400, "control character in a header");
    return take_header(r, s, i, v, (size_t)(e - v), b);
}

static int parse_head(webreq_t *r, const char *buf, size_t end, bad_t *b)
{
    const char *p = buf, *stop = buf + end;
    size_t n;
    bool cr;
    const char *s = next_line(&p, stop, &n, &cr);
    if (!s || cr || parse_request_line(r, s, n, b) < 0)
        return b->status ? -1 : refuse(b, 400, "malformed request line");
    for (int count = 0; (s = next_line(&p, stop, &n, &cr)) && n > 0; count++) {
        if (cr)
            return refuse(b, 400, "bare CR in a header");
        if (count >= WEBREQ_HEADERS_MAX)
            return refuse(b, 431, "too many headers");
        if (parse_header(r, s, n, b) < 0)
            return -1;
    }
    if (r->minor >= 1 && !r->has_host)
        return refuse(b, 400, "no Host header");
    return 0;
}

int webreq_parse(webreq_t *r, const char *buf, size_t len, int *status, const char **why)
{
    memset(r, 0, sizeof *r);
    bad_t b = {0, NULL};
    size_t end = head_end(buf, len < WEBREQ_HEAD_MAX ? len : WEBREQ_HEAD_MAX);
    if (!end && len >= WEBREQ_HEAD_MAX)
        refuse(&b, 431, "request head too long");
    else if (!end)
        return 0;
    else
        parse_head(r, buf, end, &b);
    if (b.status) {
        *status = b.status;
        *why = b.why;
        return -1;
    }
    return (int)end;
}

int webws_accept(const char *key, char out[29])
{
    static const char guid[] = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11";
    if (strlen(key) != 24 || strcspn(key, " \t\r\n") != 24 || marie_base64_decoded_len(key, 24) != 16)
        return marie_fail(EINVAL);
    struct sha1_ctx c;
    uint8_t digest[SHA1_DIGEST_SIZE];
    sha1_init(&c);
    sha1_update(&c, 24, (const uint8_t *)key);
    sha1_update(&c, sizeof guid - 1, (const uint8_t *)guid);
    sha1_digest(&c, sizeof digest, digest);
    marie_base64_encode(out, digest, sizeof digest);
    out[28] = 0;
    return 0;
}

int webws_parse(webws_frame_t *f, const uint8_t *buf, size_t len, const char **why)
{
    if (len < 2)
        return 0;
    f->fin = buf[0] & 0x80;
    f->op = buf[0] & 0x0f;
    f->masked = buf[1] & 0x80;
    f->len = buf[1] & 0x7f;
    bool control = f->op & 8;
    if (buf[0] & 0x70)
        return *why = "reserved bits set", -1;
    if ((f->op > WEBWS_BINARY && f->op < WEBWS_CLOSE) || f->op > WEBWS_PONG)
        return *why = "reserved opcode", -1;
    if (control && (!f->fin || f->len > 125))
        return *why = "fragmented or long control frame", -1;
    size_t ext = f->len == 126 ? 2 : f->len == 127 ? 8 : 0, head = 2 + ext + (f->masked ? 4 : 0);
    if (len < head)
        return 0;
    if (ext) {
        f->len = 0;
        for (size_t i = 0; i < ext; i++)
            f->len = f->len << 8 | buf[2 + i];
        if (f->len >> 63)
            return *why = "length over 2^63", -1;
    }
    if (f->masked)
        memcpy(f->mask, buf + 2 + ext, 4);
    return (int)head;
}

void webws_unmask(uint8_t *p, size_t n, const uint8_t mask[4], uint64_t at)
{
    for (size_t i = 0; i < n; i++)
        p[i] ^= mask[(at + i) & 3];
}

size_t webws_head(uint8_t out[10], int op, uint64_t len)
{
    out[0] = (uint8_t)(0x80 | (op & 0x0f));
    if (len < 126) {
        out[1] = (uint8_t)len;
        return 2;
    }
    size_t ext = len <= 0xffff ? 2 : 8;
    out[1] = ext == 2 ? 126 : 127;
    for (size_t i = 0; i < ext; i++)
        out[2 + i] = (uint8_t)(len >> (8 * (ext - 1 - i)));
    return 2 + ext;
}
