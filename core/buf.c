/* buf: the growable text buffer (core/buf.h). */
#include "core/buf.h"

#include <stdarg.h>
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
