/* vjson: the viewer's JSON: any marie message written from its type descriptor (the payload
 * walked as the XML bridge walks it), with a small table of what the page calls each type. */
#include "tools/webcommon/vjson.h"

#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/base64.h"
#include "core/err.h"
#include "core/typeinfo.h"

void vj_str(marie_buf_t *b, const char *s)
{
    marie_buf_json_str(b, s);
}

void vj_num(marie_buf_t *b, double v, int prec)
{
    if (!isfinite(v)) {
        marie_buf_put(b, "null", 4);
        return;
    }
    char tmp[64];
    int n = snprintf(tmp, sizeof tmp, "%.*f", prec, v);
    /* Trim trailing zeros: "1.500" -> "1.5", "2.000" -> "2", "-0" -> "0". */
    if (prec > 0) {
        while (n > 1 && tmp[n - 1] == '0')
            n--;
        if (tmp[n - 1] == '.')
            n--;
    }
    tmp[n] = 0;
    if (strcmp(tmp, "-0") == 0)
        marie_buf_put(b, "0", 1);
    else
        marie_buf_put(b, tmp, (size_t)n);
}

/* Decimal digits of v, backwards from end; returns the first. */
static char *digits_of(char *end, uint64_t v)
{
    do {
        *--end = (char)('0' + v % 10);
        v /= 10;
    } while (v);
    return end;
}

void vj_int(marie_buf_t *b, int64_t v)
{
    char tmp[24], *end = tmp + sizeof tmp;
    char *o = digits_of(end, v < 0 ? 0 - (uint64_t)v : (uint64_t)v);
    if (v < 0)
        *--o = '-';
    marie_buf_put(b, o, (size_t)(end - o));
}

void vj_base64(marie_buf_t *b, const void *data, size_t n)
{
    size_t m = marie_base64_len(n);
    if (marie_buf_reserve(b, m + 2) < 0)
        return;
    b->data[b->len] = '"';
    marie_base64_encode(b->data + b->len + 1, data, n);
    b->len += m + 2;
    b->data[b->len - 1] = '"';
    b->data[b->len] = 0;
}

const marie_type_t *vj_type_of(const void *data, size_t len)
{
    return len < 8 ? NULL : marie_type_by_fingerprint(marie_payload_fingerprint(data, len));
}

/* ---- messages: one walker over the type descriptors ---- */

/* What the page knows of a type: its kind, and the most elements of any top-level
 * variable-length array of numbers it is sent (0: all). A type missing here is still sent,
 * its kind being its LCM name. */
static const struct {
    const char *type;
    const char *kind;
    int max_elems;
} kinds[] = {
    /* 720 beams are enough to draw a scan, whatever the sensor; 1500 particles a cloud. */
    {"marie.laser_scan_t", "laser", 720},
    {"marie.particle_cloud_t", "particles", 1500},
    {"marie.pose_cov_t", "pose", 0},
    {"marie.path_t", "path", 0},
    {"marie.goal_t", "goal", 0},
    {"marie.arbitration_t", "arb", 0},
    {"marie.event_t", "event", 0},
    {"marie.heartbeat_t", "hb", 0},
    {"marie.am_status_t", "am", 0},
    {"marie.am_reply_t", "reply", 0},
    {"marie.occupancy_grid_t", "map", 0},
    {"marie.tag_detections_t", "tags", 0},
    {"marie.landmarks_t", "landmarks", 0},
};

static int kind_index(const marie_typeinfo_t *t)
{
    for (size_t i = 0; t && i < sizeof kinds / sizeof kinds[0]; i++)
        if (strcmp(kinds[i].type, t->name) == 0)
            return (int)i;
    return -1;
}

const char *vj_kind(const marie_typeinfo_t *t)
{
    int i = kind_index(t);
    return i < 0 ? NULL : kinds[i].kind;
}

#define VJ_MAX_STRIDES 8

typedef struct {
    marie_buf_t *b;
    const uint8_t *p;           /* cursor in a checked payload */
    int max_elems;
    int nstrides;
    const char *stride_field[VJ_MAX_STRIDES];
    int64_t stride[VJ_MAX_STRIDES];
} walk_t;

/* A real with `digits` significant digits (about what a float or a double holds), no trailing
 * zeros, NaN and infinities as null: the text of "%.*g", but through an integer scaled by a
 * power of ten in the usual range, as "%g" is ten times slower and a particle cloud is
 * thousands of numbers. */
