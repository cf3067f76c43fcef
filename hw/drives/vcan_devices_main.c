/* marie-vcan-devices: the robot's virtual CAN devices (two CiA 402 drives and the gyro) on
 * a CAN bus, with ideal motors, for tests and benches without the simulator.
 *   marie-vcan-devices --can URL [--left N] [--right N] [--gyro N] [--ticks-per-rev T]
 *       [--wheel-radius M] [--track-width M] [--gyro-bias R] [--gyro-noise R] [--rpdo-timeout S]
 * SIGUSR1 puts the left drive into fault (EMCY 0x2310 over-current); SIGUSR2 toggles a gyro
 * sensor fault. SIGTERM/SIGINT quit and print frame counts. */
#include <errno.h>
#include <getopt.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/log.h"
#include "core/time.h"
#include "hw/canopen/emcy.h"
#include "hw/drives/vdevices.h"

static volatile sig_atomic_t quit, drive_fault, gyro_fault;

static void on_signal(int s)
{
    if (s == SIGUSR1)
        drive_fault = 1;
    else if (s == SIGUSR2)
        gyro_fault = 1;
    else
        quit = 1;
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
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGUSR1, &sa, NULL);
    sigaction(SIGUSR2, &sa, NULL);

    int64_t t0 = marie_mono_us();
    vdevices_t *v = vdevices_create(&cfg, t0);
    if (!v) {
        marie_error("cannot attach to %s: %s", cfg.can_url, strerror(errno));
        return 1;
    }
    marie_info("virtual drives %u/%u and gyro %u on %s", cfg.left, cfg.right, cfg.gyro, cfg.can_url);
    int64_t last = t0;
    bool gfault = false;
    int rc = 0;
    while (!quit) {
        struct pollfd p = { .fd = vdevices_fd(v), .events = POLLIN };
        int r = poll(&p, 1, 1);                 /* physics and timers at about 1 kHz */
        int64_t now = marie_mono_us();
        if (r < 0 && errno != EINTR) {
            marie_error("poll: %s", strerror(errno));
            rc = 1;
            break;
        }
        if (r > 0 && vdevices_process(v, now) < 0) {
            marie_error("CAN bus %s went away", cfg.can_url);
            rc = 1;
            break;
        }
        if (drive_fault && vdevices_drive(v, 0)) {
            drive_fault = 0;
            vdrive_inject_fault(vdevices_drive(v, 0), CO_EMCY_OVERCURRENT);
            marie_info("left drive: injected over-current fault");
        }
        if (gyro_fault && vdevices_gyro(v)) {
            gyro_fault = 0;
            gfault = !gfault;
            vgyro_set_fault(vdevices_gyro(v), gfault);
        }
        if (now - last >= 1000) {
            vdevices_tick(v, (now - last) / 1e6, now);
            last = now;
        }
    }
    marie_info("frames in %llu, out %llu", (unsigned long long)vdevices_frames_in(v),
               (unsigned long long)vdevices_frames_out(v));
    vdevices_destroy(v);
    return rc;
}
