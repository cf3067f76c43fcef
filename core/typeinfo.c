/* typeinfo: lookups in the generated type descriptors (marie's and users' modules), and the payload checker. */
#include "core/typeinfo.h"

#include <dlfcn.h>
#include <errno.h>
#include <glob.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "core/err.h"

/* ---- the registry: marie's own types, then the modules of users' types ---- */

#define MAX_MODULES 64
static const marie_types_module_t *modules[MAX_MODULES];
static size_t nmodules;

static const marie_typeinfo_t *info_named(const marie_typeinfo_t *t, const char *name)
{
    return strcmp(t->name, name) == 0 || strcmp(t->short_name, name) == 0 ? t : NULL;
}

const marie_typeinfo_t *marie_typeinfo_find(const char *name)
{
    for (size_t i = 0; i < marie_typeinfos_count; i++)
        if (info_named(marie_typeinfos[i], name))
            return marie_typeinfos[i];
    for (size_t m = 0; m < nmodules; m++)
        for (const marie_typeinfo_t *const *t = modules[m]->infos; *t; t++)
            if (strcmp((*t)->name, name) == 0)      /* users' types by their full name only */
                return *t;
    return NULL;
}

static const marie_typeinfo_t *by_fingerprint(int64_t fp)
{
    for (size_t i = 0; i < marie_typeinfos_count; i++)
        if (marie_typeinfos[i]->fingerprint == fp)
            return marie_typeinfos[i];
    for (size_t m = 0; m < nmodules; m++)
        for (const marie_typeinfo_t *const *t = modules[m]->infos; *t; t++)
            if ((*t)->fingerprint == fp)
                return *t;
    return NULL;
}

/* Each decode looks its type up two or three times: each thread keeps the types it found (a
 * search goes through every built-in type, 50-100 ns). Types are never taken away, so an entry
 * stays true; one not found is not kept (its module may come later). */
#define FOUND_CACHE 16
const marie_typeinfo_t *marie_typeinfo_by_fingerprint(int64_t fp)
{
    static _Thread_local struct {
        int64_t fp;
        const marie_typeinfo_t *t;
    } found[FOUND_CACHE];
    unsigned k = (unsigned)((uint64_t)fp ^ (uint64_t)fp >> 29) % FOUND_CACHE;
    if (found[k].t && found[k].fp == fp)
        return found[k].t;
    const marie_typeinfo_t *t = by_fingerprint(fp);
    if (t) {
        found[k].fp = fp;
        found[k].t = t;
    }
    return t;
}

const marie_type_t *marie_type_find(const char *name)
{
    for (size_t i = 0; name && *name && marie_types[i]; i++) {
        const char *tn = marie_types[i]->name;
        if (strcmp(tn, name) == 0 || (strncmp(tn, "marie.", 6) == 0 && strcmp(tn + 6, name) == 0))
            return marie_types[i];
    }
    for (size_t m = 0; name && m < nmodules; m++)
        for (const marie_type_t *const *t = modules[m]->types; *t; t++)
            if (strcmp((*t)->name, name) == 0)
                return *t;
    return NULL;
}

const marie_type_t *marie_type_by_fingerprint(int64_t fp)
{
    for (size_t i = 0; marie_types[i]; i++)
        if (marie_types[i]->hash() == fp)
            return marie_types[i];
    for (size_t m = 0; m < nmodules; m++)
        for (const marie_type_t *const *t = modules[m]->types; *t; t++)
            if ((*t)->hash() == fp)
                return *t;
    return NULL;
}

const marie_typeinfo_t *marie_typeinfo_at(size_t i)
{
    if (i < marie_typeinfos_count)
        return marie_typeinfos[i];
    i -= marie_typeinfos_count;
    for (size_t m = 0; m < nmodules; m++)
        for (const marie_typeinfo_t *const *t = modules[m]->infos; *t; t++)
            if (i-- == 0)
                return *t;
    return NULL;
}

int marie_types_register(const marie_types_module_t *m)
{
    if (!m || m->version != MARIE_TYPES_MODULE_VERSION || !m->types || !m->infos)
        return marie_fail(EINVAL);
    for (size_t i = 0; i < nmodules; i++)
        if (modules[i] == m || strcmp(modules[i]->name, m->name) == 0)
            return 0;
    if (nmodules == MAX_MODULES)
        return marie_fail(ENOSPC);
    modules[nmodules++] = m;
    return 0;
}

