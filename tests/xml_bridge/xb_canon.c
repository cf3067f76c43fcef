/* xb_canon: canonical field lines and sample messages for the XML bridge's tests. */
#include "tests/xml_bridge/xb_canon.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

void xb_canon_init(xb_canon_t *d)
{
    marie_buf_init(&d->buf, 0);
}

void xb_canon_free(xb_canon_t *d)
{
    marie_buf_free(&d->buf);
}

void xb_canon_int(xb_canon_t *d, const char *path, long long v)
{
    marie_buf_printf(&d->buf, "%s=%lld\n", path, v);
}

void xb_canon_double(xb_canon_t *d, const char *path, double v)
{
    if (isnan(v))
        marie_buf_printf(&d->buf, "%s=nan\n", path);
    else
        marie_buf_printf(&d->buf, "%s=%.17g\n", path, v);
}

void xb_canon_float(xb_canon_t *d, const char *path, float v)
{
    xb_canon_double(d, path, (double)v);
}

void xb_canon_str(xb_canon_t *d, const char *path, const char *s)
{
    marie_buf_printf(&d->buf, "%s=", path);
    for (const unsigned char *p = (const unsigned char *)(s ? s : ""); *p; p++) {
        if (*p < 0x20 || *p == 0x7f || *p == '\\')
            marie_buf_printf(&d->buf, "\\x%02x", *p);
        else
            marie_buf_put(&d->buf, p, 1);
    }
    marie_buf_put(&d->buf, "\n", 1);
}

const char *xb_canon_text(xb_canon_t *d)
{
    marie_buf_put(&d->buf, "", 1);
    d->buf.len--;
    return d->buf.data;
}

/* ---- samples ---- */

static uint32_t rnd(uint32_t *s)
{
    uint32_t x = *s;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    return *s = x ? x : 0x9e3779b9u;
}

static int64_t sample_int(marie_prim_t prim, uint32_t *s)
{
    static const int64_t lo[] = { INT8_MIN, INT16_MIN, INT32_MIN, INT64_MIN, 0 };
    static const int64_t hi[] = { INT8_MAX, INT16_MAX, INT32_MAX, INT64_MAX, 255 };
    if (prim == MARIE_PRIM_BOOL)
        return rnd(s) & 1;
    uint32_t r = rnd(s) % 8;
    if (r == 0)
        return lo[prim];
    if (r == 1)
        return hi[prim];
    int64_t v = (int64_t)((uint64_t)rnd(s) << 32 | rnd(s));
    if (prim == MARIE_PRIM_BYTE)
        return (uint8_t)v;
    if (prim == MARIE_PRIM_INT8)
        return (int8_t)v;
    if (prim == MARIE_PRIM_INT16)
        return (int16_t)v;
    if (prim == MARIE_PRIM_INT32)
        return (int32_t)v;
    return v;
}

static double sample_real(marie_prim_t prim, uint32_t *s)
{
    switch (rnd(s) % 10) {
    case 0: return NAN;
    case 1: return (rnd(s) & 1) ? INFINITY : -INFINITY;
    case 2: return 0.0;
    case 3: case 4: return ((double)(rnd(s) % 2001) - 1000.0) / 8.0;
    default: {
        double v = ((double)rnd(s) / 4294967296.0 - 0.5) * pow(10.0, (double)(rnd(s) % 13) - 6);
        return prim == MARIE_PRIM_FLOAT ? (double)(float)v : v;
    }
    }
}

static void sample_string(uint32_t *s, char *out, size_t size)
{
    static const char *const pieces[] = { "a", "Z", "0", " ", "<", ">", "&", "\"", "'", "\t",
                                          "\n", "\r", "\xc3\xa9", "\xe2\x82\xac", "\xf0\x9d\x84\x9e",
                                          "map", "]]>", "\x01" };
    size_t n = rnd(s) % 12, len = 0;
    out[0] = '\0';
    for (size_t i = 0; i < n; i++) {
        size_t k = rnd(s) % (sizeof pieces / sizeof pieces[0]);
        if (k == sizeof pieces / sizeof pieces[0] - 1 && rnd(s) % 4)
            k = 0;
        size_t pl = strlen(pieces[k]);
        if (len + pl + 1 > size)
            break;
        memcpy(out + len, pieces[k], pl + 1);
        len += pl;
    }
}

static void put_value_xml(marie_buf_t *xml, const char *tag, marie_prim_t prim, double dv, int64_t iv,
                          const char *str)
{
    char tmp[40];
    if (prim == MARIE_PRIM_STRING) {
        if (xb_xml_safe(str, strlen(str))) {
            marie_buf_printf(xml, "<%s>", tag);
            xb_escape(xml, str, strlen(str));
        } else {
            marie_buf_printf(xml, "<%s encoding=\"base64\">", tag);
            xb_base64_encode(xml, (const uint8_t *)str, strlen(str));
        }
        marie_buf_printf(xml, "</%s>", tag);
        return;
    }
    if (prim == MARIE_PRIM_FLOAT || prim == MARIE_PRIM_DOUBLE)
        xb_format_real(prim, dv, tmp, sizeof tmp);
    else if (prim == MARIE_PRIM_BOOL)
        snprintf(tmp, sizeof tmp, "%s", iv ? ((iv & 2) ? "1" : "true") : "false");
    else
        snprintf(tmp, sizeof tmp, "%lld", (long long)iv);
    marie_buf_puts(xml, tmp);
}

