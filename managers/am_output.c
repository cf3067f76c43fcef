/* marie-am's output capture: each component's stdout and stderr, read from its pipes on the
 * loop, cut into lines (logcap.c), rate-limited, published on MARIE_LOG and written to its log
 * file. The part of comp_t it owns is c->out. */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "core/bus/bus.h"
#include "core/clear.h"
#include "core/log.h"
#include "lcmtypes/marie_types.h"
#include "managers/am.h"

static void log_line_cb(const char *line, size_t len, void *user)
{
    outpipe_t *op = user;
    comp_t *c = op->c;
    am_t *am = op->am;
    int64_t wall = marie_wall_us();
    if (!marie_ratelimit_take(&c->out.rl, am_now_us())) {
        c->out.drops_pending++;
        c->out.drops_total++;
        return;
    }
    char text[MARIE_LINE_MAX + 1];
    memcpy(text, line, len);
    text[len] = 0;
    marie_log_line_t m = {
        .utime = wall, .host = am->env.host, .component = c->cfg->name, .pid = c->sv.pid,
        .stream = (int8_t)op->stream, .seq = ++c->out.seq, .dropped = c->out.drops_pending,
        .request_seq = 0, .text = text,
    };
    marie_bus_publish_msg(am->env.lcm, MARIE_CH_LOG, &marie_type_log_line_t, &m);
    if (c->out.file) {
        char hdr[96];
        time_t secs = (time_t)(wall / 1000000);
        struct tm tm;
        gmtime_r(&secs, &tm);
        int hl = 0;
        if (c->out.drops_pending) {
            char note[96];
            int nl = snprintf(note, sizeof note, "-- %lld lines dropped (rate limit)\n", (long long)c->out.drops_pending);
            marie_logfile_write(c->out.file, note, (size_t)nl);
        }
        hl = snprintf(hdr, sizeof hdr, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ %s ", tm.tm_year + 1900,
                      tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec,
                      (int)(wall / 1000 % 1000), op->stream == MARIE_LOG_LINE_T_STDERR ? "err" : "out");
        char buf[sizeof hdr + MARIE_LINE_MAX + 2];
        memcpy(buf, hdr, (size_t)hl);
        memcpy(buf + hl, line, len);
        buf[hl + len] = '\n';
        marie_logfile_write(c->out.file, buf, (size_t)hl + len + 1);
    }
    c->out.drops_pending = 0;
}

static void outpipe_unpause(outpipe_t *op)
{
    if (op->pause)
        marie_loop_remove_timer(op->am->env.loop, op->pause);
    op->pause = NULL;
}

static void outpipe_close(outpipe_t *op)
{
    outpipe_unpause(op);
    if (op->fd < 0)
        return;
    marie_linebuf_flush(op->lb, log_line_cb, op);
    marie_loop_remove_fd(op->am->env.loop, op->fd);
    close(op->fd);
    op->fd = -1;
}

/* Read what is there; returns 0 at end of file. */
static int outpipe_drain(outpipe_t *op)
{
    char buf[4096];
    for (int rounds = 0; rounds < 16; rounds++) {
        ssize_t n = read(op->fd, buf, sizeof buf);
        if (n > 0) {
            marie_linebuf_feed(op->lb, buf, (size_t)n, log_line_cb, op);
            continue;
        }
        if (n == 0)
            return 0;
        if (errno == EINTR)
            continue;
        return errno == EAGAIN ? 1 : 0;
    }
    return 1;
}

/* A component that prints faster than its rate limit has its lines dropped; reading them all
 * as they come cost the manager a whole core (92 % of one, at its real-time priority when it has
 * one, beside `yes` as a component). So a drain that dropped lines leaves the pipe unread for
 * OUTPUT_PAUSE_US: it fills (64 KiB), the component waits in its write as on a slow terminal,
 * and the manager reads at most 64 KiB a pipe per pause, dropping and counting what is over
 * the limit as before. A component within its limit never pauses. */