static int load_so(const char *path, char *why, size_t whylen)
{
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        snprintf(why, whylen, "%s", dlerror());
        return marie_fail(ENOENT);
    }
    const marie_types_module_t *const *m = dlsym(lib, "marie_types_module");
    if (!m || !*m) {
        snprintf(why, whylen, "%s: not a library of marie-types-gen (no marie_types_module)", path);
        dlclose(lib);
        return marie_fail(EINVAL);
    }
    if (marie_types_register(*m) < 0) {
        snprintf(why, whylen, "%s: %s", path, errno == ENOSPC ? "too many type libraries" : "made by another version of marie-types-gen");
        dlclose(lib);
        return -1;
    }
    return 0;       /* kept open: the registry points into it */
}

int marie_types_load(const char *path, const char *base_dir, char *why, size_t whylen)
{
    char full[4096], pattern[4200];
    if (path[0] != '/' && base_dir)
        snprintf(full, sizeof full, "%s/%s", base_dir, path);
    else
        snprintf(full, sizeof full, "%s", path);
    struct stat st;
    if (stat(full, &st) < 0) {
        snprintf(why, whylen, "types %s: %s", full, strerror(errno));
        return -1;
    }
    if (!S_ISDIR(st.st_mode))
        return load_so(full, why, whylen);
    snprintf(pattern, sizeof pattern, "%s/lib/libmarie-types-*.so", full);
    glob_t g;
    int rc = glob(pattern, 0, NULL, &g);
    if (rc != 0) {
        snprintf(why, whylen, "types %s: no lib/libmarie-types-*.so in it (made by marie-types-gen?)", full);
        return marie_fail(ENOENT);
    }
    for (size_t i = 0; rc == 0 && i < g.gl_pathc; i++)
        rc = load_so(g.gl_pathv[i], why, whylen);
    globfree(&g);
    return rc;
}

int marie_types_load_list(const char *list, char *why, size_t whylen)
{
    char *copy = list ? strdup(list) : NULL, *save = NULL;
    if (list && !copy)
        return -1;
    int rc = 0;
    for (char *p = copy ? strtok_r(copy, ":", &save) : NULL; p && rc == 0; p = strtok_r(NULL, ":", &save))
        rc = marie_types_load(p, NULL, why, whylen);
    free(copy);
    return rc;
}

const char *marie_prim_name(marie_prim_t p)
{
    static const char *const names[] = {"int8_t", "int16_t", "int32_t", "int64_t", "byte",
                                        "float", "double", "string", "boolean", "struct"};
    return (unsigned)p < sizeof names / sizeof names[0] ? names[p] : "?";
}

#define MAX_DEPTH 16

typedef struct {
    const uint8_t *buf;
    size_t len, pos;
    int flags;          /* MARIE_CHECK_* */
    bool nonfinite;     /* a float or double was NaN or infinite */
} cursor_t;

int64_t marie_wire_int(const uint8_t *p, int n)
{
    uint64_t v = 0;
    for (int i = 0; i < n; i++)
        v = v << 8 | p[i];
    /* sign-extend */
    if (n < 8 && (v >> (8 * n - 1)) & 1)
        v |= ~0ULL << (8 * n);
    return (int64_t)v;
}

int marie_prim_size(marie_prim_t p)
{
    switch (p) {
    case MARIE_PRIM_INT8: case MARIE_PRIM_BYTE: case MARIE_PRIM_BOOL: return 1;
    case MARIE_PRIM_INT16: return 2;
    case MARIE_PRIM_INT32: case MARIE_PRIM_FLOAT: return 4;
    case MARIE_PRIM_INT64: case MARIE_PRIM_DOUBLE: return 8;
    default: return 0;
    }
}

static int walk_struct(const marie_typeinfo_t *t, cursor_t *c, int depth);

/* Notes a NaN or infinity among n floats or doubles of field f at the cursor (big-endian IEEE
 * 754), unless the field gives them a meaning. */
static void scan_finite(cursor_t *c, const marie_tfield_t *f, int64_t n)
{
    marie_prim_t prim = f->prim;
    if (!(c->flags & MARIE_CHECK_FINITE) || (prim != MARIE_PRIM_FLOAT && prim != MARIE_PRIM_DOUBLE) ||
        (f->flags & MARIE_TFIELD_NONFINITE))
        return;
    /* All exponent bits set is NaN or an infinity; big-endian, they are in the first two bytes. */
    size_t size = prim == MARIE_PRIM_FLOAT ? 4 : 8;
    uint8_t mask1 = prim == MARIE_PRIM_FLOAT ? 0x80 : 0xf0;
    const uint8_t *p = c->buf + c->pos, *end = p + (size_t)n * size;
    for (; p < end; p += size)
        if ((p[0] & 0x7f) == 0x7f && (p[1] & mask1) == mask1) {
            c->nonfinite = true;
            return;
        }
}

