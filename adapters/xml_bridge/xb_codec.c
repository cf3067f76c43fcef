/* xb_codec: XML element tree <-> LCM wire format (big-endian, fingerprint first), generic over
 * the generated descriptors. */
#include "adapters/xml_bridge/xb_codec.h"

#include <errno.h>
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/base64.h"
#include "core/err.h"

#define XB_MAX_STRUCT_DEPTH 64
#define XB_MAX_ELEMENTS (1L << 26)

/* ---- encoding ---- */

typedef struct {
    marie_buf_t *out;
    xb_error_t *err;
} enc_t;

static int is_int_prim(marie_prim_t p)
{
    return p == MARIE_PRIM_INT8 || p == MARIE_PRIM_INT16 || p == MARIE_PRIM_INT32 || p == MARIE_PRIM_INT64 || p == MARIE_PRIM_BYTE;
}

/* "pose.x" style location of a field for error reasons, from the element chain. */
static void where(const xb_node_t *n, const char *field, char *buf, size_t size)
{
    const char *names[16];
    int k = 0;
    for (const xb_node_t *p = n; p && p->parent && k < 16; p = p->parent)
        names[k++] = p->name;
    size_t len = 0;
    buf[0] = '\0';
    for (int i = k - 1; i >= 0 && len < size; i--)
        len += (size_t)snprintf(buf + len, size - len, "%s%s", len ? "." : "", names[i]);
    if (field && len < size)
        snprintf(buf + len, size - len, "%s%s", len ? "." : "", field);
}

static int enc_fail(enc_t *e, const char *code, const xb_node_t *at, const char *field,
                    const char *what)
{
    char path[160];
    where(at, field, path, sizeof path);
    xb_error_set(e->err, code, "%s: %s", path[0] ? path : "message", what);
    return -1;
}

static int put_be(enc_t *e, uint64_t v, int nbytes)
{
    uint8_t b[8];
    for (int i = 0; i < nbytes; i++)
        b[i] = (uint8_t)(v >> (8 * (nbytes - 1 - i)));
    return marie_buf_put(e->out, b, (size_t)nbytes);
}

static int put_int(enc_t *e, marie_prim_t prim, int64_t v)
{
    switch (prim) {
    case MARIE_PRIM_INT8: case MARIE_PRIM_BYTE: case MARIE_PRIM_BOOL: return put_be(e, (uint64_t)v, 1);
    case MARIE_PRIM_INT16: return put_be(e, (uint64_t)v, 2);
    case MARIE_PRIM_INT32: return put_be(e, (uint64_t)v, 4);
    default: return put_be(e, (uint64_t)v, 8);
    }
}

static int put_real(enc_t *e, marie_prim_t prim, double v)
{
    if (prim == MARIE_PRIM_FLOAT) {
        float f = (float)v;
        uint32_t u;
        memcpy(&u, &f, 4);
        return put_be(e, u, 4);
    }
    uint64_t u;
    memcpy(&u, &v, 8);
    return put_be(e, u, 8);
}

static int too_large(enc_t *e)
{
    xb_error_set(e->err, "too-large", "encoded message larger than %zu bytes", e->out->max);
    return -1;
}

static int encode_struct(enc_t *e, const marie_typeinfo_t *t, const xb_node_t *n, int depth);

/* A leaf element must hold text only. */
static int leaf_only(enc_t *e, const xb_node_t *n)
{
    if (n && n->first)
        return enc_fail(e, "unknown-field", n->first, NULL, "unexpected element in a value");
    return 0;
}

