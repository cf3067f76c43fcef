/* top: the table model of `marie top` (see top.h); pure, so every rule is unit-tested. */
#include "managers/top.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/buf.h"
#include "core/component.h"
#include "core/err.h"
#include "core/log.h"

/* Heartbeats also come on every state change: a rate over less than this is too noisy, so
 * the baseline moves only once this much sender time has passed. */
#define RATE_MIN_SPAN_US 500000

typedef struct {
    char host[TOP_NAME_MAX], name[TOP_NAME_MAX];
    bool managed;               /* in its manager's last status */
    marie_am_component_status_t st;    /* numbers only: the strings are not kept */
    char state[16];
    bool hb_heard;
    int64_t hb_rx;              /* monotonic time of the last heartbeat */
    int8_t hb_state;
    int32_t hb_pid;
    int64_t hb_uptime_us, bad;
    int64_t base_utime, base_in, base_out;  /* rate baseline */
    double in_rate, out_rate;   /* < 0 until two heartbeats far enough apart */
} entry_t;

typedef struct {
    top_host_t h;
    int64_t rx;                 /* monotonic time of its last status */
} host_t;

struct top {
    entry_t *e;
    size_t ne, cap_e;
    host_t *hosts;
    size_t nh, cap_h;
    top_host_t *hview;
    top_row_t *rview;
    size_t cap_hview, cap_rview;
};

int top_sort_parse(const char *name)
{
    static const char *const names[] = {"cpu", "mem", "name", "host"};
    for (int i = 0; i < 4; i++)
        if (name && strcmp(name, names[i]) == 0)
            return i;
    return -1;
}

static const char *top_sort_name(top_sort_t s)
{
    static const char *const names[] = {"cpu", "mem", "name", "host"};
    return (unsigned)s < 4 ? names[s] : "?";
}

top_t *top_create(void)
{
    return calloc(1, sizeof(top_t));
}

void top_destroy(top_t *t)
{
    if (!t)
        return;
    free(t->e);
    free(t->hosts);
    free(t->hview);
    free(t->rview);
    free(t);
}

/* Names come from the bus: only printable ASCII reaches the terminal (no escape sequences). */
static void copy_clean(char *dst, size_t cap, const char *src)
{
    size_t i = 0;
    for (; src && src[i] && i + 1 < cap; i++)
        dst[i] = (src[i] >= 0x20 && src[i] < 0x7f) ? src[i] : '?';
    dst[i] = 0;
}

static host_t *host_get(top_t *t, const char *name)
{
    char clean[TOP_NAME_MAX];
    copy_clean(clean, sizeof clean, name);
    for (size_t i = 0; i < t->nh; i++)
        if (strcmp(t->hosts[i].h.name, clean) == 0)
            return &t->hosts[i];
    if (MARIE_GROW(t->hosts, t->cap_h, t->nh + 1) < 0)
        return NULL;
    host_t *h = &t->hosts[t->nh++];
    memset(h, 0, sizeof *h);
    memcpy(h->h.name, clean, sizeof clean);
    return h;
}

static entry_t *entry_get(top_t *t, const char *host, const char *name)
{
    char ch[TOP_NAME_MAX], cn[TOP_NAME_MAX];
    copy_clean(ch, sizeof ch, host && *host ? host : "?");
    copy_clean(cn, sizeof cn, name);
    for (size_t i = 0; i < t->ne; i++)
        if (strcmp(t->e[i].host, ch) == 0 && strcmp(t->e[i].name, cn) == 0)
            return &t->e[i];
    if (MARIE_GROW(t->e, t->cap_e, t->ne + 1) < 0)
        return NULL;
    entry_t *e = &t->e[t->ne++];
    memset(e, 0, sizeof *e);
    memcpy(e->host, ch, sizeof ch);
    memcpy(e->name, cn, sizeof cn);
    e->in_rate = e->out_rate = -1;
    e->bad = -1;
    return e;
}

