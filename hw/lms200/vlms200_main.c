/* marie-vlms200: a virtual SICK LMS200 on a pty, for tests and for running marie-lms200 without
 * the laser. The slave path goes to --path-file and/or the --link symlink. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/cli.h"
#include "core/log.h"
#include "core/loop.h"
#include "core/time.h"
#include "core/version.h"
#include "hw/lms200/vlms200.h"
#include "core/version.h"

typedef struct {
    marie_loop_t *loop;
    vlms200_t *v;
    const char *path_file;
    char last_path[128];
    int fd;                     /* as watched by the loop, -1: none */
    short events;
    marie_timer_t *wake;        /* one-shot at the device's next deadline, NULL: none */
    int64_t silent_ms, unplug_ms;
} emu_t;

static int write_path(const char *file, const char *path)
{
    if (!file)
        return 0;
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.tmp", file);
    FILE *f = fopen(tmp, "w");
    if (!f)
        return -1;
    fprintf(f, "%s\n", path);
    if (fclose(f) != 0 || rename(tmp, file) < 0)
        return -1;
    return 0;
}

static void on_quit(marie_loop_t *loop, int signo, void *user)
{
    marie_loop_quit(loop);
}

static void on_io(marie_loop_t *loop, int fd, short revents, void *user);
static void on_wake(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user);

/* After anything the device did: the pty (new after a re-plug) and what to wait for on it,
 * its path for the driver, and a wake-up at its next deadline. */
static void sync_device(emu_t *e)
{
    int fd = vlms200_fd(e->v);
    short ev = fd >= 0 ? vlms200_events(e->v) : 0;
    if (fd != e->fd) {
        if (e->fd >= 0)
            marie_loop_remove_fd(e->loop, e->fd);
        e->fd = fd >= 0 && marie_loop_add_fd(e->loop, fd, ev, on_io, e) == 0 ? fd : -1;
    } else if (fd >= 0 && ev != e->events) {
        marie_loop_set_events(e->loop, fd, ev);
    }
    e->events = ev;
    if (fd >= 0 && strcmp(e->last_path, vlms200_path(e->v)) != 0) {
        snprintf(e->last_path, sizeof e->last_path, "%s", vlms200_path(e->v));
        marie_info("plugged in again on %s", e->last_path);
        int rc = write_path(e->path_file, e->last_path);
        if (rc < 0)
            marie_warn("cannot write %s: %s", e->path_file, strerror(errno));
    }
    marie_loop_remove_timer(e->loop, e->wake);
    e->wake = NULL;
    int64_t dl = vlms200_deadline(e->v), now = marie_mono_us();
    if (dl != INT64_MAX)
        e->wake = marie_loop_add_oneshot(e->loop, dl > now ? dl - now : 0, on_wake, e);
}

static void on_io(marie_loop_t *loop, int fd, short revents, void *user)
{
    emu_t *e = user;
    int64_t now = marie_mono_us();
    vlms200_io(e->v, revents, now);
    vlms200_tick(e->v, now);
    sync_device(e);
}

static void on_wake(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    emu_t *e = user;
    e->wake = NULL;             /* a one-shot is freed once it fired */
    vlms200_tick(e->v, marie_mono_us());
    sync_device(e);
}

static void on_silent(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    emu_t *e = user;
    marie_info("fault: silent for %lld ms", (long long)e->silent_ms);
    vlms200_silence(e->v, marie_mono_us() + e->silent_ms * 1000);
    sync_device(e);
}

static void on_unplug(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    emu_t *e = user;
    marie_info("fault: unplugged for %lld ms", (long long)e->unplug_ms);
    vlms200_unplug(e->v, marie_mono_us(), e->unplug_ms * 1000);
    sync_device(e);
}

int main(int argc, char **argv)
{
    marie_version_exit("marie-vlms200", argc, argv);
    vlms200_cfg_t cfg = VLMS200_DEFAULTS;
    const char *link = NULL, *path_file = NULL;
    int64_t silent_at = -1, silent_ms = 0, unplug_at = -1, unplug_ms = 1000;
    const marie_cli_opt_t opts[] = {
        { "link", MARIE_CLI_STRING, &link, 0, 0, "PATH symlink to the pty slave (kept current across unplugs)" },
        { "path-file", MARIE_CLI_STRING, &path_file, 0, 0, "FILE write the slave's path to FILE (rewritten on every reopen)" },
        VLMS200_CLI(&cfg)
        { "silent-at", MARIE_CLI_INT, &silent_at, 0, 1e9, "MS   stop answering for --silent-ms, MS ms after start" },
        { "silent-ms", MARIE_CLI_INT, &silent_ms, 0, 1e9, "T    how long it stays silent" },
        { "unplug-at", MARIE_CLI_INT, &unplug_at, 0, 1e9, "MS   close the pty MS ms after start" },
        { "unplug-ms", MARIE_CLI_INT, &unplug_ms, 0, 1e9, "T    a fresh pty T ms after the unplug (default 1000)" },
        { NULL },
    };
    int rc = marie_cli_parse("marie-vlms200", opts, argc, argv);
    if (rc >= 0)
        return rc;
    if (optind < argc) {
        marie_cli_usage("marie-vlms200", opts, stderr);
        return 2;
    }

    vlms200_t *v = vlms200_create(&cfg);
    if (!v) {
        marie_error("cannot create the virtual LMS200: %s", strerror(errno));
        return 1;
    }
    rc = vlms200_open(v, link);
    if (rc < 0) {
        marie_error("cannot create the pty%s%s: %s", link ? " or link " : "", link ? link : "", strerror(errno));
        vlms200_destroy(v);
        return 1;
    }
    char last_path[128];
    snprintf(last_path, sizeof last_path, "%s", vlms200_path(v));
    if ((rc = write_path(path_file, last_path)) < 0)
        marie_warn("cannot write %s: %s", path_file, strerror(errno));
    marie_info("virtual LMS200 on %s%s%s", last_path, link ? " via " : "", link ? link : "");

    emu_t e = { .loop = marie_loop_create(), .v = v, .path_file = path_file, .fd = -1,
                .silent_ms = silent_ms, .unplug_ms = unplug_ms };
    snprintf(e.last_path, sizeof e.last_path, "%s", last_path);
    if (!e.loop || marie_loop_catch_signals(e.loop, on_quit, NULL) < 0 ||
        (silent_at >= 0 && !marie_loop_add_oneshot(e.loop, silent_at * 1000, on_silent, &e)) ||
        (unplug_at >= 0 && !marie_loop_add_oneshot(e.loop, unplug_at * 1000, on_unplug, &e))) {
        marie_error("cannot set up the loop: %s", strerror(errno));
        vlms200_destroy(v);
        marie_loop_destroy(e.loop);
        return 1;
    }
    vlms200_tick(v, marie_mono_us());
    sync_device(&e);
    marie_loop_run(e.loop);
    marie_loop_destroy(e.loop);
    const vlms200_stats_t *st = vlms200_stats(v);
    marie_info("commands %lld scans %lld corrupted %lld garbage %lld truncated %lld dropped %lld",
               (long long)st->commands, (long long)st->scans_sent, (long long)st->corrupted,
               (long long)st->garbage_bytes, (long long)st->truncated, (long long)st->dropped_scans);
    vlms200_destroy(v);
    return 0;
}
