/* viewer_log: marie-viewer-server's log mode: the log indexed once (records per channel, the
 * summary the page's timeline draws), played at a speed, sought, and shown at any instant. */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/buf.h"
#include "core/typeinfo.h"
#include "core/lcmlog.h"
#include "tools/viewer/viewer.h"

/* ---------------------------------------------------------------- log mode */

static void on_log_event(void *user, const lcmlog_event_t *ev)
{
    viewer_t *v = user;
    size_t ci;
    for (ci = 0; ci < v->nlchans; ci++)
        if (strlen(v->lchans[ci].name) == ev->channel_len && memcmp(v->lchans[ci].name, ev->channel, ev->channel_len) == 0)
            break;
    if (ci == v->nlchans) {
        log_chan_t *nc = realloc(v->lchans, (v->nlchans + 1) * sizeof *nc);
        if (!nc)
            return;
        v->lchans = nc;
        log_chan_t *lc = &nc[v->nlchans++];
        memset(lc, 0, sizeof *lc);
        lc->name = strndup(ev->channel, ev->channel_len);
        lc->port = lc->name ? viewer_port_of_channel(v, lc->name) : -1;
        lc->type = vj_type_of(ev->data, ev->data_len);
    }
    log_chan_t *lc = &v->lchans[ci];
    lc->count++;
    if (MARIE_GROW(v->recs, v->recs_cap, v->nrecs + 1) < 0)
        return;
    if (lc->port >= 0 && vj_type_of(ev->data, ev->data_len) != viewer_port_type[lc->port]) {
        v->bad_payloads++;          /* not the port's type: never played */
        return;
    }
    if (lc->port >= 0) {
        if (MARIE_GROW(lc->idx, lc->cap, lc->n + 1) < 0)
            return;
        lc->idx[lc->n++] = (uint32_t)v->nrecs;
    }
    /* Play time never runs backwards, and a timestamp more than an hour off its neighbours
     * is a corrupt one: the record plays at its predecessor's time. */
    int64_t t = ev->utime;
    if (v->nrecs == 0)
        v->t0 = t;
    else if (t < v->last_t || t - v->last_t > 3600LL * 1000000)
        t = v->last_t;
    v->last_t = t;
    rec_t *r = &v->recs[v->nrecs++];
    r->t = t;
    r->chan = (uint32_t)ci;
    r->len = (uint32_t)ev->data_len;
    /* From the stream offset, not ev->data: records found at the end of the stream come
     * from the parser's own copy of the tail, not from the mapped file. */
    r->off = ev->offset + LCMLOG_HEADER_LEN + ev->channel_len;
}

static void on_log_corrupt(void *user, uint64_t offset, const char *reason)
{
    viewer_t *v = user;
    v->corrupt++;
    marie_warn_ratelimited(5, "viewer: %s: corrupt record at byte %llu: %s", viewer_params(v->c)->log,
                           (unsigned long long)offset, reason);
    if (v->ncorrupt_listed < 20) {
        marie_buf_printf(&v->corrupt_list, "%s{\"off\":%llu,\"reason\":", v->ncorrupt_listed ? "," : "",
                  (unsigned long long)offset);
        vj_str(&v->corrupt_list, reason);
        marie_buf_puts(&v->corrupt_list, "}");
        v->ncorrupt_listed++;
    }
}

static void *decode_rec(viewer_t *v, const rec_t *r, const marie_type_t *want)
{
    const uint8_t *data = v->file + r->off;
    if (vj_type_of(data, r->len) != want)
        return NULL;
    void *msg = calloc(1, want->size);
    if (msg && marie_decode_input(want, data, r->len, msg, NULL) < 0) {
        v->bad_payloads++;
        free(msg);
        return NULL;
    }
    return msg;
}

static void free_msg(const marie_type_t *t, void *msg)
{
    if (msg) {
        t->decode_cleanup(msg);
        free(msg);
    }
}

static int intern(char ***names, int *n, const char *s)
{
    for (int i = 0; i < *n; i++)
        if (strcmp((*names)[i], s) == 0)
            return i;
    char **nn = realloc(*names, (*n + 1) * sizeof *nn);
    if (!nn)
        return 0;
    *names = nn;
    nn[*n] = strdup(s ? s : "");
    return (*n)++;
}

/* The whole log at a glance for the page's timeline: every decision's winner, events,
 * goals, restarts (pid changes in heartbeats) and both trajectories at 5 Hz. */