int top_on_status(top_t *t, const marie_am_status_t *st, int64_t now_us)
{
    host_t *h = host_get(t, st->host);
    if (!h)
        return -1;
    h->rx = now_us;
    h->h.heard = true;
    h->h.load1 = st->load1;
    h->h.load5 = st->load5;
    h->h.load15 = st->load15;
    h->h.ncpu = st->ncpu;
    h->h.am_cpu = st->am_cpu;
    h->h.am_rss = st->am_rss;
    h->h.ncomponents = st->ncomponents;
    copy_clean(h->h.system, sizeof h->h.system, st->system);
    const char *hname = h->h.name;
    for (size_t i = 0; i < t->ne; i++)
        if (strcmp(t->e[i].host, hname) == 0)
            t->e[i].managed = false;
    for (int32_t i = 0; i < st->ncomponents; i++) {
        const marie_am_component_status_t *c = &st->components[i];
        entry_t *e = entry_get(t, st->host, c->name);
        if (!e)
            return -1;
        e->managed = true;
        e->st = *c;
        e->st.name = e->st.group = e->st.state = e->st.config_hash = NULL;
        copy_clean(e->state, sizeof e->state, c->state);
    }
    for (int32_t i = 0; i < st->nhosts; i++)
        if (!host_get(t, st->hosts[i]))
            return -1;
    return 0;
}

int top_on_heartbeat(top_t *t, const marie_heartbeat_t *hb, int64_t now_us)
{
    entry_t *e = entry_get(t, hb->host, hb->component);
    if (!e)
        return -1;
    bool same_run = e->hb_heard && e->hb_pid == hb->pid && hb->msgs_in >= e->base_in &&
                    hb->msgs_out >= e->base_out && hb->utime >= e->base_utime;
    if (!same_run) {
        e->in_rate = e->out_rate = -1;
        e->base_utime = hb->utime;
        e->base_in = hb->msgs_in;
        e->base_out = hb->msgs_out;
    } else if (hb->utime - e->base_utime >= RATE_MIN_SPAN_US) {
        double dt = (double)(hb->utime - e->base_utime) / 1e6;
        e->in_rate = (double)(hb->msgs_in - e->base_in) / dt;
        e->out_rate = (double)(hb->msgs_out - e->base_out) / dt;
        e->base_utime = hb->utime;
        e->base_in = hb->msgs_in;
        e->base_out = hb->msgs_out;
    }
    e->hb_heard = true;
    e->hb_rx = now_us;
    e->hb_state = hb->state;
    e->hb_pid = hb->pid;
    e->hb_uptime_us = hb->uptime_us;
    e->bad = hb->bad_input;
    return 0;
}

static int cmp_host(const void *a, const void *b)
{
    return strcmp(((const top_host_t *)a)->name, ((const top_host_t *)b)->name);
}

size_t top_hosts(top_t *t, int64_t now_us, const top_host_t **hosts)
{
    if (MARIE_GROW(t->hview, t->cap_hview, t->nh + 1) < 0) {
        *hosts = NULL;
        return 0;
    }
    for (size_t i = 0; i < t->nh; i++) {
        top_host_t *v = &t->hview[i];
        *v = t->hosts[i].h;
        v->silent_us = v->heard ? now_us - t->hosts[i].rx : -1;
        v->lost = !v->heard || v->silent_us > TOP_HOST_LOST_US;
    }
    qsort(t->hview, t->nh, sizeof(top_host_t), cmp_host);
    *hosts = t->hview;
    return t->nh;
}

static bool host_lost(top_t *t, const char *name, int64_t now_us)
{
    for (size_t i = 0; i < t->nh; i++)
        if (strcmp(t->hosts[i].h.name, name) == 0)
            return !t->hosts[i].h.heard || now_us - t->hosts[i].rx > TOP_HOST_LOST_US;
    return false;   /* no manager there: its components report themselves */
}

static void fill_row(top_t *t, const entry_t *e, int64_t now_us, top_row_t *r)
{
    memcpy(r->host, e->host, sizeof r->host);
    memcpy(r->name, e->name, sizeof r->name);
    bool fresh = e->hb_heard && now_us - e->hb_rx <= TOP_RATE_STALE_US;
    r->in_rate = fresh ? e->in_rate : -1;
    r->out_rate = fresh ? e->out_rate : -1;
    r->bad = e->hb_heard ? e->bad : -1;
    if (e->managed) {
        snprintf(r->state, sizeof r->state, "%s", host_lost(t, e->host, now_us) ? "lost" : e->state);
        r->pid = e->st.pid;
        r->restarts = e->st.restarts;
        r->cpu = e->st.cpu;
        r->rss = e->st.rss;
        r->uptime_us = e->st.pid ? e->st.uptime_us : -1;
    } else {
        snprintf(r->state, sizeof r->state, "%s", marie_state_name((marie_state_t)e->hb_state));
        r->pid = e->hb_pid;
        r->restarts = -1;
        r->cpu = -1;
        r->rss = -1;
        r->uptime_us = e->hb_uptime_us;
    }
}