/* One element of field f; an integer scalar's value is stored in *value (array lengths). */
static int walk_element(const marie_tfield_t *f, cursor_t *c, int depth, int64_t *value)
{
    size_t room = c->len - c->pos;
    if (f->prim == MARIE_PRIM_STRING) {
        if (room < 4)
            return -1;
        int64_t n = marie_wire_int(c->buf + c->pos, 4);
        if (n < 1 || (uint64_t)n > room - 4 || c->buf[c->pos + 4 + (size_t)n - 1] != 0)
            return -1;
        c->pos += 4 + (size_t)n;
        return 0;
    }
    if (f->prim == MARIE_PRIM_STRUCT)
        return walk_struct(f->sub, c, depth + 1);
    int size = marie_prim_size(f->prim);
    if (!size || room < (size_t)size)
        return -1;
    if (value)
        *value = marie_wire_int(c->buf + c->pos, size);
    scan_finite(c, f, 1);
    c->pos += (size_t)size;
    return 0;
}

static int walk_struct(const marie_typeinfo_t *t, cursor_t *c, int depth)
{
    if (depth > MAX_DEPTH)
        return -1;
    int64_t values[256];
    for (int i = 0; i < t->nfields; i++) {
        const marie_tfield_t *f = &t->fields[i];
        int64_t count = 1;
        for (int d = 0; d < f->ndims; d++) {
            int64_t n = f->dims[d].len_field >= 0 ? (f->dims[d].len_field < 256 ? values[f->dims[d].len_field] : -1)
                                                  : f->dims[d].size;
            /* Every element takes at least one byte: a count past the payload is a lie. */
            if (n < 0 || n > (int64_t)(c->len - c->pos) || (n && count > (int64_t)(c->len - c->pos) / n))
                return -1;
            count *= n;
        }
        int size = marie_prim_size(f->prim);
        if (f->ndims > 0 && size) {
            /* Arrays of fixed-size primitives: only their extent matters. */
            if ((uint64_t)count * (uint64_t)size > c->len - c->pos)
                return -1;
            scan_finite(c, f, count);
            c->pos += (size_t)count * (size_t)size;
            continue;
        }
        for (int64_t k = 0; k < count; k++)
            if (walk_element(f, c, depth, (f->ndims == 0 && i < 256) ? &values[i] : NULL) < 0)
                return -1;
    }
    return 0;
}

/* Bytes field f always takes on the wire (a scalar, or a struct of such: nested structs carry no
 * fingerprint), or -1 when that depends on the message. */
static int fixed_wire_size(const marie_tfield_t *f, int depth)
{
    if (f->ndims != 0 || depth > MAX_DEPTH)
        return -1;
    if (f->prim != MARIE_PRIM_STRUCT)
        return marie_prim_size(f->prim) ? marie_prim_size(f->prim) : -1;
    int sum = 0;
    for (int i = 0; i < f->sub->nfields; i++) {
        int size = fixed_wire_size(&f->sub->fields[i], depth + 1);
        if (size < 0)
            return -1;
        sum += size;
    }
    return sum;
}

int marie_typeinfo_tail(const marie_typeinfo_t *t, marie_tail_t *out)
{
    if (!t || t->nfields < 2)
        return marie_fail(ENOTSUP);
    const marie_tfield_t *last = &t->fields[t->nfields - 1];
    if ((last->prim != MARIE_PRIM_BYTE && last->prim != MARIE_PRIM_INT8) || last->ndims != 1 ||
        last->dims[0].len_field < 0 || t->fields[last->dims[0].len_field].prim != MARIE_PRIM_INT32)
        return marie_fail(ENOTSUP);
    size_t wire = 8;            /* the fingerprint */
    for (int i = 0; i < t->nfields - 1; i++) {
        int size = fixed_wire_size(&t->fields[i], 0);
        if (size < 0)
            return marie_fail(ENOTSUP);
        if (i == last->dims[0].len_field)
            out->len_wire_off = wire;
        wire += (size_t)size;
    }
    out->wire_off = wire;
    out->ptr_off = last->c_offset;
    out->len_off = t->fields[last->dims[0].len_field].c_offset;
    return 0;
}

