/* marie-vcan-devices: the robot's virtual CAN devices (two CiA 402 drives and the gyro) on
 * a CAN bus, with ideal motors, for tests and benches without the simulator.
 *   marie-vcan-devices --can URL [--left N] [--right N] [--gyro N] [--ticks-per-rev T]
 *       [--wheel-radius M] [--track-width M] [--gyro-bias R] [--gyro-noise R] [--rpdo-timeout S]
 * (--help lists them; a value out of range or not a number is refused with exit status 2.)
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
    vdevices_cfg_t cfg;
    vdevices_cfg_default(&cfg);
    int64_t left = cfg.left, right = cfg.right, gyro = cfg.gyro, ticks = cfg.ticks_per_rev;
    double rpdo_timeout = cfg.rpdo_timeout_us / 1e6;
    int64_t no_consumer = 0, no_deadline = 0;
    const marie_cli_opt_t opts[] = {
        { "can", MARIE_CLI_STRING, &cfg.can_url, 0, 0, "URL  the bus: can:IFNAME or emu:PATH (required)" },
        { "left", MARIE_CLI_INT, &left, 0, 127, "N    the left drive's node id (0: none)" },
        { "right", MARIE_CLI_INT, &right, 0, 127, "N    the right drive's node id (0: none)" },
        { "gyro", MARIE_CLI_INT, &gyro, 0, 127, "N    the gyro's node id (0: none)" },
        { "ticks-per-rev", MARIE_CLI_INT, &ticks, 1, 1 << 24, "T    encoder increments per wheel turn" },
        { "wheel-radius", MARIE_CLI_DOUBLE, &cfg.wheel_radius, 1e-3, 10, "M    for the ideal yaw rate" },
        { "track-width", MARIE_CLI_DOUBLE, &cfg.track_width, 1e-3, 100, "M    for the ideal yaw rate" },
        { "gyro-bias", MARIE_CLI_DOUBLE, &cfg.gyro_bias, -10, 10, "R    rad/s" },
        { "gyro-noise", MARIE_CLI_DOUBLE, &cfg.gyro_noise, 0, 10, "R    rad/s" },
        { "rpdo-timeout", MARIE_CLI_DOUBLE, &rpdo_timeout, 0, 60, "S    the drives' RPDO deadline (0: off)" },
        { "no-consumer", MARIE_CLI_INT, &no_consumer, 0, 1, "1    drives without 0x1016 (consumer heartbeat)" },
        { "no-rpdo-deadline", MARIE_CLI_INT, &no_deadline, 0, 1, "1    drives without 0x1400:05 (RPDO event timer)" },
        { NULL },
    };
    int rc = marie_cli_parse("marie-vcan-devices", opts, argc, argv);
    if (rc >= 0)
        return rc;
    if (!cfg.can_url || optind != argc) {
        marie_cli_usage("marie-vcan-devices", opts, stderr);
        return 2;
    }
    cfg.left = (uint8_t)left;
    cfg.right = (uint8_t)right;
    cfg.gyro = (uint8_t)gyro;
    cfg.ticks_per_rev = (int32_t)ticks;
    cfg.rpdo_timeout_us = (int64_t)(rpdo_timeout * 1e6);
    cfg.no_consumer = no_consumer;
    cfg.no_rpdo_deadline = no_deadline;
    marie_loop_t *loop = marie_loop_create();
    if (!loop || marie_loop_catch_signals(loop, on_quit, NULL) < 0) {
        marie_error("cannot set up the loop: %s", strerror(errno));
        return 1;
    }
    vcan_t d = { .url = cfg.can_url, .last = marie_mono_us() };
    d.v = vdevices_create(&cfg, d.last);
    if (!d.v) {
        marie_error("cannot attach to %s: %s", cfg.can_url, strerror(errno));
        return 1;
    }
    marie_info("virtual drives %u/%u and gyro %u on %s", cfg.left, cfg.right, cfg.gyro, cfg.can_url);
    int r = marie_loop_add_fd(loop, vdevices_fd(d.v), POLLIN, on_frames, &d);
    if (r == 0)
        r = marie_loop_watch_signals(loop, (const int[]){ SIGUSR1, SIGUSR2 }, 2, on_usr, &d);
    if (r == 0 && !marie_loop_add_timer(loop, TICK_US, on_tick, &d))
        r = -errno;
    if (r < 0) {
        marie_error("cannot set up the loop: %s", strerror(-r));
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
