/* topic_encode: a message given as YAML or JSON ({utime: 1, pose: {x: 2}}) encoded as an LCM
 * payload of any described type, marie's or a user's (core/typeinfo.h): missing fields are zero,
 * a length field left out is the length of its array. */
#include "tools/topic/topic.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "core/log.h"

static void put_be(marie_buf_t *b, uint64_t v, int n)
{
    uint8_t x[8];
    for (int i = 0; i < n; i++)
        x[i] = (uint8_t)(v >> (8 * (n - 1 - i)));
    marie_buf_put(b, x, (size_t)n);
}

static int fail(char *why, size_t len, const char *path, const char *what)
{
    return marie_fail_why(why, len, "%s: %s", path[0] ? path : "message", what);
}

static int put_prim(marie_buf_t *b, marie_prim_t p, const marie_node_t *n, const char *path, char *why, size_t wl)
{
    if (n && n->kind != MARIE_NODE_SCALAR)
        return fail(why, wl, path, "expected a single value");
    marie_errors_t errs = {0};
    int rc = 0;
    if (p == MARIE_PRIM_STRING) {
        const char *s = n ? n->value : "";
        put_be(b, strlen(s) + 1, 4);
        marie_buf_put(b, s, strlen(s) + 1);
    } else if (p == MARIE_PRIM_FLOAT || p == MARIE_PRIM_DOUBLE) {
        double d = 0;
        rc = n ? marie_node_double(n, &d, &errs) : 0;
        float f = (float)d;
        uint64_t bits = 0;
        if (p == MARIE_PRIM_FLOAT) {
            uint32_t u;
            memcpy(&u, &f, 4);
            bits = u;
        } else {
            memcpy(&bits, &d, 8);
        }
        put_be(b, bits, p == MARIE_PRIM_FLOAT ? 4 : 8);
    } else if (p == MARIE_PRIM_BOOL) {
        bool v = false;
        rc = n ? marie_node_bool(n, &v, &errs) : 0;
        put_be(b, v, 1);
    } else {
        int64_t v = 0;
        int size = marie_prim_size(p);
        rc = n ? marie_node_int(n, &v, &errs) : 0;
        int64_t hi = p == MARIE_PRIM_BYTE ? 255 : size == 8 ? INT64_MAX : (INT64_C(1) << (8 * size - 1)) - 1;
        int64_t lo = p == MARIE_PRIM_BYTE ? 0 : size == 8 ? INT64_MIN : -hi - 1;
        if (rc == 0 && (v < lo || v > hi))
            rc = -1;
        put_be(b, (uint64_t)v, size);
    }
    marie_errors_clear(&errs);
    return rc < 0 ? fail(why, wl, path, marie_prim_name(p)) : 0;
}

static int put_struct(marie_buf_t *b, const marie_typeinfo_t *t, const marie_node_t *n, const char *path, char *why,
                      size_t wl, int depth);

/* One element (scalar or struct) of field f. */
static int put_elem(marie_buf_t *b, const marie_tfield_t *f, const marie_node_t *n, const char *path, char *why,
                    size_t wl, int depth)
{
    return f->prim == MARIE_PRIM_STRUCT ? put_struct(b, f->sub, n, path, why, wl, depth + 1)
                                        : put_prim(b, f->prim, n, path, why, wl);
}

/* Dimensions d.. of field f from the nested sequences n (NULL: zeros); lens[] are the lengths. */
static int put_dims(marie_buf_t *b, const marie_tfield_t *f, int d, const int64_t *lens, const marie_node_t *n,
                    const char *path, char *why, size_t wl, int depth)
{
    if (d == f->ndims)
        return put_elem(b, f, n, path, why, wl, depth);
    if (n && n->kind != MARIE_NODE_SEQ)
        return fail(why, wl, path, "expected a list");
    if (n && (int64_t)n->n != lens[d])
        return fail(why, wl, path, "the list's length differs from its length field");
    for (int64_t i = 0; i < lens[d]; i++) {
        char sub[512];
        snprintf(sub, sizeof sub, "%s[%lld]", path, (long long)i);
        if (put_dims(b, f, d + 1, lens, n ? n->items[i] : NULL, sub, why, wl, depth) < 0)
            return -1;
    }
    return 0;
}