static int encode_value(enc_t *e, const marie_tfield_t *f, const xb_node_t *n, int depth)
{
    int64_t iv = 0;
    double dv = 0;
    switch (f->prim) {
    case MARIE_PRIM_INT8: case MARIE_PRIM_INT16: case MARIE_PRIM_INT32: case MARIE_PRIM_INT64: case MARIE_PRIM_BYTE: case MARIE_PRIM_BOOL:
        if (leaf_only(e, n) < 0)
            return -1;
        if (n && xb_parse_int(f->prim, n->text, n->text_len, &iv) < 0)
            return enc_fail(e, "bad-value", n, NULL, f->prim == MARIE_PRIM_BOOL ? "not a boolean"
                            : "not an integer in range");
        return put_int(e, f->prim, iv) < 0 ? too_large(e) : 0;
    case MARIE_PRIM_FLOAT: case MARIE_PRIM_DOUBLE:
        if (leaf_only(e, n) < 0)
            return -1;
        if (n && xb_parse_real(f->prim, n->text, n->text_len, &dv) < 0)
            return enc_fail(e, "bad-value", n, NULL, "not a real number in range");
        return put_real(e, f->prim, dv) < 0 ? too_large(e) : 0;
    case MARIE_PRIM_STRING: {
        if (leaf_only(e, n) < 0)
            return -1;
        const char *s = n ? n->text : "";
        size_t len = n ? n->text_len : 0;
        const char *enc = n ? xb_node_attr(n, "encoding") : NULL;
        if (enc && strcmp(enc, "base64") != 0)
            return enc_fail(e, "bad-value", n, NULL, "unknown encoding (only base64)");
        if (enc) {
            long m = marie_base64_decoded_len(s, len);
            if (m < 0)
                return enc_fail(e, "bad-value", n, NULL, "bad base64");
            if (m >= INT32_MAX || put_be(e, (uint64_t)(m + 1), 4) < 0 ||
                marie_buf_reserve(e->out, (size_t)m + 1) < 0)
                return too_large(e);
            uint8_t *o = (uint8_t *)e->out->data + e->out->len;
            marie_base64_decode(s, len, o, (size_t)m);
            if (memchr(o, 0, (size_t)m))
                return enc_fail(e, "bad-value", n, NULL, "string contains NUL");
            o[m] = 0;
            e->out->len += (size_t)m + 1;
            return 0;
        }
        if (memchr(s, 0, len))
            return enc_fail(e, "bad-value", n, NULL, "string contains NUL");
        if (len >= INT32_MAX || put_be(e, (uint64_t)len + 1, 4) < 0 ||
            marie_buf_put(e->out, s, len) < 0 || marie_buf_put(e->out, "", 1) < 0)
            return too_large(e);
        return 0;
    }
    case MARIE_PRIM_STRUCT:
        return encode_struct(e, f->sub, n, depth + 1);
    }
    return -1;
}

/* Elements of an array field as written: whitespace-separated values for numbers and
 * booleans, base64 for bytes, <item> children for strings and structs. -1 on bad syntax. */
static long array_count(enc_t *e, const marie_tfield_t *f, const xb_node_t *n)
{
    if (!n)
        return 0;
    if (f->prim == MARIE_PRIM_STRING || f->prim == MARIE_PRIM_STRUCT) {
        if (!xb_text_blank(n->text, n->text_len))
            return enc_fail(e, "bad-value", n, NULL, "text in an array: use <item> elements");
        for (const xb_node_t *c = n->first; c; c = c->next)
            if (strcmp(c->name, "item") != 0)
                return enc_fail(e, "unknown-field", c, NULL, "array elements must be <item>");
        return n->nchildren;
    }
    if (leaf_only(e, n) < 0)
        return -1;
    if (f->prim == MARIE_PRIM_BYTE) {
        const char *enc = xb_node_attr(n, "encoding");
        if (enc && strcmp(enc, "base64") != 0)
            return enc_fail(e, "bad-value", n, NULL, "unknown encoding (only base64)");
        long m = marie_base64_decoded_len(n->text, n->text_len);
        if (m < 0)
            return enc_fail(e, "bad-value", n, NULL, "bad base64");
        return m;
    }
    long count = 0;
    const char *s = n->text, *end = n->text + n->text_len;
    while (s < end) {
        while (s < end && xb_is_ws(*s))
            s++;
        if (s == end)
            break;
        count++;
        while (s < end && !xb_is_ws(*s))
            s++;
    }
    return count;
}

