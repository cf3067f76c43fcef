/* vjson: the viewer's JSON. Hand-written per type so the page gets only what it draws, with
 * coordinates rounded to millimetres: a laser scan is ~1 KB instead of ~4 KB. */
#include "tools/webcommon/vjson.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/typeinfo.h"

void vj_init(vj_buf_t *b)
{
    memset(b, 0, sizeof *b);
}

void vj_free(vj_buf_t *b)
{
    free(b->s);
    memset(b, 0, sizeof *b);
}

void vj_reset(vj_buf_t *b)
{
    b->len = 0;
    b->oom = false;
    if (b->s)
        b->s[0] = 0;
}

static bool grow(vj_buf_t *b, size_t n)
{
    if (b->oom)
        return false;
    if (b->len + n + 1 <= b->cap)
        return true;
    size_t cap = b->cap ? b->cap : 256;
    while (cap < b->len + n + 1)
        cap *= 2;
    char *s = realloc(b->s, cap);
    if (!s) {
        b->oom = true;
        return false;
    }
    b->s = s;
    b->cap = cap;
    return true;
}

void vj_raw(vj_buf_t *b, const char *s, size_t n)
{
    if (!grow(b, n))
        return;
    memcpy(b->s + b->len, s, n);
    b->len += n;
    b->s[b->len] = 0;
}

void vj_lit(vj_buf_t *b, const char *s)
{
    vj_raw(b, s, strlen(s));
}

void vj_printf(vj_buf_t *b, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    char tmp[256];
    int n = vsnprintf(tmp, sizeof tmp, fmt, ap);
    va_end(ap);
    if (n < 0)
        return;
    if ((size_t)n < sizeof tmp) {
        vj_raw(b, tmp, (size_t)n);
        return;
    }
    if (!grow(b, (size_t)n))
        return;
    va_start(ap, fmt);
    vsnprintf(b->s + b->len, (size_t)n + 1, fmt, ap);
    va_end(ap);
    b->len += (size_t)n;
}

void vj_str(vj_buf_t *b, const char *s)
{
    static const char hex[] = "0123456789abcdef";
    vj_raw(b, "\"", 1);
    for (const unsigned char *p = (const unsigned char *)(s ? s : ""); *p; p++) {
        if (*p == '"' || *p == '\\') {
            char e[2] = {'\\', (char)*p};
            vj_raw(b, e, 2);
        } else if (*p < 0x20 || *p == 0x7f) {
            char e[6] = {'\\', 'u', '0', '0', hex[*p >> 4], hex[*p & 15]};
            vj_raw(b, e, 6);
        } else if (*p >= 0x80) {
            /* Not checked as UTF-8: a stray byte would make the whole frame invalid text. */
            vj_raw(b, "?", 1);
        } else {
            vj_raw(b, (const char *)p, 1);
        }
    }
    vj_raw(b, "\"", 1);
}