static void build_summary(viewer_t *v)
{
    marie_buf_t dec, ev, goals, rst, traj[2], b;
    marie_buf_t *all[] = {&dec, &ev, &goals, &rst, &traj[0], &traj[1], &b};
    for (size_t i = 0; i < sizeof all / sizeof all[0]; i++)
        marie_buf_init(all[i], 0);
    char **names = NULL;
    int nnames = 0;
    int64_t ndec = 0, nev = 0, ngoals = 0, nrst = 0, ntraj[2] = {0, 0}, last_traj[2] = {0, 0};
    char *comp[MAXCOMP];
    int pid[MAXCOMP], ncomp = 0;
    for (size_t i = 0; i < v->nrecs; i++) {
        const rec_t *r = &v->recs[i];
        int pi = v->lchans[r->chan].port;
        if (pi < 0)
            continue;
        const marie_type_t *t = viewer_port_type[pi];
        int64_t ms = (r->t - v->t0) / 1000;
        if (pi == P_ARB) {
            marie_arbitration_t *m = decode_rec(v, r, t);
            if (!m)
                continue;
            if (ndec < 200000)
                marie_buf_printf(&dec, "%s[%lld,%d]", ndec++ ? "," : "", (long long)ms, intern(&names, &nnames, m->winner));
            free_msg(t, m);
        } else if (pi == P_EVENT) {
            marie_event_t *m = decode_rec(v, r, t);
            if (!m)
                continue;
            if (nev < 20000) {
                marie_buf_printf(&ev, "%s[%lld,", nev++ ? "," : "", (long long)ms);
                vj_str(&ev, m->source);
                marie_buf_printf(&ev, ",%d,", m->severity);
                vj_str(&ev, m->kind);
                marie_buf_puts(&ev, ",");
                vj_str(&ev, m->text);
                marie_buf_puts(&ev, "]");
            }
            free_msg(t, m);
        } else if (pi == P_GOAL) {
            marie_goal_t *m = decode_rec(v, r, t);
            if (!m)
                continue;
            if (ngoals < 20000) {
                marie_buf_printf(&goals, "%s[%lld,%d,", ngoals++ ? "," : "", (long long)ms, m->id);
                vj_str(&goals, m->name);
                marie_buf_puts(&goals, ",");
                vj_num(&goals, m->pose.x, 3);
                marie_buf_puts(&goals, ",");
                vj_num(&goals, m->pose.y, 3);
                marie_buf_puts(&goals, "]");
            }
            free_msg(t, m);
        } else if (pi == P_HB) {
            marie_heartbeat_t *m = decode_rec(v, r, t);
            if (!m)
                continue;
            int k;
            for (k = 0; k < ncomp; k++)
                if (strcmp(comp[k], m->component) == 0)
                    break;
            if (k == ncomp && ncomp < MAXCOMP) {
                comp[ncomp] = strdup(m->component);
                pid[ncomp++] = m->pid;
            } else if (k < ncomp && pid[k] != m->pid) {
                if (nrst < 20000) {
                    marie_buf_printf(&rst, "%s[%lld,", nrst++ ? "," : "", (long long)ms);
                    vj_str(&rst, m->component);
                    marie_buf_printf(&rst, ",%d,%d]", pid[k], m->pid);
                }
                pid[k] = m->pid;
            }
            free_msg(t, m);
        } else if (pi == P_POSE || pi == P_TRUTH) {
            int k = pi == P_TRUTH;
            if ((ntraj[k] && r->t - last_traj[k] < 200000) || ntraj[k] >= 100000)
                continue;
            marie_pose_cov_t *m = decode_rec(v, r, t);
            if (!m)
                continue;
            last_traj[k] = r->t;
            marie_buf_printf(&traj[k], "%s[%lld,", ntraj[k]++ ? "," : "", (long long)ms);
            vj_num(&traj[k], m->pose.x, 3);
            marie_buf_puts(&traj[k], ",");
            vj_num(&traj[k], m->pose.y, 3);
            marie_buf_puts(&traj[k], "]");
            free_msg(t, m);
        }
    }
    marie_buf_puts(&b, "{\"type\":\"summary\",\"file\":");
    vj_str(&b, viewer_params(v->c)->log);
    marie_buf_printf(&b, ",\"t0\":%lld,\"t1\":%lld,\"records\":%zu,\"bytes\":%zu,\"corrupt\":%lld,\"bad_payloads\":%lld",
              (long long)v->t0, (long long)v->t1, v->nrecs, v->file_len, (long long)v->corrupt,
              (long long)v->bad_payloads);
    marie_buf_puts(&b, ",\"corrupt_list\":[");
    if (v->corrupt_list.data)
        marie_buf_puts(&b, v->corrupt_list.data);
    marie_buf_puts(&b, "],\"channels\":[");
    for (size_t i = 0; i < v->nlchans; i++) {
        marie_buf_puts(&b, i ? ",[" : "[");
        vj_str(&b, v->lchans[i].name);
        marie_buf_puts(&b, ",");
        vj_str(&b, v->lchans[i].type ? v->lchans[i].type->name : "?");
        marie_buf_printf(&b, ",%lld,", (long long)v->lchans[i].count);
        vj_str(&b, v->lchans[i].port >= 0 ? viewer_ports[v->lchans[i].port].name : "");
        marie_buf_puts(&b, "]");
    }
    marie_buf_puts(&b, "],\"names\":[");
    for (int i = 0; i < nnames; i++) {
        if (i)
            marie_buf_puts(&b, ",");
        vj_str(&b, names[i]);
        free(names[i]);
    }
    free(names);
    for (int i = 0; i < ncomp; i++)
        free(comp[i]);
    marie_buf_puts(&b, "],\"dec\":[");
    if (dec.data) marie_buf_puts(&b, dec.data);
    marie_buf_puts(&b, "],\"events\":[");
    if (ev.data) marie_buf_puts(&b, ev.data);
    marie_buf_puts(&b, "],\"goals\":[");
    if (goals.data) marie_buf_puts(&b, goals.data);
    marie_buf_puts(&b, "],\"restarts\":[");
    if (rst.data) marie_buf_puts(&b, rst.data);
    marie_buf_puts(&b, "],\"est\":[");
    if (traj[0].data) marie_buf_puts(&b, traj[0].data);
    marie_buf_puts(&b, "],\"truth\":[");
    if (traj[1].data) marie_buf_puts(&b, traj[1].data);
    marie_buf_puts(&b, "]}");
    if (!b.failed) {
        v->summary = b.data;
        v->summary_len = b.len;
    } else {
        marie_buf_free(&b);
    }
    marie_buf_free(&dec); marie_buf_free(&ev); marie_buf_free(&goals); marie_buf_free(&rst); marie_buf_free(&traj[0]); marie_buf_free(&traj[1]);
}

