/* pgm: P5/P2 graymap parser; every malformed input is an error with a reason, never a crash. */
#include "map/pgm.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"

typedef struct {
    const uint8_t *buf;
    size_t len, pos;
} cursor_t;

static int is_space(uint8_t c)
{
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

/* Skip whitespace and '#' comments (allowed anywhere between header tokens). */
static void skip_blank(cursor_t *c)
{
    while (c->pos < c->len) {
        if (is_space(c->buf[c->pos])) {
            c->pos++;
        } else if (c->buf[c->pos] == '#') {
            while (c->pos < c->len && c->buf[c->pos] != '\n')
                c->pos++;
        } else {
            break;
        }
    }
}

/* An unsigned decimal token; -1 when absent or too large. */
static long read_uint(cursor_t *c)
{
    skip_blank(c);
    if (c->pos >= c->len || c->buf[c->pos] < '0' || c->buf[c->pos] > '9')
        return -1;
    long v = 0;
    while (c->pos < c->len && c->buf[c->pos] >= '0' && c->buf[c->pos] <= '9') {
        v = v * 10 + (c->buf[c->pos] - '0');
        if (v > 1000000000L)
            return -1;
        c->pos++;
    }
    return v;
}

int pgm_parse(const uint8_t *buf, size_t len, pgm_t *out, char *err, size_t errlen)
{
    memset(out, 0, sizeof(*out));
    if (len < 2 || buf[0] != 'P' || (buf[1] != '5' && buf[1] != '2')) {
        snprintf(err, errlen, "not a PGM image (expected magic P5 or P2)");
        return marie_fail(EINVAL);
    }
    int ascii = buf[1] == '2';
    cursor_t c = { buf, len, 2 };
    long w = read_uint(&c), h = read_uint(&c), maxval = read_uint(&c);
    if (w <= 0 || h <= 0 || w > PGM_MAX_SIDE || h > PGM_MAX_SIDE) {
        snprintf(err, errlen, "bad PGM size (width and height must be 1..%d)", PGM_MAX_SIDE);
        return marie_fail(EINVAL);
    }
    if (maxval <= 0 || maxval > 65535) {
        snprintf(err, errlen, "bad PGM maxval (must be 1..65535)");
        return marie_fail(EINVAL);
    }
    size_t n = (size_t)w * (size_t)h;
    uint16_t *px = malloc(n * sizeof(*px));
    if (!px) {
        snprintf(err, errlen, "out of memory for a %ldx%ld image", w, h);
        return marie_fail(ENOMEM);
    }
    if (ascii) {
        for (size_t i = 0; i < n; i++) {
            long v = read_uint(&c);
            if (v < 0) {
                snprintf(err, errlen, "PGM data truncated or malformed at byte %zu (pixel %zu of %zu)",
                         c.pos, i, n);
                goto fail;
            }
            if (v > maxval) {
                snprintf(err, errlen, "PGM pixel %zu is %ld, above maxval %ld", i, v, maxval);
                goto fail;
            }
            px[i] = (uint16_t)v;
        }
    } else {
        /* Exactly one whitespace byte separates maxval from the raster. */
        if (c.pos >= len || !is_space(buf[c.pos])) {
            snprintf(err, errlen, "PGM header not followed by whitespace at byte %zu", c.pos);
            goto fail;
        }
        c.pos++;
        size_t bpp = maxval > 255 ? 2 : 1;
        if (len - c.pos < n * bpp) {
            snprintf(err, errlen, "PGM data truncated: %zu bytes of raster, expected %zu",
                     len - c.pos, n * bpp);
            goto fail;
        }
        const uint8_t *p = buf + c.pos;
        for (size_t i = 0; i < n; i++) {
            unsigned v = bpp == 2 ? (unsigned)p[2 * i] << 8 | p[2 * i + 1] : p[i];
            if (v > (unsigned)maxval) {
                snprintf(err, errlen, "PGM pixel %zu is %u, above maxval %ld", i, v, maxval);
                goto fail;
            }
            px[i] = (uint16_t)v;
        }
    }
    out->width = (int)w;
    out->height = (int)h;
    out->maxval = (int)maxval;
    out->pixels = px;
    return 0;
fail:
    free(px);
    return marie_fail(EINVAL);
}