void vj_num(vj_buf_t *b, double v, int prec)
{
    if (!isfinite(v)) {
        vj_raw(b, "null", 4);
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
        vj_raw(b, "0", 1);
    else
        vj_raw(b, tmp, (size_t)n);
}

void vj_int(vj_buf_t *b, int64_t v)
{
    vj_printf(b, "%lld", (long long)v);
}

void vj_base64(vj_buf_t *b, const void *data, size_t n)
{
    static const char tab[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    const uint8_t *p = data;
    if (!grow(b, (n + 2) / 3 * 4 + 2))
        return;
    char *o = b->s + b->len;
    *o++ = '"';
    size_t i = 0;
    for (; i + 3 <= n; i += 3) {
        uint32_t v = (uint32_t)p[i] << 16 | (uint32_t)p[i + 1] << 8 | p[i + 2];
        *o++ = tab[v >> 18]; *o++ = tab[(v >> 12) & 63]; *o++ = tab[(v >> 6) & 63]; *o++ = tab[v & 63];
    }
    if (i < n) {
        uint32_t v = (uint32_t)p[i] << 16 | (i + 1 < n ? (uint32_t)p[i + 1] << 8 : 0);
        *o++ = tab[v >> 18];
        *o++ = tab[(v >> 12) & 63];
        *o++ = i + 1 < n ? tab[(v >> 6) & 63] : '=';
        *o++ = '=';
    }
    *o++ = '"';
    *o = 0;
    b->len = (size_t)(o - b->s);
}

const marie_type_t *vj_type_of(const void *data, size_t len)
{
    return len < 8 ? NULL : marie_type_by_fingerprint(marie_payload_fingerprint(data, len));
}

/* ---- per-type encoders: each appends `,"k":KIND` and its fields ---- */

static void key(vj_buf_t *b, const char *k)
{
    vj_raw(b, ",\"", 2);
    vj_lit(b, k);
    vj_raw(b, "\":", 2);
}

static void pose_fields(vj_buf_t *b, const marie_pose2d_t *p)
{
    key(b, "x"); vj_num(b, p->x, 3);
    key(b, "y"); vj_num(b, p->y, 3);
    key(b, "th"); vj_num(b, p->theta, 3);
}

static void enc_laser(vj_buf_t *b, const marie_laser_scan_t *m)
{
    /* At most 720 beams reach the page: enough to draw, whatever the sensor. */
    int step = m->nranges > 720 ? (m->nranges + 719) / 720 : 1;
    key(b, "amin"); vj_num(b, m->angle_min, 5);
    key(b, "ainc"); vj_num(b, (double)m->angle_increment * step, 6);
    key(b, "rmax"); vj_num(b, m->range_max, 2);
    key(b, "r");
    vj_raw(b, "[", 1);
    for (int i = 0; i < m->nranges; i += step) {
        if (i)
            vj_raw(b, ",", 1);
        vj_num(b, m->ranges[i], 2);
    }
    vj_raw(b, "]", 1);
}

static void enc_pose(vj_buf_t *b, const marie_pose_cov_t *m, vj_role_t role)
{
    key(b, "role"); vj_lit(b, role == VJ_ROLE_TRUTH ? "\"truth\"" : "\"est\"");
    key(b, "frame"); vj_str(b, m->frame);
    pose_fields(b, &m->pose);
    key(b, "cov");
    vj_raw(b, "[", 1);
    vj_num(b, m->cov[0], 5); vj_raw(b, ",", 1);
    vj_num(b, m->cov[1], 5); vj_raw(b, ",", 1);
    vj_num(b, m->cov[4], 5); vj_raw(b, ",", 1);
    vj_num(b, m->cov[8], 5);
    vj_raw(b, "]", 1);
}

static void enc_particles(vj_buf_t *b, const marie_particle_cloud_t *m)
{
    int step = m->n > 1500 ? (m->n + 1499) / 1500 : 1;
    key(b, "n"); vj_int(b, m->n);
    key(b, "x");
    vj_raw(b, "[", 1);
    for (int i = 0; i < m->n; i += step) {
        if (i)
            vj_raw(b, ",", 1);
        vj_num(b, m->x[i], 2);
    }
    vj_raw(b, "]", 1);
    key(b, "y");
    vj_raw(b, "[", 1);
    for (int i = 0; i < m->n; i += step) {
        if (i)
            vj_raw(b, ",", 1);
        vj_num(b, m->y[i], 2);
    }
    vj_raw(b, "]", 1);
}

static void enc_path(vj_buf_t *b, const marie_path_t *m)
{
    key(b, "goal"); vj_int(b, m->goal_id);
    key(b, "status"); vj_int(b, m->status);
    key(b, "p");
    vj_raw(b, "[", 1);
    for (int i = 0; i < m->nposes; i++) {
        vj_raw(b, i ? ",[" : "[", i ? 2 : 1);
        vj_num(b, m->poses[i].x, 2);
        vj_raw(b, ",", 1);
        vj_num(b, m->poses[i].y, 2);
        vj_raw(b, "]", 1);
    }
    vj_raw(b, "]", 1);
}

static void enc_goal(vj_buf_t *b, const marie_goal_t *m)
{
    key(b, "id"); vj_int(b, m->id);
    key(b, "name"); vj_str(b, m->name);
    pose_fields(b, &m->pose);
    key(b, "tol"); vj_num(b, m->tolerance, 3);
    key(b, "prio"); vj_int(b, m->priority);
    key(b, "deadline"); vj_int(b, m->deadline_utime);
}

static void enc_arbitration(vj_buf_t *b, const marie_arbitration_t *m)
{
    key(b, "cycle"); vj_int(b, m->cycle);
    key(b, "winner"); vj_str(b, m->winner);
    key(b, "v"); vj_num(b, m->v, 3);
    key(b, "w"); vj_num(b, m->omega, 3);
    key(b, "votes");
    vj_raw(b, "[", 1);
    for (int i = 0; i < m->nvotes; i++) {
        const marie_behaviour_vote_t *v = &m->votes[i];
        vj_raw(b, i ? ",{\"n\":" : "{\"n\":", i ? 6 : 5);
        vj_str(b, v->name);
        key(b, "p"); vj_int(b, v->priority);
        key(b, "a"); vj_lit(b, v->active ? "1" : "0");
        key(b, "v"); vj_num(b, v->v, 3);
        key(b, "w"); vj_num(b, v->omega, 3);
        key(b, "r"); vj_str(b, v->reason);
        vj_raw(b, "}", 1);
    }
    vj_raw(b, "]", 1);
    key(b, "in");
    vj_raw(b, "[", 1);
    for (int i = 0; i < m->ninputs; i++) {
        vj_raw(b, i ? ",{\"n\":" : "{\"n\":", i ? 6 : 5);
        vj_str(b, m->inputs[i].name);
        key(b, "age"); vj_num(b, m->inputs[i].age, 3);
        vj_raw(b, "}", 1);
    }
    vj_raw(b, "]", 1);
}

static void enc_event(vj_buf_t *b, const marie_event_t *m)
{
    key(b, "src"); vj_str(b, m->source);
    key(b, "seq"); vj_int(b, m->seq);
    key(b, "sev"); vj_int(b, m->severity);
    key(b, "kind"); vj_str(b, m->kind);
    key(b, "text"); vj_str(b, m->text);
}

static void enc_heartbeat(vj_buf_t *b, const marie_heartbeat_t *m)
{
    key(b, "c"); vj_str(b, m->component);
    key(b, "host"); vj_str(b, m->host);
    key(b, "pid"); vj_int(b, m->pid);
    key(b, "state"); vj_int(b, m->state);
    key(b, "reason"); vj_str(b, m->reason);
    key(b, "up"); vj_num(b, m->uptime_us / 1e6, 1);
    key(b, "in"); vj_int(b, m->msgs_in);
    key(b, "out"); vj_int(b, m->msgs_out);
    key(b, "drops"); vj_int(b, m->drops);
    key(b, "bad"); vj_int(b, m->bad_input);
    key(b, "ovr"); vj_int(b, m->overruns);
    key(b, "ports");
    vj_raw(b, "[", 1);
    for (int i = 0; i < m->nports; i++) {
        const marie_port_status_t *p = &m->ports[i];
        vj_raw(b, i ? ",{\"n\":" : "{\"n\":", i ? 6 : 5);
        vj_str(b, p->name);
        key(b, "ch"); vj_str(b, p->channel);
        key(b, "t"); vj_str(b, p->type);
        key(b, "out"); vj_lit(b, p->direction == MARIE_PORT_STATUS_T_OUT ? "1" : "0");
        key(b, "m"); vj_int(b, p->msgs);
        vj_raw(b, "}", 1);
    }
    vj_raw(b, "]", 1);
}

static void enc_am_status(vj_buf_t *b, const marie_am_status_t *m)
{
    key(b, "host"); vj_str(b, m->host);
    key(b, "comps");
    vj_raw(b, "[", 1);
    for (int i = 0; i < m->ncomponents; i++) {
        const marie_am_component_status_t *c = &m->components[i];
        vj_raw(b, i ? ",{\"n\":" : "{\"n\":", i ? 6 : 5);
        vj_str(b, c->name);
        key(b, "g"); vj_str(b, c->group);
        key(b, "s"); vj_str(b, c->state);
        key(b, "pid"); vj_int(b, c->pid);
        key(b, "up"); vj_num(b, c->uptime_us / 1e6, 1);
        key(b, "rs"); vj_int(b, c->restarts);
        key(b, "cpu"); vj_num(b, c->cpu, 1);
        key(b, "rss"); vj_int(b, c->rss);
        vj_raw(b, "}", 1);
    }
    vj_raw(b, "]", 1);
    key(b, "leader"); vj_str(b, m->balance_leader);
    key(b, "term"); vj_int(b, m->balance_term);
    key(b, "last"); vj_str(b, m->balance_last);
}

static void enc_am_reply(vj_buf_t *b, const marie_am_reply_t *m)
{
    key(b, "host"); vj_str(b, m->host);
    key(b, "seq"); vj_int(b, m->seq);
    key(b, "ok"); vj_lit(b, m->ok ? "1" : "0");
    key(b, "reason"); vj_str(b, m->reason);
}

static void enc_grid(vj_buf_t *b, const marie_occupancy_grid_t *m)
{
    key(b, "res"); vj_num(b, m->resolution, 4);
    key(b, "w"); vj_int(b, m->width);
    key(b, "h"); vj_int(b, m->height);
    key(b, "ox"); vj_num(b, m->origin.x, 3);
    key(b, "oy"); vj_num(b, m->origin.y, 3);
    key(b, "oth"); vj_num(b, m->origin.theta, 4);
    /* Cells as base64 of the int8 values: 1.33 bytes a cell instead of up to 5 as numbers. */
    int64_t need = (int64_t)m->width * m->height;
    key(b, "cells");
    if (m->width <= 0 || m->height <= 0 || need != m->ncells)
        vj_lit(b, "\"\"");
    else
        vj_base64(b, m->cells, (size_t)m->ncells);
}

static void enc_tags(vj_buf_t *b, const marie_tag_detections_t *m)
{
    key(b, "camera"); vj_str(b, m->camera);
    key(b, "tags");
    vj_raw(b, "[", 1);
    for (int i = 0; i < m->count; i++) {
        const marie_tag_detection_t *t = &m->tags[i];
        vj_raw(b, i ? ",{\"id\":" : "{\"id\":", i ? 7 : 6);
        vj_int(b, t->id);
        key(b, "valid"); vj_lit(b, t->pose_valid ? "1" : "0");
        key(b, "px"); vj_num(b, t->position[0], 3);
        key(b, "pz"); vj_num(b, t->position[2], 3);
        vj_raw(b, "}", 1);
    }
    vj_raw(b, "]", 1);
}

static void enc_landmarks(vj_buf_t *b, const marie_landmarks_t *m)
{
    key(b, "lm");
    vj_raw(b, "[", 1);
    for (int i = 0; i < m->count; i++) {
        const marie_landmark_t *l = &m->landmarks[i];
        vj_raw(b, i ? ",{\"id\":" : "{\"id\":", i ? 7 : 6);
        vj_int(b, l->id);
        key(b, "x"); vj_num(b, l->x, 3);
        key(b, "y"); vj_num(b, l->y, 3);
        key(b, "yaw"); vj_num(b, l->yaw, 3);
        key(b, "msg"); vj_str(b, l->message);
        vj_raw(b, "}", 1);
    }
    vj_raw(b, "]", 1);
}

static const struct {
    const marie_type_t *type;
    const char *kind;
} kinds[] = {
    {&marie_type_laser_scan_t, "laser"},
    {&marie_type_pose_cov_t, "pose"},
    {&marie_type_particle_cloud_t, "particles"},
    {&marie_type_path_t, "path"},
    {&marie_type_goal_t, "goal"},
    {&marie_type_arbitration_t, "arb"},
    {&marie_type_event_t, "event"},
    {&marie_type_heartbeat_t, "hb"},
    {&marie_type_am_status_t, "am"},
    {&marie_type_am_reply_t, "reply"},
    {&marie_type_occupancy_grid_t, "map"},
    {&marie_type_tag_detections_t, "tags"},
    {&marie_type_landmarks_t, "landmarks"},
};

const char *vj_kind(const marie_type_t *t)
{
    for (size_t i = 0; i < sizeof kinds / sizeof kinds[0]; i++)
        if (kinds[i].type == t)
            return kinds[i].kind;
    return NULL;
}

bool vj_message(vj_buf_t *b, const marie_type_t *t, const void *msg, vj_role_t role)
{
    const char *kind = vj_kind(t);
    if (!kind)
        return false;
    key(b, "k");
    vj_str(b, kind);
    if (t == &marie_type_laser_scan_t) enc_laser(b, msg);
    else if (t == &marie_type_pose_cov_t) enc_pose(b, msg, role);
    else if (t == &marie_type_particle_cloud_t) enc_particles(b, msg);
    else if (t == &marie_type_path_t) enc_path(b, msg);
    else if (t == &marie_type_goal_t) enc_goal(b, msg);
    else if (t == &marie_type_arbitration_t) enc_arbitration(b, msg);
    else if (t == &marie_type_event_t) enc_event(b, msg);
    else if (t == &marie_type_heartbeat_t) enc_heartbeat(b, msg);
    else if (t == &marie_type_am_status_t) enc_am_status(b, msg);
    else if (t == &marie_type_am_reply_t) enc_am_reply(b, msg);
    else if (t == &marie_type_occupancy_grid_t) enc_grid(b, msg);
    else if (t == &marie_type_tag_detections_t) enc_tags(b, msg);
    else if (t == &marie_type_landmarks_t) enc_landmarks(b, msg);
    return true;
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
        return -EBADMSG;
    p++;
    skip_ws(&p, end);
    if (p < end && *p == '}') {
        p++;
        goto tail;
    }
    for (;;) {
        if (cmd->n >= VJ_CMD_MAX)
            return -EBADMSG;
        int i = cmd->n;
        skip_ws(&p, end);
        if (parse_string(&p, end, cmd->key[i], sizeof cmd->key[i]) < 0)
            return -EBADMSG;
        skip_ws(&p, end);
        if (p >= end || *p != ':')
            return -EBADMSG;
        p++;
        skip_ws(&p, end);
        if (p < end && *p == '"') {
            if (parse_string(&p, end, cmd->str[i], sizeof cmd->str[i]) < 0)
                return -EBADMSG;
        } else if (p < end && (*p == 't' || *p == 'f')) {
            const char *w = *p == 't' ? "true" : "false";
            size_t wl = strlen(w);
            if ((size_t)(end - p) < wl || memcmp(p, w, wl) != 0)
                return -EBADMSG;
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
                return -EBADMSG;
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
        return -EBADMSG;
    }
tail:
    skip_ws(&p, end);
    return p == end ? 0 : -EBADMSG;
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