static int encode_array(enc_t *e, const marie_tfield_t *f, const xb_node_t *n, long count, int depth)
{
    if (f->prim == MARIE_PRIM_BYTE) {
        if (marie_buf_reserve(e->out, (size_t)count) < 0)
            return too_large(e);
        uint8_t *o = (uint8_t *)e->out->data + e->out->len;
        if (n)
            marie_base64_decode(n->text, n->text_len, o, (size_t)count);
        else
            memset(o, 0, (size_t)count);
        e->out->len += (size_t)count;
        return 0;
    }
    if (f->prim == MARIE_PRIM_STRING || f->prim == MARIE_PRIM_STRUCT) {
        const xb_node_t *c = n ? n->first : NULL;
        for (long i = 0; i < count; i++) {
            if (encode_value(e, f, c, depth) < 0)
                return -1;
            if (c)
                c = c->next;
        }
        return 0;
    }
    const char *s = n ? n->text : NULL, *end = n ? n->text + n->text_len : NULL;
    for (long i = 0; i < count; i++) {
        int64_t iv = 0;
        double dv = 0;
        if (s) {
            while (s < end && xb_is_ws(*s))
                s++;
            const char *tok = s;
            while (s < end && !xb_is_ws(*s))
                s++;
            int bad = (f->prim == MARIE_PRIM_FLOAT || f->prim == MARIE_PRIM_DOUBLE)
                          ? xb_parse_real(f->prim, tok, (size_t)(s - tok), &dv)
                          : xb_parse_int(f->prim, tok, (size_t)(s - tok), &iv);
            if (bad < 0) {
                char what[96];
                snprintf(what, sizeof what, "element %ld is not a %s in range", i, marie_prim_name(f->prim));
                return enc_fail(e, "bad-value", n, NULL, what);
            }
        }
        int r = (f->prim == MARIE_PRIM_FLOAT || f->prim == MARIE_PRIM_DOUBLE) ? put_real(e, f->prim, dv)
                                                               : put_int(e, f->prim, iv);
        if (r < 0)
            return too_large(e);
    }
    return 0;
}

