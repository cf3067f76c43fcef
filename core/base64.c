/* base64: RFC 4648 base64 text of bytes and back. */
#include "core/base64.h"

static const char tab[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

size_t marie_base64_len(size_t n) { return (n + 2) / 3 * 4; }

void marie_base64_encode(char *o, const void *data, size_t n)
{
    const uint8_t *d = data;
    size_t i = 0;
    for (; i + 2 < n; i += 3) {
        uint32_t v = (uint32_t)d[i] << 16 | (uint32_t)d[i + 1] << 8 | d[i + 2];
        *o++ = tab[v >> 18];
        *o++ = tab[(v >> 12) & 63];
        *o++ = tab[(v >> 6) & 63];
        *o++ = tab[v & 63];
    }
    if (i < n) {
        uint32_t v = (uint32_t)d[i] << 16 | (i + 1 < n ? (uint32_t)d[i + 1] << 8 : 0);
        *o++ = tab[v >> 18];
        *o++ = tab[(v >> 12) & 63];
        *o++ = i + 1 < n ? tab[(v >> 6) & 63] : '=';
        *o = '=';
    }
}

static int value(char c)
{
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
}

static int is_ws(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

long marie_base64_decoded_len(const char *s, size_t len)
{
    size_t n = 0, pad = 0;
    for (size_t i = 0; i < len; i++) {
        if (is_ws(s[i]))
            continue;
        if (s[i] == '=')
            pad++;
        else if (pad || value(s[i]) < 0)
            return -1;
        n++;
    }
    if (n % 4 || pad > 2)
        return -1;
    return (long)(n / 4 * 3 - pad);
}

long marie_base64_decode(const char *s, size_t len, uint8_t *out, size_t cap)
{
    long total = marie_base64_decoded_len(s, len);
    if (total < 0 || (size_t)total > cap)
        return -1;
    uint32_t acc = 0;
    int bits = 0;
    long n = 0;
    for (size_t i = 0; i < len; i++) {
        int v = value(s[i]);
        if (v < 0)
            continue;
        acc = acc << 6 | (uint32_t)v;
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            if (n < total)
                out[n++] = (uint8_t)(acc >> bits);
        }
    }
    return n;
}