#define OUTPUT_PAUSE_US 20000

static void on_pause_end(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    outpipe_t *op = user;
    op->pause = NULL;
    if (op->fd >= 0)
        marie_loop_set_events(loop, op->fd, POLLIN);
}

static void on_outpipe(marie_loop_t *loop, int fd, short revents, void *user)
{
    outpipe_t *op = user;
    int64_t dropped = op->c->out.drops_total;
    if (outpipe_drain(op) == 0) {
        outpipe_close(op);
        return;
    }
    if (op->c->out.drops_total > dropped && !op->pause &&
        (op->pause = marie_loop_add_oneshot(loop, OUTPUT_PAUSE_US, on_pause_end, op)))
        marie_loop_set_events(loop, fd, 0);
}


void am_comp_close_output(comp_t *c)
{
    for (int i = 0; i < 2; i++)
        outpipe_close(&c->out.pipe[i]);
}

void am_output_init(comp_t *c)
{
    for (int i = 0; i < 2; i++)
        c->out.pipe[i].fd = -1;
}

void am_output_set_rate(comp_t *c, double rate)
{
    marie_ratelimit_init(&c->out.rl, rate, rate * 2);
}

int am_output_prepare(comp_t *c)
{
    for (int i = 0; i < 2; i++)
        if (!c->out.pipe[i].lb && !(c->out.pipe[i].lb = malloc(sizeof *c->out.pipe[i].lb)))
            return -1;
    return 0;
}

void am_output_attach(comp_t *c, int out_fd, int err_fd)
{
    int rd[2] = {out_fd, err_fd};
    for (int i = 0; i < 2; i++) {
        outpipe_t *op = &c->out.pipe[i];
        op->am = c->am;
        op->c = c;
        op->fd = rd[i];
        op->stream = i == 0 ? MARIE_LOG_LINE_T_STDOUT : MARIE_LOG_LINE_T_STDERR;
        op->lb->len = 0;
        fcntl(op->fd, F_SETFL, O_NONBLOCK);     /* a new pipe's end has no other flag */
        marie_loop_add_fd(c->am->env.loop, op->fd, POLLIN, on_outpipe, op);
    }
}

void am_output_drain(comp_t *c)
{
    for (int i = 0; i < 2; i++)
        if (c->out.pipe[i].fd >= 0 && outpipe_drain(&c->out.pipe[i]) == 0)
            outpipe_close(&c->out.pipe[i]);
}

void am_output_moved(comp_t *c)
{
    for (int i = 0; i < 2; i++) {
        outpipe_t *op = &c->out.pipe[i];
        op->c = c;
        outpipe_unpause(op);    /* its timer knows it by its old place */
        if (op->fd >= 0) {      /* the loop's callback follows the pipe to its new place */
            marie_loop_remove_fd(c->am->env.loop, op->fd);
            marie_loop_add_fd(c->am->env.loop, op->fd, POLLIN, on_outpipe, op);
        }
    }
}

void am_comp_open_log(comp_t *c)
{
    if (c->out.file || !c->sv.local)
        return;
    char path[PATH_MAX];
    int64_t max_bytes;
    int keep;
    am_log_settings(c->am, &max_bytes, &keep);
    snprintf(path, sizeof path, "%s/logs/%s.log", c->am->env.state_dir, c->cfg->name);
    c->out.file = marie_logfile_open(path, max_bytes, keep);
    if (!c->out.file)
        marie_warn("%s: cannot open log file %s: %s", c->cfg->name, path, strerror(errno));
}

int64_t am_output_drops(const comp_t *c) { return c->out.drops_total; }

void am_output_free(comp_t *c)
{
    am_comp_close_output(c);
    for (int i = 0; i < 2; i++)
        MARIE_CLEAR(c->out.pipe[i].lb, free);
    MARIE_CLEAR(c->out.file, marie_logfile_close);
}