static int encode_struct(enc_t *e, const marie_typeinfo_t *t, const xb_node_t *n, int depth)
{
    if (depth > XB_MAX_STRUCT_DEPTH)
        return enc_fail(e, "too-deep", n, NULL, "structs nested too deeply");
    int nf = t->nfields, rc = -1;
    const xb_node_t *slot_s[32];
    int64_t len_s[32];
    char known_s[32];
    const xb_node_t **slot = slot_s;
    int64_t *lenval = len_s;
    char *known = known_s;
    if (nf > 32) {
        slot = calloc((size_t)nf, sizeof *slot);
        lenval = calloc((size_t)nf, sizeof *lenval);
        known = calloc((size_t)nf, 1);
        if (!slot || !lenval || !known) {
            xb_error_set(e->err, "no-memory", "out of memory");
            goto out;
        }
    } else {
        memset(slot_s, 0, sizeof slot_s);
        memset(len_s, 0, sizeof len_s);
        memset(known_s, 0, sizeof known_s);
    }

    if (n) {
        if (!xb_text_blank(n->text, n->text_len)) {
            enc_fail(e, "bad-value", n, NULL, "text where fields are expected");
            goto out;
        }
        for (const xb_node_t *c = n->first; c; c = c->next) {
            int i = 0;
            while (i < nf && strcmp(t->fields[i].name, c->name) != 0)
                i++;
            if (i == nf) {
                char what[128];
                snprintf(what, sizeof what, "no such field in %s", t->name);
                enc_fail(e, "unknown-field", c, NULL, what);
                goto out;
            }
            if (slot[i]) {
                enc_fail(e, "bad-value", c, NULL, "field given twice");
                goto out;
            }
            slot[i] = c;
        }
    }
    /* Length fields given explicitly must agree with their arrays; absent ones are counted. */
    for (int i = 0; i < nf; i++) {
        const marie_tfield_t *f = &t->fields[i];
        if (f->ndims == 0 && is_int_prim(f->prim) && slot[i]) {
            if (leaf_only(e, slot[i]) < 0)
                goto out;
            if (xb_parse_int(f->prim, slot[i]->text, slot[i]->text_len, &lenval[i]) < 0) {
                enc_fail(e, "bad-value", slot[i], NULL, "not an integer in range");
                goto out;
            }
            known[i] = 1;
        }
    }
    for (int i = 0; i < nf; i++) {
        const marie_tfield_t *f = &t->fields[i];
        if (f->ndims == 0)
            continue;
        long count = array_count(e, f, slot[i]);
        if (count < 0)
            goto out;
        long prod = 1;
        int unknown = -1, nunknown = 0;
        for (int d = 0; d < f->ndims; d++) {
            int lf = f->dims[d].len_field;
            long size = lf < 0 ? f->dims[d].size : (known[lf] ? (long)lenval[lf] : -1);
            if (size < 0 && lf >= 0 && known[lf]) {
                enc_fail(e, "bad-length", slot[lf], NULL, "negative length");
                goto out;
            }
            if (size < 0) {
                if (unknown != lf)
                    nunknown++;
                unknown = lf;
                continue;
            }
            if (size > 0 && prod > XB_MAX_ELEMENTS / size) {
                enc_fail(e, "bad-length", slot[i], f->name, "array too large");
                goto out;
            }
            prod *= size;
        }
        if (f->ndims > 0 && !slot[i] && nunknown == 0 && f->dims[0].len_field < 0) {
            /* An absent fixed-size array is all zeros. */
            int allfixed = 1;
            for (int d = 0; d < f->ndims; d++)
                allfixed &= f->dims[d].len_field < 0;
            if (allfixed)
                continue;
        }
        if (nunknown == 0) {
            if (count != prod) {
                char what[128];
                snprintf(what, sizeof what, "%ld elements where the sizes say %ld", count, prod);
                enc_fail(e, "bad-length", slot[i], slot[i] ? NULL : f->name, what);
                goto out;
            }
        } else if (nunknown == 1 && prod > 0 && count % prod == 0) {
            int uses = 0;
            for (int d = 0; d < f->ndims; d++)
                uses += f->dims[d].len_field == unknown;
            if (uses != 1 && count != 0) {
                enc_fail(e, "bad-length", slot[i], slot[i] ? NULL : f->name,
                         "give the length field explicitly");
                goto out;
            }
            lenval[unknown] = count / prod;
            known[unknown] = 1;
        } else if (count == 0) {
            for (int d = 0; d < f->ndims; d++)
                if (f->dims[d].len_field >= 0 && !known[f->dims[d].len_field]) {
                    lenval[f->dims[d].len_field] = 0;
                    known[f->dims[d].len_field] = 1;
                }
        } else {
            enc_fail(e, "bad-length", slot[i], slot[i] ? NULL : f->name,
                     "cannot infer the sizes: give the length fields");
            goto out;
        }
    }
    for (int i = 0; i < nf; i++) {
        const marie_tfield_t *f = &t->fields[i];
        if (f->ndims == 0) {
            if (is_int_prim(f->prim) && known[i]) {
                int64_t v = lenval[i], chk;
                char tmp[32];
                snprintf(tmp, sizeof tmp, "%lld", (long long)v);
                if (xb_parse_int(f->prim, tmp, strlen(tmp), &chk) < 0) {
                    enc_fail(e, "bad-length", n, f->name, "length does not fit its field");
                    goto out;
                }
                if (put_int(e, f->prim, v) < 0) {
                    too_large(e);
                    goto out;
                }
            } else if (encode_value(e, f, slot[i], depth) < 0) {
                goto out;
            }
            continue;
        }
        long count = 1;
        for (int d = 0; d < f->ndims; d++) {
            int lf = f->dims[d].len_field;
            long size = lf < 0 ? f->dims[d].size : (long)lenval[lf];
            if (size < 0) {
                enc_fail(e, "bad-length", n, f->name, "negative length");
                goto out;
            }
            count *= size;
        }
        if (encode_array(e, f, slot[i], count, depth) < 0)
            goto out;
    }
    rc = 0;
out:
    if (slot != slot_s) {
        free(slot);
        free(lenval);
        free(known);
    }
    return rc;
}

int xb_encode(const marie_typeinfo_t *t, const xb_node_t *msg, marie_buf_t *out, xb_error_t *err)
{
    enc_t e = { out, err };
    size_t start = out->len;
    if (put_be(&e, (uint64_t)t->fingerprint, 8) < 0 || encode_struct(&e, t, msg, 0) < 0) {
        if (out->failed && err && strcmp(err->code, "too-large") != 0)
            too_large(&e);
        out->len = start;
        out->failed = false;
        return marie_fail(EINVAL);
    }
    return 0;
}

/* ---- decoding ---- */

typedef struct {
    const uint8_t *p;
    size_t len, pos;
    marie_buf_t *out;
    xb_error_t *err;
    const char *type;
} dec_t;

static int dec_fail(dec_t *d, const char *what)
{
    xb_error_set(d->err, "bad-message", "%s: %s at byte %zu", d->type, what, d->pos);
    return -1;
}