/* The length a length field takes: given, or the length of the first array that names it. */
static int64_t length_of(const marie_typeinfo_t *t, int field, const marie_node_t *n)
{
    const marie_node_t *given = marie_node_get(n, t->fields[field].name);
    int64_t v = 0;
    marie_errors_t errs = {0};
    if (given && marie_node_int(given, &v, &errs) == 0)
        return v;
    marie_errors_clear(&errs);
    for (int i = field + 1; i < t->nfields; i++)
        for (int d = 0; d < t->fields[i].ndims; d++)
            if (t->fields[i].dims[d].len_field == field) {
                const marie_node_t *a = marie_node_get(n, t->fields[i].name);
                for (int k = 0; a && k < d && a->kind == MARIE_NODE_SEQ && a->n; k++)
                    a = a->items[0];
                return a && a->kind == MARIE_NODE_SEQ ? (int64_t)a->n : 0;
            }
    return 0;
}

static int put_struct(marie_buf_t *b, const marie_typeinfo_t *t, const marie_node_t *n, const char *path, char *why,
                      size_t wl, int depth)
{
    if (depth > 16)
        return fail(why, wl, path, "nested too deep");
    if (n && n->kind != MARIE_NODE_MAP)
        return fail(why, wl, path, "expected a mapping of fields");
    for (size_t i = 0; n && i < n->n; i++) {
        int known = 0;
        for (int k = 0; k < t->nfields && !known; k++)
            known = strcmp(t->fields[k].name, n->items[i]->key) == 0;
        if (!known) {
            char sub[512];
            snprintf(sub, sizeof sub, "%s%s%s", path, path[0] ? "." : "", n->items[i]->key);
            return fail(why, wl, sub, "no such field");
        }
    }
    int64_t values[256] = {0};
    for (int i = 0; i < t->nfields && i < 256; i++) {
        const marie_tfield_t *f = &t->fields[i];
        char sub[512];
        snprintf(sub, sizeof sub, "%s%s%s", path, path[0] ? "." : "", f->name);
        const marie_node_t *v = marie_node_get(n, f->name);
        if (f->ndims == 0 && f->prim != MARIE_PRIM_STRUCT && f->prim != MARIE_PRIM_STRING && marie_prim_size(f->prim) &&
            f->prim != MARIE_PRIM_FLOAT && f->prim != MARIE_PRIM_DOUBLE && f->prim != MARIE_PRIM_BOOL) {
            values[i] = length_of(t, i, n);
            char text[32];
            snprintf(text, sizeof text, "%lld", (long long)values[i]);
            marie_node_t tmp = {.kind = MARIE_NODE_SCALAR, .value = text, .key = (char *)f->name};
            if (put_prim(b, f->prim, v ? v : &tmp, sub, why, wl) < 0)
                return -1;
            continue;
        }
        int64_t lens[8] = {0};
        for (int d = 0; d < f->ndims && d < 8; d++)
            lens[d] = f->dims[d].len_field >= 0 ? values[f->dims[d].len_field] : f->dims[d].size;
        if (put_dims(b, f, 0, lens, v, sub, why, wl, depth) < 0)
            return -1;
    }
    return 0;
}

int topic_encode(const marie_typeinfo_t *t, const char *text, marie_buf_t *out, char *why, size_t whylen)
{
    marie_errors_t errs = {0};
    marie_doc_t *d = marie_doc_parse("message", text, strlen(text), &errs);
    if (!d) {
        snprintf(why, whylen, "%s", errs.n ? errs.msgs[0] : "not YAML");
        marie_errors_clear(&errs);
        return -1;
    }
    const marie_node_t *root = marie_doc_root(d);
    if (root && root->kind == MARIE_NODE_SCALAR && !root->value[0])
        root = NULL;            /* '' or {}: every field zero */
    marie_buf_reset(out);
    put_be(out, (uint64_t)t->fingerprint, 8);
    int rc = put_struct(out, t, root, "", why, whylen, 0);
    marie_doc_destroy(d);
    if (rc == 0 && (out->failed || marie_typeinfo_check(t, out->data, out->len) < 0))
        rc = fail(why, whylen, "", "does not encode to a well-formed message");
    return rc;
}
