/* marie-vlms200: a virtual SICK LMS200 on a pty, for tests and for running marie-lms200 without
 * the laser. The slave path goes to --path-file and/or the --link symlink. */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/log.h"
#include "core/loop.h"
#include "core/time.h"
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
    long silent_ms, unplug_ms;
} emu_t;

static void usage(FILE *out)
{
    fprintf(out,
            "usage: marie-vlms200 [options]\n"
            "  --link PATH          symlink to the pty slave (kept current across unplugs)\n"
            "  --path-file FILE     write the slave's path to FILE (rewritten on every reopen)\n"
            "  --rate HZ            scans per second while streaming (default 10; a real LMS200: 75)\n"
            "  --units mm|cm        units of measured values (default mm)\n"
            "  --corrupt-every N    every Nth scan has a bad CRC\n"
            "  --garbage-every N    garbage bytes before every Nth scan\n"
            "  --truncate-every N   every Nth scan is cut off half way\n"
            "  --silent-at MS --silent-ms T    stop answering T ms, MS ms after start\n"
            "  --unplug-at MS --unplug-ms T    close the pty MS ms after start; a fresh one T ms later\n"
            "  --ignore-baud        accept the host at any line speed\n");
}

static int write_path(const char *file, const char *path)
{
    if (!file)
        return 0;
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.tmp", file);
    FILE *f = fopen(tmp, "w");
    if (!f)
        return -errno;
    fprintf(f, "%s\n", path);
    if (fclose(f) != 0 || rename(tmp, file) < 0)
        return -errno;
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
            marie_warn("cannot write %s: %s", e->path_file, strerror(-rc));
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
    marie_info("fault: silent for %ld ms", e->silent_ms);
    vlms200_silence(e->v, marie_mono_us() + e->silent_ms * 1000);
    sync_device(e);
}

static void on_unplug(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    emu_t *e = user;
    marie_info("fault: unplugged for %ld ms", e->unplug_ms);
    vlms200_unplug(e->v, marie_mono_us(), e->unplug_ms * 1000);
    sync_device(e);
}

int main(int argc, char **argv)
{
    marie_version_exit("marie-vlms200", argc, argv);
    vlms200_cfg_t cfg = { .rate_hz = 10, .unit = LMS200_UNIT_MM };
    const char *link = NULL, *path_file = NULL;
    long silent_at = -1, silent_ms = 0, unplug_at = -1, unplug_ms = 1000;
    enum { O_LINK = 1, O_PATH, O_RATE, O_UNITS, O_CORRUPT, O_GARBAGE, O_TRUNC, O_SAT, O_SMS,
           O_UAT, O_UMS, O_IGN, O_HELP };
    static const struct option opts[] = {
        { "link", required_argument, 0, O_LINK }, { "path-file", required_argument, 0, O_PATH },
        { "rate", required_argument, 0, O_RATE }, { "units", required_argument, 0, O_UNITS },
        { "corrupt-every", required_argument, 0, O_CORRUPT },
        { "garbage-every", required_argument, 0, O_GARBAGE },
        { "truncate-every", required_argument, 0, O_TRUNC },
        { "silent-at", required_argument, 0, O_SAT }, { "silent-ms", required_argument, 0, O_SMS },
        { "unplug-at", required_argument, 0, O_UAT }, { "unplug-ms", required_argument, 0, O_UMS },
        { "ignore-baud", no_argument, 0, O_IGN }, { "help", no_argument, 0, O_HELP },
        { 0 },
    };
    int o;
    while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        switch (o) {
        case O_LINK: link = optarg; break;
        case O_PATH: path_file = optarg; break;
        case O_RATE: cfg.rate_hz = atof(optarg); break;
        case O_UNITS:
            if (strcmp(optarg, "mm") && strcmp(optarg, "cm")) {
                fprintf(stderr, "marie-vlms200: --units must be mm or cm\n");
                return 2;
            }
            cfg.unit = strcmp(optarg, "mm") == 0 ? LMS200_UNIT_MM : LMS200_UNIT_CM;
            break;
        case O_CORRUPT: cfg.corrupt_every = atoi(optarg); break;
        case O_GARBAGE: cfg.garbage_every = atoi(optarg); break;
        case O_TRUNC: cfg.truncate_every = atoi(optarg); break;
        case O_SAT: silent_at = atol(optarg); break;
        case O_SMS: silent_ms = atol(optarg); break;
        case O_UAT: unplug_at = atol(optarg); break;
        case O_UMS: unplug_ms = atol(optarg); break;
        case O_IGN: cfg.ignore_baud = true; break;
        case O_HELP: usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    if (optind < argc || cfg.rate_hz <= 0) {
        usage(stderr);
        return 2;
    }

    vlms200_t *v = vlms200_create(&cfg);
    if (!v) {
        marie_error("cannot create the virtual LMS200: %s", strerror(errno));
        return 1;
    }
    int rc = vlms200_open(v, link);
    if (rc < 0) {
        marie_error("cannot create the pty%s%s: %s", link ? " or link " : "", link ? link : "", strerror(-rc));
        vlms200_destroy(v);
        return 1;
    }
    char last_path[128];
    snprintf(last_path, sizeof last_path, "%s", vlms200_path(v));
    if ((rc = write_path(path_file, last_path)) < 0)
        marie_warn("cannot write %s: %s", path_file, strerror(-rc));
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