static int by_host_name(const top_row_t *a, const top_row_t *b)
{
    int c = strcmp(a->host, b->host);
    return c ? c : strcmp(a->name, b->name);
}
static int cmp_cpu(const void *pa, const void *pb)
{
    const top_row_t *a = pa, *b = pb;
    if (a->cpu != b->cpu)
        return a->cpu < b->cpu ? 1 : -1;
    return by_host_name(a, b);
}
static int cmp_mem(const void *pa, const void *pb)
{
    const top_row_t *a = pa, *b = pb;
    if (a->rss != b->rss)
        return a->rss < b->rss ? 1 : -1;
    return by_host_name(a, b);
}
static int cmp_name(const void *pa, const void *pb)
{
    const top_row_t *a = pa, *b = pb;
    int c = strcmp(a->name, b->name);
    return c ? c : strcmp(a->host, b->host);
}
static int cmp_host_row(const void *pa, const void *pb)
{
    return by_host_name(pa, pb);
}

size_t top_rows(top_t *t, top_sort_t sort, int64_t now_us, const top_row_t **rows)
{
    static int (*const cmp[])(const void *, const void *) = {cmp_cpu, cmp_mem, cmp_name, cmp_host_row};
    if (MARIE_GROW(t->rview, t->cap_rview, t->ne + 1) < 0) {
        *rows = NULL;
        return 0;
    }
    size_t n = 0;
    for (size_t i = 0; i < t->ne; i++) {
        const entry_t *e = &t->e[i];
        if (!e->managed && !(e->hb_heard && now_us - e->hb_rx <= TOP_HB_ONLY_KEEP_US))
            continue;
        fill_row(t, e, now_us, &t->rview[n++]);
    }
    qsort(t->rview, n, sizeof(top_row_t), cmp[(unsigned)sort < 4 ? sort : 0]);
    *rows = t->rview;
    return n;
}

/* ---- formatting ---- */

enum { COL_HOST, COL_NAME, COL_STATE, COL_PID, COL_CPU, COL_RSS, COL_RST, COL_UPTIME, COL_IN, COL_OUT, COL_BAD, NCOLS };
static const struct {
    const char *title;
    int width;                  /* 0: host_w / name_w */
    bool left;
} cols[NCOLS] = {
    {"HOST", 0, true}, {"COMPONENT", 0, true}, {"STATE", 8, true}, {"PID", 7, false},
    {"CPU%", 6, false}, {"RSS", 6, false}, {"RST", 4, false}, {"UPTIME", 8, false},
    {"IN/s", 7, false}, {"OUT/s", 7, false}, {"BAD", 6, false},
};
static const int drop_order[] = {COL_BAD, COL_OUT, COL_IN, COL_UPTIME, COL_PID, COL_RST, COL_RSS};

static int col_width(const top_layout_t *l, int c)
{
    return c == COL_HOST ? l->host_w : c == COL_NAME ? l->name_w : cols[c].width;
}

static int layout_width(const top_layout_t *l)
{
    int w = 0, n = 0;
    for (int c = 0; c < NCOLS; c++)
        if (l->shown & (1u << c)) {
            w += col_width(l, c);
            n++;
        }
    return w + (n > 0 ? n - 1 : 0);
}

static int clampi(int v, int lo, int hi)
{
    return v < lo ? lo : v > hi ? hi : v;
}

void top_layout(top_layout_t *l, const top_row_t *rows, size_t n, int width)
{
    int hw = 4, nw = 9;
    for (size_t i = 0; i < n; i++) {
        int a = (int)strlen(rows[i].host), b = (int)strlen(rows[i].name);
        hw = a > hw ? a : hw;
        nw = b > nw ? b : nw;
    }
    l->width = clampi(width, 1, TOP_LINE_MAX - 1);
    l->host_w = clampi(hw, 4, 16);
    l->name_w = clampi(nw, 9, 32);
    l->shown = (1u << NCOLS) - 1;
    for (size_t i = 0; i < sizeof drop_order / sizeof drop_order[0] && layout_width(l) > l->width; i++)
        l->shown &= ~(1u << drop_order[i]);
    while (layout_width(l) > l->width && l->name_w > 9)
        l->name_w--;
    while (layout_width(l) > l->width && l->host_w > 4)
        l->host_w--;
}