static int get_be(dec_t *d, int nbytes, uint64_t *v)
{
    if (d->len - d->pos < (size_t)nbytes)
        return dec_fail(d, "truncated");
    uint64_t x = 0;
    for (int i = 0; i < nbytes; i++)
        x = x << 8 | d->p[d->pos + (size_t)i];
    d->pos += (size_t)nbytes;
    *v = x;
    return 0;
}

static int get_int(dec_t *d, marie_prim_t prim, int64_t *v)
{
    uint64_t u;
    switch (prim) {
    case MARIE_PRIM_INT8: case MARIE_PRIM_BOOL:
        if (get_be(d, 1, &u) < 0) return -1;
        *v = (int8_t)u;
        return 0;
    case MARIE_PRIM_BYTE:
        if (get_be(d, 1, &u) < 0) return -1;
        *v = (uint8_t)u;
        return 0;
    case MARIE_PRIM_INT16:
        if (get_be(d, 2, &u) < 0) return -1;
        *v = (int16_t)u;
        return 0;
    case MARIE_PRIM_INT32:
        if (get_be(d, 4, &u) < 0) return -1;
        *v = (int32_t)u;
        return 0;
    default:
        if (get_be(d, 8, &u) < 0) return -1;
        *v = (int64_t)u;
        return 0;
    }
}

static int get_real(dec_t *d, marie_prim_t prim, double *v)
{
    uint64_t u;
    if (prim == MARIE_PRIM_FLOAT) {
        if (get_be(d, 4, &u) < 0)
            return -1;
        uint32_t w = (uint32_t)u;
        float f;
        memcpy(&f, &w, 4);
        *v = f;
        return 0;
    }
    if (get_be(d, 8, &u) < 0)
        return -1;
    memcpy(v, &u, 8);
    return 0;
}

/* <name> or </name>, without printf: one per field of every message delivered. */
static int put_tag(marie_buf_t *o, const char *open, const char *name)
{
    return marie_buf_puts(o, open) < 0 || marie_buf_puts(o, name) < 0 || marie_buf_put(o, ">", 1) < 0
               ? -1 : 0;
}

/* The "%lld" text of v. */
static void format_int(int64_t v, char *buf)
{
    char dig[24];
    int nd = 0;
    uint64_t u = v < 0 ? 0 - (uint64_t)v : (uint64_t)v;
    do {
        dig[nd++] = (char)('0' + u % 10);
        u /= 10;
    } while (u);
    if (v < 0)
        *buf++ = '-';
    while (nd)
        *buf++ = dig[--nd];
    *buf = '\0';
}

static int put_scalar_text(dec_t *d, marie_prim_t prim, int64_t *intval)
{
    char tmp[40];
    if (prim == MARIE_PRIM_FLOAT || prim == MARIE_PRIM_DOUBLE) {
        double v;
        if (get_real(d, prim, &v) < 0)
            return -1;
        xb_format_real(prim, v, tmp, sizeof tmp);
    } else {
        int64_t v;
        if (get_int(d, prim, &v) < 0)
            return -1;
        if (intval)
            *intval = v;
        if (prim == MARIE_PRIM_BOOL)
            return marie_buf_puts(d->out, v ? "true" : "false");
        format_int(v, tmp);
    }
    return marie_buf_puts(d->out, tmp);
}

static int decode_struct(dec_t *d, const marie_typeinfo_t *t, int depth);

/* <tag>value</tag>, with the string form choosing base64 when XML cannot carry it. */
static int decode_value(dec_t *d, const char *tag, const marie_tfield_t *f, int64_t *intval, int depth)
{
    marie_buf_t *o = d->out;
    if (f->prim == MARIE_PRIM_STRING) {
        uint64_t u;
        if (get_be(d, 4, &u) < 0)
            return -1;
        int32_t n = (int32_t)u;
        if (n < 1 || (size_t)n > d->len - d->pos)
            return dec_fail(d, "bad string length");
        const char *s = (const char *)d->p + d->pos;
        if (s[n - 1] != '\0')
            return dec_fail(d, "string not NUL-terminated");
        d->pos += (size_t)n;
        if (xb_xml_safe(s, (size_t)n - 1))
            return put_tag(o, "<", tag) < 0 || xb_escape(o, s, (size_t)n - 1) < 0 ||
                   put_tag(o, "</", tag) < 0 ? -1 : 0;
        return marie_buf_printf(o, "<%s encoding=\"base64\">", tag) < 0 ||
               xb_base64_encode(o, (const uint8_t *)s, (size_t)n - 1) < 0 ||
               put_tag(o, "</", tag) < 0 ? -1 : 0;
    }
    if (put_tag(o, "<", tag) < 0)
        return -1;
    if (f->prim == MARIE_PRIM_STRUCT) {
        if (decode_struct(d, f->sub, depth + 1) < 0)
            return -1;
    } else if (put_scalar_text(d, f->prim, intval) < 0) {
        return -1;
    }
    return put_tag(o, "</", tag);
}