static void canon_value(xb_canon_t *c, const char *path, marie_prim_t prim, double dv, int64_t iv,
                        const char *str)
{
    if (prim == MARIE_PRIM_STRING)
        xb_canon_str(c, path, str);
    else if (prim == MARIE_PRIM_FLOAT)
        xb_canon_float(c, path, (float)dv);
    else if (prim == MARIE_PRIM_DOUBLE)
        xb_canon_double(c, path, dv);
    else
        xb_canon_int(c, path, prim == MARIE_PRIM_BOOL ? (iv != 0) : iv);
}

static void sample_struct(const marie_typeinfo_t *t, uint32_t *s, marie_buf_t *xml, xb_canon_t *c,
                          const char *prefix, int depth)
{
    int64_t lens[64] = { 0 };
    char is_len[64] = { 0 };
    for (int i = 0; i < t->nfields && i < 64; i++)
        for (int d = 0; d < t->fields[i].ndims; d++) {
            int lf = t->fields[i].dims[d].len_field;
            if (lf < 0 || lf >= 64)
                continue;
            marie_prim_t pr = t->fields[i].prim;
            if (!is_len[lf]) {
                is_len[lf] = 1;
                lens[lf] = depth > 2 ? 0 : (int64_t)(rnd(s) % (pr == MARIE_PRIM_BYTE ? 40 : 4));
            }
        }
    for (int i = 0; i < t->nfields; i++) {
        const marie_tfield_t *f = &t->fields[i];
        char path[512];
        if (f->ndims == 0) {
            snprintf(path, sizeof path, "%s%s", prefix, f->name);
            if (f->prim == MARIE_PRIM_STRUCT) {
                char sub[520];
                snprintf(sub, sizeof sub, "%s.", path);
                marie_buf_printf(xml, "<%s>", f->name);
                sample_struct(f->sub, s, xml, c, sub, depth + 1);
                marie_buf_printf(xml, "</%s>", f->name);
                continue;
            }
            char str[128] = "";
            double dv = 0;
            int64_t iv = 0;
            if (i < 64 && is_len[i])
                iv = lens[i];
            else if (f->prim == MARIE_PRIM_STRING)
                sample_string(s, str, sizeof str);
            else if (f->prim == MARIE_PRIM_FLOAT || f->prim == MARIE_PRIM_DOUBLE)
                dv = sample_real(f->prim, s);
            else
                iv = sample_int(f->prim, s);
            canon_value(c, path, f->prim, dv, iv, str);
            if (i < 64 && is_len[i] && (rnd(s) & 1))
                continue;           /* the bridge counts the array instead */
            if (f->prim == MARIE_PRIM_STRING) {
                put_value_xml(xml, f->name, f->prim, dv, iv, str);
            } else {
                marie_buf_printf(xml, "<%s>", f->name);
                put_value_xml(xml, f->name, f->prim, dv, iv, str);
                marie_buf_printf(xml, "</%s>", f->name);
            }
            continue;
        }
        long count = 1, sizes[8];
        int allfixed = 1;
        for (int d = 0; d < f->ndims && d < 8; d++) {
            int lf = f->dims[d].len_field;
            sizes[d] = lf < 0 ? f->dims[d].size : (long)lens[lf];
            allfixed &= lf < 0;
            count *= sizes[d];
        }
        int omit = allfixed && rnd(s) % 8 == 0;     /* absent fixed arrays are zeros */
        if (!omit)
            marie_buf_printf(xml, "<%s>", f->name);
        uint8_t bytes[4096];
        for (long k = 0; k < count; k++) {
            size_t len = (size_t)snprintf(path, sizeof path, "%s%s", prefix, f->name);
            long rem = k, idx[8];
            for (int d = f->ndims - 1; d >= 0; d--) {
                idx[d] = sizes[d] ? rem % sizes[d] : 0;
                rem = sizes[d] ? rem / sizes[d] : 0;
            }
            for (int d = 0; d < f->ndims && len < sizeof path; d++)
                len += (size_t)snprintf(path + len, sizeof path - len, "[%ld]", idx[d]);
            if (f->prim == MARIE_PRIM_STRUCT) {
                char sub[520];
                snprintf(sub, sizeof sub, "%s.", path);
                marie_buf_puts(xml, "<item>");
                sample_struct(f->sub, s, xml, c, sub, depth + 1);
                marie_buf_puts(xml, "</item>");
                continue;
            }
            char str[128] = "";
            double dv = 0;
            int64_t iv = 0;
            if (omit)
                ;
            else if (f->prim == MARIE_PRIM_STRING)
                sample_string(s, str, sizeof str);
            else if (f->prim == MARIE_PRIM_FLOAT || f->prim == MARIE_PRIM_DOUBLE)
                dv = sample_real(f->prim, s);
            else
                iv = sample_int(f->prim, s);
            canon_value(c, path, f->prim, dv, iv, str);
            if (omit)
                continue;
            if (f->prim == MARIE_PRIM_BYTE) {
                if (k < (long)sizeof bytes)
                    bytes[k] = (uint8_t)iv;
            } else if (f->prim == MARIE_PRIM_STRING) {
                put_value_xml(xml, "item", f->prim, dv, iv, str);
            } else {
                if (k)
                    marie_buf_puts(xml, (rnd(s) & 3) ? " " : " \n\t");
                put_value_xml(xml, NULL, f->prim, dv, iv, str);
            }
        }
        if (f->prim == MARIE_PRIM_BYTE && !omit)
            xb_base64_encode(xml, bytes, (size_t)(count < (long)sizeof bytes ? count : (long)sizeof bytes));
        if (!omit)
            marie_buf_printf(xml, "</%s>", f->name);
    }
}

void xb_sample(const marie_typeinfo_t *t, uint32_t seed, marie_buf_t *xml, xb_canon_t *canon)
{
    uint32_t s = seed * 2654435761u + 1;
    sample_struct(t, &s, xml, canon, "", 0);
}