static void real(marie_buf_t *b, double v, int digits)
{
    static const double p10[] = {1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12,
                                 1e13, 1e14, 1e15, 1e16, 1e17};
    if (!isfinite(v)) {
        marie_buf_put(b, "null", 4);
        return;
    }
    double a = fabs(v);
    int dec = a >= 1e-4 ? digits - 1 - (int)floor(log10(a)) : -1;
    if (a == 0 || dec < 0 || dec >= (int)(sizeof p10 / sizeof p10[0])) {
        char tmp[40];
        int n = snprintf(tmp, sizeof tmp, "%.*g", digits, a == 0 ? 0.0 : v);
        marie_buf_put(b, tmp, (size_t)n);
        return;
    }
    uint64_t scaled = (uint64_t)nearbyint(a * p10[dec]), unit = (uint64_t)p10[dec];
    uint64_t ip = scaled / unit, fp = scaled % unit;
    char tmp[48], *end = tmp + sizeof tmp, *o = end;
    if (fp) {
        int nd = dec;
        while (fp % 10 == 0) {
            fp /= 10;
            nd--;
        }
        char *f = digits_of(o, fp);
        while (end - f < nd)
            *--f = '0';
        o = f;
        *--o = '.';
    }
    o = digits_of(o, ip);
    if (v < 0 && scaled)
        *--o = '-';
    marie_buf_put(b, o, (size_t)(end - o));
}

static void walk_struct(walk_t *w, const marie_typeinfo_t *t, int depth);

/* One value of a field at the cursor; an integer's value goes to *ival (array lengths). */
static void walk_value(walk_t *w, const marie_tfield_t *f, int depth, int64_t *ival)
{
    const uint8_t *p = w->p;
    int64_t iv = 0;
    switch (f->prim) {
    case MARIE_PRIM_STRING: {
        int64_t n = marie_wire_int(p, 4);
        vj_str(w->b, (const char *)p + 4);      /* NUL-terminated: checked */
        w->p += 4 + (size_t)n;
        return;
    }
    case MARIE_PRIM_STRUCT:
        walk_struct(w, f->sub, depth + 1);
        return;
    case MARIE_PRIM_FLOAT: {
        uint32_t u = (uint32_t)marie_wire_int(p, 4);
        float x;
        memcpy(&x, &u, 4);
        real(w->b, x, 7);
        break;
    }
    case MARIE_PRIM_DOUBLE: {
        uint64_t u = (uint64_t)marie_wire_int(p, 8);
        double x;
        memcpy(&x, &u, 8);
        real(w->b, x, 10);
        break;
    }
    case MARIE_PRIM_BOOL:
        marie_buf_puts(w->b, *p ? "true" : "false");
        break;
    case MARIE_PRIM_BYTE:
        iv = *p;
        vj_int(w->b, iv);
        break;
    default:
        iv = marie_wire_int(p, marie_prim_size(f->prim));
        vj_int(w->b, iv);
        break;
    }
    if (ival)
        *ival = iv;
    w->p += marie_prim_size(f->prim);
}

/* Dimension d of an array field: nested JSON arrays, bytes (byte or int8) as one base64
 * string. A top-level variable-length array of numbers longer than max_elems is sent as
 * every stride-th element; the stride is noted for the frame. */
static void walk_array(walk_t *w, const marie_tfield_t *f, const int64_t *vals, int d, int depth)
{
    const marie_tdim_t *dim = &f->dims[d];
    int64_t n = dim->len_field >= 0 ? vals[dim->len_field] : dim->size;
    int size = marie_prim_size(f->prim);
    bool last = d == f->ndims - 1;
    if (last && (f->prim == MARIE_PRIM_BYTE || f->prim == MARIE_PRIM_INT8)) {
        vj_base64(w->b, w->p, (size_t)n);
        w->p += (size_t)n;
        return;
    }
    int64_t step = 1;
    if (last && depth == 0 && f->ndims == 1 && dim->len_field >= 0 && size && w->max_elems > 0 &&
        n > w->max_elems && w->nstrides < VJ_MAX_STRIDES) {
        step = (n + w->max_elems - 1) / w->max_elems;
        w->stride_field[w->nstrides] = f->name;
        w->stride[w->nstrides++] = step;
    }
    const uint8_t *start = w->p;
    marie_buf_put(w->b, "[", 1);
    for (int64_t i = 0; i < n; i += step) {
        if (i)
            marie_buf_put(w->b, ",", 1);
        if (step > 1)
            w->p = start + (size_t)i * (size_t)size;
        if (last)
            walk_value(w, f, depth, NULL);
        else
            walk_array(w, f, vals, d + 1, depth);
    }
    if (step > 1)
        w->p = start + (size_t)n * (size_t)size;
    marie_buf_put(w->b, "]", 1);
}

static void walk_struct(walk_t *w, const marie_typeinfo_t *t, int depth)
{
    int64_t vals[256];      /* integer fields, for the lengths of later arrays (checked: < 256) */
    marie_buf_put(w->b, "{", 1);
    for (int i = 0; i < t->nfields; i++) {
        const marie_tfield_t *f = &t->fields[i];
        marie_buf_put(w->b, i ? ",\"" : "\"", i ? 2 : 1);
        marie_buf_puts(w->b, f->name);
        marie_buf_put(w->b, "\":", 2);
        if (f->ndims == 0)
            walk_value(w, f, depth, i < 256 ? &vals[i] : NULL);
        else
            walk_array(w, f, vals, 0, depth);
    }
    marie_buf_put(w->b, "}", 1);
}

