/* marie-vcan-devices: the robot's virtual CAN devices (two CiA 402 drives and the gyro) on
 * a CAN bus, with ideal motors, for tests and benches without the simulator.
 *   marie-vcan-devices --can URL [--left N] [--right N] [--gyro N] [--ticks-per-rev T]
 *       [--wheel-radius M] [--track-width M] [--gyro-bias R] [--gyro-noise R] [--rpdo-timeout S]
 * SIGUSR1 puts the left drive into fault (EMCY 0x2310 over-current); SIGUSR2 toggles a gyro
 * sensor fault. SIGTERM/SIGINT quit and print frame counts. */
#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

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

static void usage(FILE *out)
{
    fprintf(out, "usage: marie-vcan-devices --can URL [--left N] [--right N] [--gyro N (0: none)]\n"
                 "       [--ticks-per-rev T] [--wheel-radius M] [--track-width M] [--gyro-bias R]\n"
                 "       [--gyro-noise R] [--rpdo-timeout S]\n");
}

int main(int argc, char **argv)
{
    vdevices_cfg_t cfg;
    vdevices_cfg_default(&cfg);
    static const struct option opts[] = {
        { "can", required_argument, 0, 'c' }, { "left", required_argument, 0, 'l' },
        { "right", required_argument, 0, 'r' }, { "gyro", required_argument, 0, 'g' },
        { "ticks-per-rev", required_argument, 0, 't' }, { "wheel-radius", required_argument, 0, 'w' },
        { "track-width", required_argument, 0, 'k' }, { "gyro-bias", required_argument, 0, 'b' },
        { "gyro-noise", required_argument, 0, 'n' }, { "rpdo-timeout", required_argument, 0, 'o' },
        { "help", no_argument, 0, 'h' }, { 0, 0, 0, 0 },
    };
    int ch;
    while ((ch = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        switch (ch) {
        case 'c': cfg.can_url = optarg; break;
        case 'l': cfg.left = (uint8_t)atoi(optarg); break;
        case 'r': cfg.right = (uint8_t)atoi(optarg); break;
        case 'g': cfg.gyro = (uint8_t)atoi(optarg); break;
        case 't': cfg.ticks_per_rev = atoi(optarg); break;
        case 'w': cfg.wheel_radius = atof(optarg); break;
        case 'k': cfg.track_width = atof(optarg); break;
        case 'b': cfg.gyro_bias = atof(optarg); break;
        case 'n': cfg.gyro_noise = atof(optarg); break;
        case 'o': cfg.rpdo_timeout_us = (int64_t)(atof(optarg) * 1e6); break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    if (!cfg.can_url || optind != argc) {
        usage(stderr);
        return 2;
    }
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
    marie_info("frames in %llu, out %llu", (unsigned long long)vdevices_frames_in(d.v),
               (unsigned long long)vdevices_frames_out(d.v));
    vdevices_destroy(d.v);
    marie_loop_destroy(loop);
    return d.rc;
}
