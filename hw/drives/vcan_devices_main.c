/* marie-vcan-devices: the robot's virtual CAN devices (two CiA 402 drives and the gyro) on
 * a CAN bus, with ideal motors, for tests and benches without the simulator.
 *   marie-vcan-devices --can URL [--left N] [--right N] [--gyro N] [--ticks-per-rev T] ...
 * (the options are vdevices.params.yaml's; --help lists them; a value out of range or not a
 * number is refused with exit status 2.)
 * SIGUSR1 puts the left drive into fault (EMCY 0x2310 over-current); SIGUSR2 toggles a gyro
 * sensor fault. SIGTERM/SIGINT quit and print frame counts. */
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/cli.h"
#include "core/log.h"
#include "core/loop.h"
#include "core/time.h"
#include "hw/canopen/emcy.h"
#include "hw/drives/vdevices.h"
#include "core/version.h"

/* Physics and the devices' timers (heartbeats, the gyro's event timer, RPDO deadlines) step at
 * 1 kHz; frames are answered as they arrive. */
#define TICK_US 1000

typedef struct {
    vdevices_t *v;
    const char *url;
    int64_t last;               /* mono us of the last physics step */
    bool gyro_fault;
    int rc;
} vcan_t;

static void on_quit(marie_loop_t *loop, int signo, void *user)
{
    marie_loop_quit(loop);
}

static void on_frames(marie_loop_t *loop, int fd, short revents, void *user)
{
    vcan_t *d = user;
    if (vdevices_process(d->v, marie_mono_us()) < 0) {
        marie_error("CAN bus %s went away", d->url);
        d->rc = 1;
        marie_loop_quit(loop);
    }
}

static void on_tick(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    vcan_t *d = user;
    int64_t now = marie_mono_us();
    vdevices_tick(d->v, (now - d->last) / 1e6, now);
    d->last = now;
}

/* SIGUSR1 / SIGUSR2, from the loop: the faults are injected. */
static void on_usr(marie_loop_t *loop, int signo, void *user)
{
    vcan_t *d = user;
    if (signo == SIGUSR1 && vdevices_drive(d->v, 0)) {
        vdrive_inject_fault(vdevices_drive(d->v, 0), CO_EMCY_OVERCURRENT);
        marie_info("left drive: injected over-current fault");
    } else if (signo == SIGUSR2 && vdevices_gyro(d->v)) {
        d->gyro_fault = !d->gyro_fault;
        vgyro_set_fault(vdevices_gyro(d->v), d->gyro_fault);
    }
}

int main(int argc, char **argv)
{
    marie_version_exit("marie-vcan-devices", argc, argv);
    vdevices_cfg_t cfg;
    vdevices_cfg_default(&cfg);
    const marie_cli_opt_t opts[] = { VDEVICES_CLI(&cfg) { NULL } };
    int rc = marie_cli_parse("marie-vcan-devices", opts, argc, argv);
    if (rc >= 0)
        return rc;
    if (!cfg.can || optind != argc) {
        marie_cli_usage("marie-vcan-devices", opts, stderr);
        return 2;
    }
    marie_loop_t *loop = marie_loop_create();
    if (!loop || marie_loop_catch_signals(loop, on_quit, NULL) < 0) {
        marie_error("cannot set up the loop: %s", strerror(errno));
        return 1;
    }
    vcan_t d = { .url = cfg.can, .last = marie_mono_us() };
    d.v = vdevices_create(&cfg, d.last);
    if (!d.v) {
        marie_error("cannot attach to %s: %s", cfg.can, strerror(errno));
        return 1;
    }
    marie_info("virtual drives %lld/%lld and gyro %lld on %s", (long long)cfg.left, (long long)cfg.right,
               (long long)cfg.gyro, cfg.can);
    int r = marie_loop_add_fd(loop, vdevices_fd(d.v), POLLIN, on_frames, &d);
    if (r == 0)
        r = marie_loop_watch_signals(loop, (const int[]){ SIGUSR1, SIGUSR2 }, 2, on_usr, &d);
    if (r == 0 && !marie_loop_add_timer(loop, TICK_US, on_tick, &d))
        r = -1;
    if (r < 0) {
        marie_error("cannot set up the loop: %s", strerror(errno));
        d.rc = 1;
    } else if (marie_loop_run(loop) < 0) {
        d.rc = 1;
    }
    const vdevices_stats_t *st = vdevices_stats(d.v);
    marie_info("frames in %llu, out %llu", (unsigned long long)st->frames_in, (unsigned long long)st->frames_out);
    vdevices_destroy(d.v);
    marie_loop_destroy(loop);
    return d.rc;
}