static int decode_struct(dec_t *d, const marie_typeinfo_t *t, int depth)
{
    if (depth > XB_MAX_STRUCT_DEPTH)
        return dec_fail(d, "structs nested too deeply");
    int nf = t->nfields, rc = -1;
    int64_t len_s[32];
    int64_t *lenval = nf > 32 ? calloc((size_t)nf, sizeof *lenval) : len_s;
    if (!lenval)
        return dec_fail(d, "out of memory");
    for (int i = 0; i < nf; i++) {
        const marie_tfield_t *f = &t->fields[i];
        lenval[i] = 0;
        if (f->ndims == 0) {
            if (decode_value(d, f->name, f, &lenval[i], depth) < 0)
                goto out;
            continue;
        }
        long count = 1;
        for (int k = 0; k < f->ndims; k++) {
            int lf = f->dims[k].len_field;
            int64_t size = lf < 0 ? f->dims[k].size : lenval[lf];
            if (size < 0) {
                dec_fail(d, "negative array length");
                goto out;
            }
            if (size > 0 && count > XB_MAX_ELEMENTS / size) {
                dec_fail(d, "array too large");
                goto out;
            }
            count *= (long)size;
        }
        static const int minsize[] = { 1, 2, 4, 8, 1, 4, 8, 5, 1, 0 };
        if (minsize[f->prim] && (size_t)count > (d->len - d->pos) / (size_t)minsize[f->prim]) {
            dec_fail(d, "array longer than the message");
            goto out;
        }
        marie_buf_t *o = d->out;
        if (put_tag(o, "<", f->name) < 0)
            goto out;
        if (f->prim == MARIE_PRIM_BYTE) {
            if (xb_base64_encode(o, d->p + d->pos, (size_t)count) < 0)
                goto out;
            d->pos += (size_t)count;
        } else if (f->prim == MARIE_PRIM_STRING || f->prim == MARIE_PRIM_STRUCT) {
            for (long k = 0; k < count; k++)
                if (decode_value(d, "item", f, NULL, depth) < 0)
                    goto out;
        } else {
            for (long k = 0; k < count; k++)
                if ((k && marie_buf_put(o, " ", 1) < 0) || put_scalar_text(d, f->prim, NULL) < 0)
                    goto out;
        }
        if (put_tag(o, "</", f->name) < 0)
            goto out;
    }
    rc = 0;
out:
    if (lenval != len_s)
        free(lenval);
    return rc;
}

int xb_decode(const marie_typeinfo_t *t, const void *data, size_t len, marie_buf_t *out, xb_error_t *err)
{
    dec_t d = { data, len, 0, out, err, t->name };
    size_t start = out->len;
    uint64_t fp;
    if (get_be(&d, 8, &fp) < 0)
        goto fail;
    if ((int64_t)fp != t->fingerprint) {
        xb_error_set(err, "bad-fingerprint", "payload is not a %s (fingerprint %016llx)", t->name,
                     (unsigned long long)fp);
        goto fail;
    }
    if (decode_struct(&d, t, 0) < 0)
        goto fail;
    if (d.pos != d.len) {
        xb_error_set(err, "bad-message", "%s: %zu bytes after the end of the message", t->name, d.len - d.pos);
        goto fail;
    }
    /* The verdict components get from marie_decode_checked: what they refuse is not passed on. */
    if (marie_typeinfo_check(t, data, len) < 0) {
        xb_error_set(err, "bad-message", "%s: not a well-formed message", t->name);
        goto fail;
    }
    return 0;
fail:
    if (out->failed)
        xb_error_set(err, "too-large", "decoded %s larger than %zu bytes", t->name, out->max);
    out->len = start;
    out->failed = false;
    return marie_fail(EBADMSG);
}