int viewer_log_load(viewer_t *v, const char *path)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        marie_component_fail_reason(v->c, "log %s: %s", path, strerror(errno));
        return -1;
    }
    struct stat st;
    if (fstat(fd, &st) < 0 || !S_ISREG(st.st_mode)) {
        marie_component_fail_reason(v->c, "log %s: not a regular file", path);
        close(fd);
        return -1;
    }
    v->file_len = (size_t)st.st_size;
    if (v->file_len) {
        v->file = mmap(NULL, v->file_len, PROT_READ, MAP_PRIVATE, fd, 0);
        if (v->file == MAP_FAILED) {
            v->file = NULL;
            marie_component_fail_reason(v->c, "log %s: mmap: %s", path, strerror(errno));
            close(fd);
            return -1;
        }
    }
    close(fd);
    lcmlog_parser_t *p = lcmlog_parser_create(on_log_event, on_log_corrupt, v);
    if (!p) {
        marie_component_fail_reason(v->c, "out of memory");
        return -1;
    }
    if (v->file_len)
        lcmlog_parser_feed(p, v->file, v->file_len);
    lcmlog_parser_finish(p);
    lcmlog_parser_destroy(p);
    v->t1 = v->nrecs ? v->recs[v->nrecs - 1].t : 0;
    build_summary(v);
    marie_info("viewer: %s: %zu records over %.1f s, %lld corrupt stretches, %zu channels", path, v->nrecs,
               (v->t1 - v->t0) / 1e6, (long long)v->corrupt, v->nlchans);
    return 0;
}

static void send_rec(viewer_t *v, int id, size_t i, bool droppable)
{
    const rec_t *r = &v->recs[i];
    int pi = v->lchans[r->chan].port;
    if (pi < 0 || pi == P_MAP_UPDATE)       /* a log plays its whole maps only */
        return;
    const char *ch = v->lchans[r->chan].name;
    const void *data = v->file + r->off;
    if (viewer_payload_ok(v, pi, ch, data, r->len) && viewer_encode_msg(v, &v->jb, pi, ch, r->t, data, r->len))
        viewer_send_json(v, id, &v->jb, droppable);
}

/* Index in lc->idx of the last record before `cursor`, or -1. */
static long last_before(const log_chan_t *lc, size_t cursor)
{
    long lo = 0, hi = (long)lc->n - 1, best = -1;
    while (lo <= hi) {
        long mid = (lo + hi) / 2;
        if (lc->idx[mid] < cursor) {
            best = mid;
            lo = mid + 1;
        } else {
            hi = mid - 1;
        }
    }
    return best;
}