int vj_message(marie_buf_t *b, const void *data, size_t len, vj_role_t role)
{
    const marie_typeinfo_t *t = len < 8 ? NULL : marie_typeinfo_by_fingerprint(marie_payload_fingerprint(data, len));
    if (!t || marie_typeinfo_check(t, data, len) < 0)
        return marie_fail(EBADMSG);
    int k = kind_index(t);
    marie_buf_puts(b, ",\"k\":");
    vj_str(b, k >= 0 ? kinds[k].kind : t->name);
    if (role != VJ_ROLE_OTHER)
        marie_buf_puts(b, role == VJ_ROLE_TRUTH ? ",\"role\":\"truth\"" : ",\"role\":\"est\"");
    marie_buf_puts(b, ",\"msg\":");
    walk_t w = {.b = b, .p = (const uint8_t *)data + 8, .max_elems = k >= 0 ? kinds[k].max_elems : 0};
    walk_struct(&w, t, 0);
    if (w.nstrides) {
        marie_buf_puts(b, ",\"stride\":{");
        for (int i = 0; i < w.nstrides; i++) {
            marie_buf_puts(b, i ? ",\"" : "\"");
            marie_buf_puts(b, w.stride_field[i]);
            marie_buf_printf(b, "\":%lld", (long long)w.stride[i]);
        }
        marie_buf_puts(b, "}");
    }
    return 0;
}

/* ---- commands from the page ---- */

static void skip_ws(const char **p, const char *end)
{
    while (*p < end && (**p == ' ' || **p == '\t' || **p == '\n' || **p == '\r'))
        (*p)++;
}

/* A JSON string into out (cap bytes); escapes other than \" \\ \/ are refused: the page
 * never sends them. */
static int parse_string(const char **p, const char *end, char *out, size_t cap)
{
    if (*p >= end || **p != '"')
        return -1;
    (*p)++;
    size_t n = 0;
    while (*p < end && **p != '"') {
        char c = **p;
        if (c == '\\') {
            (*p)++;
            if (*p >= end || (**p != '"' && **p != '\\' && **p != '/'))
                return -1;
            c = **p;
        } else if ((unsigned char)c < 0x20) {
            return -1;
        }
        if (n + 1 >= cap)
            return -1;
        out[n++] = c;
        (*p)++;
    }
    if (*p >= end)
        return -1;
    (*p)++;
    out[n] = 0;
    return 0;
}

int vj_cmd_parse(vj_cmd_t *cmd, const char *text, size_t len)
{
    const char *p = text, *end = text + len;
    memset(cmd, 0, sizeof *cmd);
    skip_ws(&p, end);
    if (p >= end || *p != '{')
        return marie_fail(EBADMSG);
    p++;
    skip_ws(&p, end);
    if (p < end && *p == '}') {
        p++;
        goto tail;
    }
    for (;;) {
        if (cmd->n >= VJ_CMD_MAX)
            return marie_fail(EBADMSG);
        int i = cmd->n;
        skip_ws(&p, end);
        if (parse_string(&p, end, cmd->key[i], sizeof cmd->key[i]) < 0)
            return marie_fail(EBADMSG);
        skip_ws(&p, end);
        if (p >= end || *p != ':')
            return marie_fail(EBADMSG);
        p++;
        skip_ws(&p, end);
        if (p < end && *p == '"') {
            if (parse_string(&p, end, cmd->str[i], sizeof cmd->str[i]) < 0)
                return marie_fail(EBADMSG);
        } else if (p < end && (*p == 't' || *p == 'f')) {
            const char *w = *p == 't' ? "true" : "false";
            size_t wl = strlen(w);
            if ((size_t)(end - p) < wl || memcmp(p, w, wl) != 0)
                return marie_fail(EBADMSG);
            p += wl;
            cmd->is_num[i] = true;
            cmd->num[i] = *w == 't';
        } else {
            char tmp[40];
            size_t n = 0;
            while (p < end && n + 1 < sizeof tmp && strchr("+-0123456789.eE", *p) && *p)
                tmp[n++] = *p++;
            tmp[n] = 0;
            char *e;
            double v = strtod(tmp, &e);
            if (n == 0 || *e || !isfinite(v))
                return marie_fail(EBADMSG);
            cmd->is_num[i] = true;
            cmd->num[i] = v;
        }
        cmd->n++;
        skip_ws(&p, end);
        if (p < end && *p == ',') {
            p++;
            continue;
        }
        if (p < end && *p == '}') {
            p++;
            break;
        }
        return marie_fail(EBADMSG);
    }
tail:
    skip_ws(&p, end);
    return p == end ? 0 : marie_fail(EBADMSG);
}

const char *vj_cmd_str(const vj_cmd_t *cmd, const char *k)
{
    for (int i = 0; i < cmd->n; i++)
        if (!cmd->is_num[i] && strcmp(cmd->key[i], k) == 0)
            return cmd->str[i];
    return NULL;
}

bool vj_cmd_num(const vj_cmd_t *cmd, const char *k, double *out)
{
    for (int i = 0; i < cmd->n; i++)
        if (cmd->is_num[i] && strcmp(cmd->key[i], k) == 0) {
            *out = cmd->num[i];
            return true;
        }
    return false;
}
