/* buf: the growable text buffer (core/buf.h). */
#include "core/buf.h"
#include "core/err.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void marie_buf_init(marie_buf_t *b, size_t max)
{
    memset(b, 0, sizeof *b);
    b->max = max ? max : (size_t)1 << 30;
}

void marie_buf_free(marie_buf_t *b)
{
    size_t max = b->max;
    free(b->data);
    marie_buf_init(b, max);
}

void marie_buf_reset(marie_buf_t *b)
{
    b->len = 0;
    b->failed = false;
    if (b->data)
        b->data[0] = 0;
}

int marie_buf_reserve(marie_buf_t *b, size_t extra)
{
    if (!b->max)
        b->max = (size_t)1 << 30;
    if (extra > b->max || b->len > b->max - extra) {
        b->failed = true;
        return -1;
    }
    if (b->len + extra + 1 <= b->cap)
        return 0;
    size_t cap = b->cap ? b->cap : 256;
    while (cap < b->len + extra + 1)
        cap *= 2;
    if (cap > b->max + 1)
        cap = b->max + 1;
    char *d = realloc(b->data, cap);
    if (!d) {
        b->failed = true;
        return -1;
    }
    b->data = d;
    b->cap = cap;
    return 0;
}

int marie_buf_put(marie_buf_t *b, const void *data, size_t len)
{
    if (marie_buf_reserve(b, len) < 0)
        return -1;
    if (len)
        memcpy(b->data + b->len, data, len);
    b->len += len;
    b->data[b->len] = 0;
    return 0;
}

int marie_buf_puts(marie_buf_t *b, const char *s)
{
    return marie_buf_put(b, s, strlen(s));
}

int marie_buf_printf(marie_buf_t *b, const char *fmt, ...)
{
    char tmp[256];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(tmp, sizeof tmp, fmt, ap);
    va_end(ap);
    if (n < 0)
        return -1;
    if ((size_t)n < sizeof tmp)
        return marie_buf_put(b, tmp, (size_t)n);
    if (marie_buf_reserve(b, (size_t)n) < 0)
        return -1;
    va_start(ap, fmt);
    vsnprintf(b->data + b->len, (size_t)n + 1, fmt, ap);
    va_end(ap);
    b->len += (size_t)n;
    return 0;
}

/* The length of the well-formed UTF-8 sequence at p (2 to 4), or 0. */
static int utf8_len(const unsigned char *p)
{
    int n = p[0] >= 0xf0 && p[0] <= 0xf4 ? 4 : p[0] >= 0xe0 ? 3 : p[0] >= 0xc2 && p[0] < 0xe0 ? 2 : 0;
    for (int i = 1; i < n; i++)
        if ((p[i] & 0xc0) != 0x80)
            return 0;
    if ((n == 3 && p[0] == 0xe0 && p[1] < 0xa0) || (n == 3 && p[0] == 0xed && p[1] >= 0xa0) ||
        (n == 4 && p[0] == 0xf0 && p[1] < 0x90) || (n == 4 && p[0] == 0xf4 && p[1] >= 0x90))
        return 0;               /* overlong, a surrogate, or past U+10FFFF */
    return n;
}

int marie_buf_json_str(marie_buf_t *b, const char *s)
{
    static const char hex[] = "0123456789abcdef";
    size_t start = b->len;
    bool failed = b->failed;
    marie_buf_put(b, "\"", 1);
    for (const unsigned char *p = (const unsigned char *)(s ? s : ""); *p; p++) {
        int n = *p >= 0x80 ? utf8_len(p) : 1;
        if (*p == '"' || *p == '\\')
            marie_buf_put(b, (char[]){ '\\', (char)*p }, 2);
        else if (*p < 0x20 || *p == 0x7f)
            marie_buf_put(b, (char[]){ '\\', 'u', '0', '0', hex[*p >> 4], hex[*p & 15] }, 6);
        else if (n == 0)
            marie_buf_puts(b, "\\ufffd");
        else
            marie_buf_put(b, p, (size_t)n);
        p += n > 1 ? n - 1 : 0;
    }
    marie_buf_put(b, "\"", 1);
    if (b->failed && !failed) {     /* all or nothing, as the other appends */
        b->len = start;
        if (b->data)
            b->data[start] = 0;
        return -1;
    }
    return b->failed ? -1 : 0;
}

void marie_json_fputs(FILE *f, const char *s)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    if (marie_buf_json_str(&b, s) == 0)
        fwrite(b.data, 1, b.len, f);
    marie_buf_free(&b);
}

int marie_grow(void **p, size_t *cap, size_t need, size_t elem)
{
    if (need <= *cap)
        return 0;
    size_t n = *cap ? *cap : 16;
    while (n < need && n <= SIZE_MAX / 2)
        n *= 2;
    if (n < need || !elem || n > SIZE_MAX / elem)
        return marie_fail(ENOMEM);
    void *q = realloc(*p, n * elem);
    if (!q)
        return marie_fail(ENOMEM);
    *p = q;
    *cap = n;
    return 0;
}