void viewer_log_send_player(viewer_t *v, int id)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_printf(&b, "{\"type\":\"player\",\"playing\":%s,\"speed\":", v->playing ? "true" : "false");
    vj_num(&b, viewer_speed(v), 3);
    marie_buf_printf(&b, ",\"t\":%lld,\"t0\":%lld,\"t1\":%lld}", (long long)v->play_t, (long long)v->t0, (long long)v->t1);
    viewer_send_json(v, id, &b, false);
    marie_buf_free(&b);
}

/* The state of the world at the play time: the newest message of each input, the last
 * decisions and every component's last heartbeat. */
void viewer_log_snapshot(viewer_t *v, int id)
{
    char head[96];
    int n = snprintf(head, sizeof head, "{\"type\":\"snap\",\"t\":%lld}", (long long)v->play_t);
    viewer_send(v, id, head, (size_t)n, false);
    for (size_t ci = 0; ci < v->nlchans; ci++) {
        log_chan_t *lc = &v->lchans[ci];
        if (lc->port < 0 || lc->port == P_AM_REPLY || !lc->n)
            continue;
        long k = last_before(lc, v->cursor);
        if (k < 0) {
            if (lc->port == P_MAP)      /* a map describes the whole run */
                send_rec(v, id, lc->idx[0], false);
            continue;
        }
        if (lc->port == P_ARB || lc->port == P_HB || lc->port == P_AM_STATUS) {
            /* the last 30 decisions; heartbeats of the last 10 s (every component); the
             * managers' reports of the last 3 s (every host) */
            int64_t window = lc->port == P_HB ? 10000000 : 3000000;
            long first = k;
            while (first > 0 && (lc->port == P_ARB ? k - first < 29
                                 : v->recs[lc->idx[first - 1]].t >= v->play_t - window && k - first < 400))
                first--;
            for (long j = first; j <= k; j++)
                send_rec(v, id, lc->idx[j], false);
        } else if (lc->port != P_EVENT) {
            /* events come with the summary; everything else: the newest one */
            send_rec(v, id, lc->idx[k], false);
        }
    }
    n = snprintf(head, sizeof head, "{\"type\":\"snapend\",\"t\":%lld}", (long long)v->play_t);
    viewer_send(v, id, head, (size_t)n, false);
}

void viewer_log_seek(viewer_t *v, int64_t t)
{
    if (t < v->t0)
        t = v->t0;
    if (t > v->t1)
        t = v->t1;
    size_t lo = 0, hi = v->nrecs;
    while (lo < hi) {                   /* first record after t */
        size_t mid = (lo + hi) / 2;
        if (v->recs[mid].t <= t)
            lo = mid + 1;
        else
            hi = mid;
    }
    v->cursor = lo;
    v->play_t = t;
    v->anchor_mono = marie_mono_us();
    for (int i = 0; i < P_NIN; i++)
        v->chans[i].last_sent_mono = 0;
    viewer_log_snapshot(v, -1);
    viewer_log_send_player(v, -1);
}

void viewer_log_tick(marie_loop_t *loop, marie_timer_t *tm, int64_t overruns, void *user)
{
    viewer_t *v = user;
    int64_t now = marie_mono_us();
    if (v->live) {
        /* stats for the page's "no data" banner */
        if (now - v->last_player_msg >= 1000000) {
            v->last_player_msg = now;
            char s[200];
            long long frames = (long long)webserve_frames_out(v->web);
            int n = snprintf(s, sizeof s, "{\"type\":\"stats\",\"msgs\":%lld,\"frames\":%lld,\"rx_age\":%.1f,\"bad\":%lld}",
                             (long long)v->msgs_in, frames, v->last_rx_mono ? (now - v->last_rx_mono) / 1e6 : -1.0,
                             (long long)v->bad_payloads);
            viewer_send(v, -1, s, (size_t)n, false);
        }
        return;
    }
    if (!v->playing)
        return;
    int64_t target = v->play_t + (int64_t)((now - v->anchor_mono) * viewer_speed(v));
    v->play_t = target;
    v->anchor_mono = now;
    while (v->cursor < v->nrecs && v->recs[v->cursor].t <= target) {
        const rec_t *r = &v->recs[v->cursor];
        int pi = v->lchans[r->chan].port;
        if (pi >= 0 && pi != P_AM_REPLY && viewer_pass_rate(v, pi, now, v->file + r->off, r->len))
            send_rec(v, -1, v->cursor, viewer_decimated(pi));
        v->cursor++;
    }
    if (v->cursor >= v->nrecs && target >= v->t1) {
        v->playing = false;
        v->play_t = v->t1;
        viewer_log_send_player(v, -1);
        viewer_notice(v, -1, "info", "end of log");
        return;
    }
    if (now - v->last_player_msg >= 250000) {
        v->last_player_msg = now;
        viewer_log_send_player(v, -1);
    }
}

