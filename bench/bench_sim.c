/* bench_sim: real-time factor of the simulator with the laser at 10 Hz, in-process (physics
 * and sensors only) and as the marie-sim program publishing on the bus, with CPU and RSS. */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "bench/bench.h"
#include "core/loop.h"
#include "core/time.h"
#include "lcmtypes/marie_sim_clock_t.h"
#include "map/occmap.h"
#include "sim/world.h"

static double cpu_s(int who)
{
    struct rusage ru;
    getrusage(who, &ru);
    return ru.ru_utime.tv_sec + ru.ru_stime.tv_sec + (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) / 1e6;
}

static void row(const char *bench, const char *metric, double v, const char *unit)
{
    bench_row(bench, metric, v, unit, NAN);
}

/* Physics, laser at 10 Hz and odometry at 50 Hz for sim_s, in the office corridor. */
static void in_process(const char *world, int beams, double sim_s)
{
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load(world, &errs);
    if (!m) {
        marie_errors_print(&errs, stderr);
        exit(1);
    }
    sim_params_t p;
    sim_params_default(&p);
    p.start_x = 10.0;
    p.start_y = 15.0;
    p.laser_beams = beams;
    sim_world_t *w = sim_world_create(m, &p);
    occmap_destroy(m);
    float *scan = calloc((size_t)beams, sizeof(float));
    long steps = lround(sim_s / p.step);
    double c0 = cpu_s(RUSAGE_SELF);
    int64_t t0 = marie_mono_us();
    double sink = 0;
    for (long i = 0; i < steps; i++) {
        if (i % 400 == 0)               /* a 1 m circle, alternating direction */
            sim_world_set_velocity(w, 0.5, (i / 400) % 2 ? 0.5 : -0.5);
        sim_world_step(w);
        if (i % 20 == 0)
            sink += sim_world_laser(w, scan, beams);
        if (i % 4 == 0) {
            int32_t l, r;
            sink += sim_world_gyro(w);
            sim_world_encoders(w, &l, &r);
        }
    }
    double wall = (marie_mono_us() - t0) / 1e6, cpu = cpu_s(RUSAGE_SELF) - c0;
    char name[64];
    snprintf(name, sizeof(name), "sim_physics_%d", beams);
    row(name, "rtf_laser_10hz", sim_s / wall, "x");
    row(name, "cpu_per_sim_s", 1e3 * cpu / sim_s, "ms");
    row(name, "step_with_sensors", 1e6 * wall / steps, "us");
    if (sink == 12345.678)
        puts("");
    free(scan);
    sim_world_destroy(w);
}

static int64_t last_clock = -1;
static void on_clock(const lcm_recv_buf_t *rb, const char *ch, const marie_sim_clock_t *msg, void *u)
{
    last_clock = msg->utime;
}

static int have_clock(void *user) { return last_clock >= 0; }

static long vm_hwm_kb(pid_t pid)
{
    char path[64], line[256];
    snprintf(path, sizeof(path), "/proc/%d/status", (int)pid);
    FILE *f = fopen(path, "r");
    long kb = -1;
    if (!f)
        return -1;
    while (fgets(line, sizeof(line), f))
        if (sscanf(line, "VmHWM: %ld", &kb) == 1)
            break;
    fclose(f);
    return kb;
}

/* CPU seconds a process has used so far (utime + stime from /proc). */
static double proc_cpu_s(pid_t pid)
{
    char path[64], buf[1024];
    snprintf(path, sizeof(path), "/proc/%d/stat", (int)pid);
    FILE *f = fopen(path, "r");
    if (!f)
        return 0;
    size_t n = fread(buf, 1, sizeof(buf) - 1, f);
    fclose(f);
    buf[n] = 0;
    char *p = strrchr(buf, ')');        /* the command name may hold spaces */
    unsigned long ut = 0, st = 0;
    if (!p || sscanf(p + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu", &ut, &st) != 2)
        return 0;
    return (double)(ut + st) / sysconf(_SC_CLK_TCK);
}

/* The program on the bus: run for wall_s at --speed, read the clock it reaches. */
static void program(const char *bin, const char *speed, double wall_s)
{
    lcm_t *lcm = lcm_create(NULL);
    marie_loop_t *loop = marie_loop_create();
    if (!lcm || !loop || marie_loop_add_bus(loop, lcm, 1) < 0) {
        fprintf(stderr, "bench_sim: no LCM\n");
        exit(1);
    }
    marie_sim_clock_t_subscribe(lcm, "MARIE_CLOCK", on_clock, NULL);
    last_clock = -1;
    pid_t pid = fork();
    if (pid == 0) {
        execl(bin, bin, "--world", "office", "--param", "start_x=10", "--param", "start_y=15",
              "--speed", speed, (char *)NULL);
        _exit(127);
    }
    /* Time from the first clock message, so process start and world loading are excluded. */
    int64_t t0 = marie_mono_us(), c0 = -1;
    long rss = -1;
    double cpu0 = 0;
    if (marie_loop_run_until(loop, 20000, have_clock, NULL) == 1) {
        c0 = last_clock;
        t0 = marie_mono_us();
        cpu0 = proc_cpu_s(pid);
        marie_loop_run_until(loop, (int)(wall_s * 1000), NULL, NULL);
    }
    double wall = (marie_mono_us() - t0) / 1e6;
    rss = vm_hwm_kb(pid);
    double cpu = proc_cpu_s(pid) - cpu0;
    kill(pid, SIGTERM);
    int status;
    waitpid(pid, &status, 0);
    char name[64];
    snprintf(name, sizeof(name), "marie_sim_speed_%s", speed);
    if (c0 < 0) {
        fprintf(stderr, "bench_sim: no clock from %s\n", bin);
        exit(1);
    }
    row(name, "rtf_laser_10hz", (last_clock - c0) / 1e6 / wall, "x");
    row(name, "cpu", 100.0 * cpu / wall, "% of a core");
    row(name, "rss", rss / 1024.0, "MB");
    marie_loop_destroy(loop);
    lcm_destroy(lcm);
}

int main(int argc, char **argv)
{
    const char *bin = getenv("B") ? NULL : "build/bin/marie-sim";
    char path[256];
    if (!bin) {
        snprintf(path, sizeof(path), "%s/bin/marie-sim", getenv("B"));
        bin = path;
    }
    in_process("sim/worlds/office.yaml", 181, 120.0);
    in_process("sim/worlds/office.yaml", 361, 60.0);
    program(bin, "0", 4.0);
    program(bin, "20", 4.0);
    return 0;
}