/* Appends a cell (cut to w, '~' marking a cut) and a separating space; returns the new length. */
static size_t put_cell(char *buf, size_t pos, size_t cap, const char *s, int w, bool left, bool first)
{
    char cell[TOP_LINE_MAX];
    int len = (int)strlen(s);
    if (len > w) {
        memcpy(cell, s, (size_t)w);
        if (w > 1)
            cell[w - 1] = '~';
        len = w;
    } else {
        memcpy(cell, s, (size_t)len);
    }
    cell[len] = 0;
    int n = snprintf(buf + pos, pos < cap ? cap - pos : 0, left ? "%s%-*s" : "%s%*s", first ? "" : " ", w, cell);
    return pos + (size_t)(n > 0 ? n : 0);
}

static size_t finish_line(const top_layout_t *l, char *buf, size_t pos, size_t len)
{
    size_t max = (size_t)l->width < len ? (size_t)l->width : len - 1;
    if (pos > max)
        pos = max;
    while (pos > 0 && buf[pos - 1] == ' ')
        pos--;
    buf[pos] = 0;
    return pos;
}

int top_format_header(const top_layout_t *l, char *buf, size_t len)
{
    if (len == 0)
        return 0;
    size_t pos = 0;
    buf[0] = 0;
    bool first = true;
    for (int c = 0; c < NCOLS; c++)
        if (l->shown & (1u << c)) {
            pos = put_cell(buf, pos, len, cols[c].title, col_width(l, c), cols[c].left, first);
            first = false;
        }
    return (int)finish_line(l, buf, pos, len);
}

static void fmt_bytes(char *s, size_t n, int64_t b)
{
    if (b < 0)
        snprintf(s, n, "-");
    else if (b < 1024)
        snprintf(s, n, "%lldB", (long long)b);
    else if (b < 1024 * 1024)
        snprintf(s, n, "%.0fK", b / 1024.0);
    else if (b < 1024LL * 1024 * 1024)
        snprintf(s, n, b < 100LL * 1024 * 1024 ? "%.1fM" : "%.0fM", b / 1048576.0);
    else
        snprintf(s, n, "%.1fG", b / 1073741824.0);
}

static void fmt_duration(char *s, size_t n, int64_t us)
{
    if (us < 0) {
        snprintf(s, n, "-");
        return;
    }
    long long sec = us / 1000000;
    if (sec < 60)
        snprintf(s, n, "%llds", sec);
    else if (sec < 3600)
        snprintf(s, n, "%lld:%02lld", sec / 60, sec % 60);
    else if (sec < 86400)
        snprintf(s, n, "%lld:%02lld:%02lld", sec / 3600, sec / 60 % 60, sec % 60);
    else
        snprintf(s, n, "%lldd%02lldh", sec / 86400, sec / 3600 % 24);
}

static void fmt_count(char *s, size_t n, double v)
{
    if (v < 0)
        snprintf(s, n, "-");
    else if (v < 10 && v != (long long)v)
        snprintf(s, n, "%.1f", v);
    else if (v < 100000)
        snprintf(s, n, "%.0f", v);
    else if (v < 1e8)
        snprintf(s, n, "%.0fk", v / 1e3);
    else
        snprintf(s, n, "%.0fM", v / 1e6);
}

int top_format_row(const top_layout_t *l, const top_row_t *r, char *buf, size_t len)
{
    if (len == 0)
        return 0;
    char cell[NCOLS][32];
    snprintf(cell[COL_STATE], 32, "%s", r->state);
    if (r->pid > 0)
        snprintf(cell[COL_PID], 32, "%d", (int)r->pid);
    else
        snprintf(cell[COL_PID], 32, "-");
    if (r->cpu >= 0)
        snprintf(cell[COL_CPU], 32, "%.1f", r->cpu);
    else
        snprintf(cell[COL_CPU], 32, "-");
    fmt_bytes(cell[COL_RSS], 32, r->rss);
    if (r->restarts >= 0)
        snprintf(cell[COL_RST], 32, "%d", (int)r->restarts);
    else
        snprintf(cell[COL_RST], 32, "-");
    fmt_duration(cell[COL_UPTIME], 32, r->uptime_us);
    fmt_count(cell[COL_IN], 32, r->in_rate);
    fmt_count(cell[COL_OUT], 32, r->out_rate);
    fmt_count(cell[COL_BAD], 32, r->bad < 0 ? -1 : (double)r->bad);
    size_t pos = 0;
    buf[0] = 0;
    bool first = true;
    for (int c = 0; c < NCOLS; c++) {
        if (!(l->shown & (1u << c)))
            continue;
        const char *s = c == COL_HOST ? r->host : c == COL_NAME ? r->name : cell[c];
        pos = put_cell(buf, pos, len, s, col_width(l, c), cols[c].left, first);
        first = false;
    }
    return (int)finish_line(l, buf, pos, len);
}

