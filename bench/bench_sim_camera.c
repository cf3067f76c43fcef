/* bench_sim_camera: what the simulator's camera costs: render time per frame and the real-time
 * factor with and without it, in-process and as the marie-sim program. */
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "bench/bench.h"
#include "core/loop.h"
#include "core/time.h"
#include "lcmtypes/marie_sim_clock_t.h"
#include "map/occmap.h"
#include "sim/camera.h"
#include "sim/world.h"

#define WORLD "sim/worlds/office.yaml"

static void row(const char *bench, const char *metric, double v, const char *unit)
{
    bench_row(bench, metric, v, unit, NAN);
}

/* Physics, laser at 10 Hz and, when w x h is given, the camera at 10 Hz for sim_s along the
 * office corridor. Returns the real-time factor; *frame_ms the mean render time. */
static double run(const occmap_t *m, int w, int h, double sim_s, double *frame_ms)
{
    sim_params_t p;
    sim_params_default(&p);
    p.start_x = 10.0;
    p.start_y = 15.0;
    sim_world_t *world = sim_world_create(m, &p);
    sim_camera_t *cam = NULL;
    if (w) {
        sim_camera_cfg_t cfg = { .hz = 10, .step = p.step, .width = w, .height = h, .seed = 1 };
        char why[256];
        cam = sim_camera_create(WORLD, m, &cfg, why, sizeof why);
        if (!cam) {
            fprintf(stderr, "bench_sim_camera: %s\n", why);
            exit(1);
        }
    }
    float scan[181];
    long steps = lround(sim_s / p.step), frames = 0;
    int64_t t0 = marie_mono_us(), render_us = 0;
    double sink = 0;
    for (long i = 0; i < steps; i++) {
        if (i % 400 == 0)               /* a 1 m circle, alternating direction: walls and signs pass by */
            sim_world_set_velocity(world, 0.5, (i / 400) % 2 ? 0.5 : -0.5);
        sim_world_step(world);
        if (i % 20 == 0)
            sink += sim_world_laser(world, scan, 181);
        if (cam) {
            double x, y, th;
            marie_image_t img;
            sim_world_pose(world, &x, &y, &th);
            int64_t r0 = marie_mono_us();
            if (sim_camera_step(cam, i, x, y, th, i, &img) == 1) {
                frames++;
                render_us += marie_mono_us() - r0;
                sink += img.data[0];
            }
        }
    }
    double wall = (marie_mono_us() - t0) / 1e6;
    if (frame_ms)
        *frame_ms = frames ? render_us / 1e3 / frames : 0;
    if (sink == 12345.678)
        puts("");
    sim_camera_destroy(cam);
    sim_world_destroy(world);
    return sim_s / wall;
}

static int64_t last_clock = -1;
static void on_clock(const lcm_recv_buf_t *rb, const char *ch, const marie_sim_clock_t *msg, void *u)
{
    last_clock = msg->utime;
}

static int have_clock(void *user) { return last_clock >= 0; }

/* marie-sim as fast as it goes (--speed 0) for wall_s: the sim seconds per wall second. */
static double program(const char *bin, const char *camera, double wall_s)
{
    lcm_t *lcm = lcm_create(NULL);
    marie_loop_t *loop = marie_loop_create();
    if (!lcm || !loop || marie_loop_add_bus(loop, lcm, 1) < 0)
        exit(1);
    marie_sim_clock_t_subscribe(lcm, "MARIE_CLOCK", on_clock, NULL);
    last_clock = -1;
    pid_t pid = fork();
    if (pid == 0) {
        execl(bin, bin, "--world", "office", "--param", "start_x=10", "--param", "start_y=15", "--speed", "0",
              "--param", camera, "--param", "camera_size=320x240", (char *)NULL);
        _exit(127);
    }
    int64_t t0 = marie_mono_us(), c0 = -1;
    if (marie_loop_run_until(loop, 20000, have_clock, NULL) == 1) {
        c0 = last_clock;
        t0 = marie_mono_us();
        marie_loop_run_until(loop, (int)(wall_s * 1000), NULL, NULL);
    }
    double wall = (marie_mono_us() - t0) / 1e6;
    kill(pid, SIGTERM);
    waitpid(pid, NULL, 0);
    marie_loop_destroy(loop);
    lcm_destroy(lcm);
    if (c0 < 0) {
        fprintf(stderr, "bench_sim_camera: no clock from %s\n", bin);
        exit(1);
    }
    return (last_clock - c0) / 1e6 / wall;
}

int main(void)
{
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load(WORLD, &errs);
    if (!m) {
        marie_errors_print(&errs, stderr);
        return 1;
    }
    /* Rounds alternate so both sides see the same machine load. */
    double base = 0, with320 = 0, with640 = 0, ms320 = 0, ms640 = 0, ms;
    for (int round = 0; round < 2; round++) {
        base += run(m, 0, 0, 60.0, NULL) / 2;
        with320 += run(m, 320, 240, 60.0, &ms) / 2;
        ms320 += ms / 2;
        with640 += run(m, 640, 480, 30.0, &ms) / 2;
        ms640 += ms / 2;
    }
    row("sim_camera_render_320x240", "per_frame", ms320, "ms");
    row("sim_camera_render_640x480", "per_frame", ms640, "ms");
    row("sim_physics_no_camera", "rtf", base, "x");
    row("sim_physics_camera_320x240_10hz", "rtf", with320, "x");
    row("sim_physics_camera_640x480_10hz", "rtf", with640, "x");
    row("sim_physics_camera_320x240_10hz", "ratio_to_no_camera", with320 / base, "x");
    occmap_destroy(m);
    const char *bin = getenv("B") ? NULL : "build/bin/marie-sim";
    char path[256];
    if (!bin) {
        snprintf(path, sizeof path, "%s/bin/marie-sim", getenv("B"));
        bin = path;
    }
    row("marie_sim_speed_0_no_camera", "rtf", program(bin, "camera=false", 4.0), "x");
    row("marie_sim_speed_0_camera_320x240_10hz", "rtf", program(bin, "camera=true", 4.0), "x");
    return 0;
}