int64_t marie_payload_fingerprint(const void *buf, size_t len)
{
    return len < 8 ? 0 : marie_wire_int(buf, 8);
}

int marie_typeinfo_check_flags(const marie_typeinfo_t *t, const void *buf, size_t len, int flags)
{
    if (!t || len < 8 || marie_wire_int(buf, 8) != t->fingerprint)
        return marie_fail(EBADMSG);
    cursor_t c = {buf, len, 8, flags, false};
    if (walk_struct(t, &c, 0) < 0 || c.pos != len)
        return marie_fail(EBADMSG);
    return c.nonfinite ? marie_fail(EDOM) : 0;
}

int marie_typeinfo_check(const marie_typeinfo_t *t, const void *buf, size_t len)
{
    return marie_typeinfo_check_flags(t, buf, len, 0);
}

#define DECODE_VIEW 0x100     /* beside MARIE_CHECK_FINITE */
#define VIEW_HEAD_MAX 256

/* A checked payload of a type with a tail (marie_typeinfo_tail): lcm-gen's decoder runs on its
 * head alone, the array's length there set to 0, and the array's pointer then aims into buf.
 * 1 when done so, 0 for a type of another shape (decode it whole), -1 with errno EBADMSG. */
static int decode_view(const marie_type_t *t, const uint8_t *buf, void *out)
{
    marie_tail_t tl;
    if (marie_typeinfo_tail(marie_typeinfo_by_fingerprint(t->hash()), &tl) < 0 || tl.wire_off > VIEW_HEAD_MAX)
        return 0;
    uint8_t head[VIEW_HEAD_MAX];
    memcpy(head, buf, tl.wire_off);
    memset(head + tl.len_wire_off, 0, 4);
    if (t->decode(head, 0, (int)tl.wire_off, out) != (int)tl.wire_off)
        return marie_fail(EBADMSG);
    int32_t n = (int32_t)marie_wire_int(buf + tl.len_wire_off, 4);
    const uint8_t *at = buf + tl.wire_off;
    memcpy((uint8_t *)out + tl.len_off, &n, sizeof n);
    memcpy((uint8_t *)out + tl.ptr_off, &at, sizeof at);
    return 1;
}

/* The one place in marie where lcm-gen's decoder runs on bytes from outside the process
 * (tests/core/test_decode_rule.sh keeps it so). */
static int decode(const marie_type_t *t, const void *buf, size_t len, void *out, int flags, const char **why)
{
    const char *dummy;
    why = why ? why : &dummy;
    *why = "bad_fingerprint";
    if (marie_payload_fingerprint(buf, len) != t->hash() || len < 8)
        return marie_fail(EBADMSG);
    *why = "bad_payload";
    int rc = len > INT32_MAX ? marie_fail(EBADMSG)
                             : marie_typeinfo_check_flags(marie_typeinfo_by_fingerprint(t->hash()), buf, len, flags & ~DECODE_VIEW);
    if (rc < 0 && errno == EDOM)
        *why = "bad_nonfinite";
    if (rc < 0)
        return -1;
    memset(out, 0, t->size);
    if (flags & DECODE_VIEW) {
        int rc = decode_view(t, buf, out);
        if (rc != 0)
            return rc;
    }
    return t->decode(buf, 0, (int)len, out) < 0 ? marie_fail(EBADMSG) : 0;
}

int marie_decode_checked(const marie_type_t *t, const void *buf, size_t len, void *out)
{
    return decode(t, buf, len, out, 0, NULL) < 0 ? marie_fail(EBADMSG) : 0;
}

int marie_decode_input(const marie_type_t *t, const void *buf, size_t len, void *out, const char **why)
{
    return decode(t, buf, len, out, MARIE_CHECK_FINITE, why);
}

int marie_decode_view(const marie_type_t *t, const void *buf, size_t len, void *out, const char **why)
{
    return decode(t, buf, len, out, MARIE_CHECK_FINITE | DECODE_VIEW, why);
}

void marie_decode_cleanup_view(const marie_type_t *t, void *out, int viewed)
{
    marie_tail_t tl;
    if (viewed == 1 && marie_typeinfo_tail(marie_typeinfo_by_fingerprint(t->hash()), &tl) == 0)
        memset((uint8_t *)out + tl.ptr_off, 0, sizeof(void *));     /* not decode_cleanup's to free */
    t->decode_cleanup(out);
}