/* ---- the screen ---- */

static void line_set(top_line_t *ln, top_line_kind_t kind, int width, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void line_set(top_line_t *ln, top_line_kind_t kind, int width, const char *fmt, ...)
{
    MARIE_VFORMAT(ln->text, fmt);
    if ((int)strlen(ln->text) > width)
        ln->text[width] = 0;
    ln->kind = kind;
}

static void host_line(top_line_t *ln, const top_host_t *h, int width)
{
    char rss[16];
    fmt_bytes(rss, sizeof rss, h->am_rss);
    if (!h->heard)
        line_set(ln, TOP_LINE_HOST_LOST, width, "%-12s manager LOST (never heard)", h->name);
    else if (h->lost)
        line_set(ln, TOP_LINE_HOST_LOST, width, "%-12s manager LOST (silent %.1f s)  %d components", h->name,
                 h->silent_us / 1e6, (int)h->ncomponents);
    else
        line_set(ln, TOP_LINE_HOST, width,
                 "%-12s manager alive  load %.2f %.2f %.2f (%d cpu)  am %.1f%% %s  %d components%s%s", h->name,
                 h->load1, h->load5, h->load15, (int)h->ncpu, h->am_cpu, rss, (int)h->ncomponents,
                 h->system[0] ? "  system " : "", h->system);
}

static top_line_kind_t row_kind(const top_row_t *r)
{
    static const char *const bad[] = {"failed", "lost", "hung", NULL};
    static const char *const warn[] = {"backoff", "starting", "waiting", "stopping", NULL};
    for (int i = 0; bad[i]; i++)
        if (strcmp(r->state, bad[i]) == 0)
            return TOP_LINE_ROW_BAD;
    for (int i = 0; warn[i]; i++)
        if (strcmp(r->state, warn[i]) == 0)
            return TOP_LINE_ROW_WARN;
    return TOP_LINE_ROW;
}

int top_frame_lines(top_t *t, int64_t now_us)
{
    const top_host_t *h;
    const top_row_t *r;
    return 3 + (int)top_hosts(t, now_us, &h) + (int)top_rows(t, TOP_SORT_HOST, now_us, &r);
}

int top_frame(top_t *t, const top_view_t *v, int64_t now_us, top_line_t *lines, int max)
{
    int width = clampi(v->width, 1, TOP_LINE_MAX - 1);
    if (v->height > 0 && v->height < max)
        max = v->height;
    const top_host_t *hosts;
    size_t nh = top_hosts(t, now_us, &hosts);
    size_t nlost = 0;
    for (size_t i = 0; i < nh; i++)
        nlost += hosts[i].lost;
    const top_row_t *rows;
    size_t nr = top_rows(t, v->sort, now_us, &rows);
    char bad[48] = "";
    if (v->malformed)
        snprintf(bad, sizeof bad, " - %lld malformed", (long long)v->malformed);
    int n = 0;
    if (n < max)
        line_set(&lines[n++], TOP_LINE_TITLE, width,
                 "marie top - %zu host%s (%zu lost), %zu components - sort: %s - every %gs%s"
                 " - keys: c cpu, m mem, n name, h host, q quit",
                 nh, nh == 1 ? "" : "s", nlost, nr, top_sort_name(v->sort), v->interval_s, bad);
    for (size_t i = 0; i < nh && n < max; i++)
        host_line(&lines[n++], &hosts[i], width);
    if (n < max)
        line_set(&lines[n++], TOP_LINE_BLANK, width, "%s", nh ? "" : "(no manager heard yet)");
    top_layout_t l;
    top_layout(&l, rows, nr, width);
    if (n < max) {
        lines[n].kind = TOP_LINE_HEADER;
        top_format_header(&l, lines[n++].text, sizeof lines[0].text);
    }
    for (size_t i = 0; i < nr && n < max; i++) {
        if (n == max - 1 && i + 1 < nr) {
            line_set(&lines[n++], TOP_LINE_MORE, width, "... %zu more (taller terminal to see them)", nr - i);
            break;
        }
        lines[n].kind = row_kind(&rows[i]);
        top_format_row(&l, &rows[i], lines[n++].text, sizeof lines[0].text);
    }
    return n;
}
