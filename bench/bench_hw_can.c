/* bench_hw_can: motor command to CAN frame latency (LCM publish -> RPDO1 on the emulated
 * bus, p50/p99) and CPU and memory (RSS, anonymous RSS, PSS) of marie-drives and marie-gyro at
 * their nominal rates (50 Hz SYNC, 20 Hz encoders, 50 Hz gyro), against marie-vcan-devices on
 * marie-canbus. */
#include <fcntl.h>
#include <lcm/lcm.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "bench/bench.h"
#include "core/config.h"
#include "core/loop.h"
#include "core/procstat.h"
#include "core/time.h"
#include "hw/can/can.h"
#include "lcmtypes/marie_motor_command_t.h"
#include "lcmtypes/marie_wheel_encoders_t.h"
#include "tests/proc.h"

static char bindir[256];
static int enc_ok;

static pid_t spawn(const char *name, char *const args[])
{
    char path[512];
    snprintf(path, sizeof path, "%s/%s", bindir, name);
    char *argv[16];
    int n = 0;
    argv[n++] = path;
    for (int i = 0; args[i] && n < 15; i++)
        argv[n++] = args[i];
    argv[n] = NULL;
    return test_spawn(argv, "/dev/null");
}

static void on_enc(const lcm_recv_buf_t *rb, const char *ch, const marie_wheel_encoders_t *m, void *u)
{
    enc_ok = m->status == MARIE_WHEEL_ENCODERS_T_STATUS_OK;
}

/* The command being timed: its left-wheel target, recognised in RPDO1 on the spy's bus. */
typedef struct {
    can_bus_t *spy;
    int32_t want;
    bool armed;
    int64_t sent, seen;         /* mono us; seen 0 until the RPDO came */
} probe_t;

static void on_spy(marie_loop_t *loop, int fd, short revents, void *user)
{
    probe_t *p = user;
    struct can_frame f;
    while (can_bus_read(p->spy, &f) == 1) {
        int32_t tgt;
        memcpy(&tgt, f.data + 2, 4);
        if (p->armed && f.len == 6 && tgt == p->want) {
            p->seen = marie_mono_us();
            p->armed = false;
        }
    }
}

/* CPU seconds used so far, and a memory field of /proc/PID/status or smaps_rollup in MB. */
static double cpu_s(pid_t pid)
{
    int64_t us = 0, rss;
    marie_proc_usage(pid, &us, &rss);
    return us / 1e6;
}

static double mem_mb(pid_t pid, const char *key)
{
    return marie_proc_field_bytes(pid, strcmp(key, "Pss") == 0 ? "smaps_rollup" : "status", key) / 1048576.0;
}

static int cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

int main(void)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    snprintf(bindir, sizeof bindir, "%s/bin", b);
    char sock[96], url[112], param[128];
    snprintf(sock, sizeof sock, "/tmp/marie-bench-can-%d.sock", getpid());
    snprintf(url, sizeof url, "emu:%s", sock);
    snprintf(param, sizeof param, "can=%s", url);
    setenv("MARIE_LOG", "warn", 1);
    pid_t bus = spawn("marie-canbus", (char *[]){ sock, NULL });
    for (int i = 0; i < 50 && access(sock, F_OK) != 0; i++)
        usleep(100000);
    pid_t dev = spawn("marie-vcan-devices", (char *[]){ "--can", url, NULL });
    pid_t drv = spawn("marie-drives", (char *[]){ "--param", param, NULL });
    pid_t gyr = spawn("marie-gyro", (char *[]){ "--param", param, NULL });
    lcm_t *lcm = lcm_create(marie_default_url());
    can_bus_t *spy = can_bus_open(url);
    marie_loop_t *loop = marie_loop_create();
    int rc = 1;
    if (!lcm || !spy || !loop || bus <= 0 || dev <= 0 || drv <= 0 || gyr <= 0) {
        fprintf(stderr, "bench_hw_can: setup failed\n");
        goto out;
    }
    struct can_filter flt = { 0x201, 0x7FF };
    can_bus_set_filters(spy, &flt, 1);
    marie_wheel_encoders_t_subscription_t *se = marie_wheel_encoders_t_subscribe(lcm, "WHEEL_ENCODERS", on_enc, NULL);
    probe_t pr = { .spy = spy };
    marie_loop_add_bus(loop, lcm, 1);
    marie_loop_add_fd(loop, can_bus_fd(spy), POLLIN, on_spy, &pr);
    int64_t t0 = marie_mono_us();
    while (!enc_ok && marie_mono_us() - t0 < 20000000)
        marie_loop_run_once(loop, 50);
    if (!enc_ok) {
        fprintf(stderr, "bench_hw_can: drives never enabled\n");
        goto out_sub;
    }

    /* Latency: each command has a distinct v; its left-wheel target is recognised in RPDO1. */
    enum { N = 300 };
    static double lat[N];
    int got = 0;
    struct can_frame f;
    for (int i = 0; i < N; i++) {
        while (can_bus_read(spy, &f) == 1)
            ;
        double v = 0.01 * (1 + i % 50);                 /* 0.01 .. 0.5 m/s */
        pr.want = (int32_t)lround(v / 0.1 * 4096 / (2 * M_PI));
        pr.seen = 0;
        pr.armed = true;
        marie_motor_command_t m = { .utime = marie_wall_us(), .v = v, .omega = 0, .source = "bench" };
        pr.sent = marie_mono_us();
        marie_motor_command_t_publish(lcm, "MOTOR_COMMAND", &m);
        while (!pr.seen && marie_mono_us() - pr.sent < 200000)
            marie_loop_run_once(loop, 20);
        pr.armed = false;
        if (pr.seen)
            lat[got++] = (pr.seen - pr.sent) / 1000.0;
        /* keep the rate of a real controller (20 Hz) so the drivers run at nominal load */
        while (marie_mono_us() - pr.sent < 50000)
            marie_loop_run_once(loop, 10);
    }
    if (got > 0) {
        qsort(lat, (size_t)got, sizeof lat[0], cmp);
        bench_row("hw_can", "cmd_to_rpdo_p50", lat[got / 2], "ms", NAN);
        bench_row("hw_can", "cmd_to_rpdo_p99", lat[(int)(got * 0.99) < got ? (int)(got * 0.99) : got - 1], "ms", NAN);
    }
    char of[32];
    snprintf(of, sizeof of, "of %d", N);
    bench_row("hw_can", "cmd_to_rpdo_seen", got, of, NAN);

    /* CPU and memory over 10 s at nominal rates, commanded at 10 Hz. */
    double d0 = cpu_s(drv), g0 = cpu_s(gyr), v0 = cpu_s(dev), b0 = cpu_s(bus);
    int64_t w0 = marie_mono_us(), last = 0;
    while (marie_mono_us() - w0 < 10000000) {
        if (marie_mono_us() - last >= 100000) {
            marie_motor_command_t m = { .utime = marie_wall_us(), .v = 0.3, .omega = 0.2, .source = "bench" };
            marie_motor_command_t_publish(lcm, "MOTOR_COMMAND", &m);
            last = marie_mono_us();
        }
        marie_loop_run_once(loop, 20);     /* the spy's frames are read and dropped */
    }
    double wall = (marie_mono_us() - w0) / 1e6;
    bench_row("hw_can", "marie-drives_cpu", 100.0 * (cpu_s(drv) - d0) / wall, "% of a core", NAN);
    bench_row("hw_can", "marie-drives_rss", mem_mb(drv, "VmRSS"), "MB", NAN);
    bench_row("hw_can", "marie-drives_rss_anon", mem_mb(drv, "RssAnon"), "MB", NAN);
    bench_row("hw_can", "marie-drives_pss", mem_mb(drv, "Pss"), "MB", NAN);
    bench_row("hw_can", "marie-gyro_cpu", 100.0 * (cpu_s(gyr) - g0) / wall, "% of a core", NAN);
    bench_row("hw_can", "marie-gyro_rss", mem_mb(gyr, "VmRSS"), "MB", NAN);
    bench_row("hw_can", "marie-gyro_rss_anon", mem_mb(gyr, "RssAnon"), "MB", NAN);
    bench_row("hw_can", "marie-gyro_pss", mem_mb(gyr, "Pss"), "MB", NAN);
    bench_row("hw_can", "marie-vcan-devices_cpu", 100.0 * (cpu_s(dev) - v0) / wall, "% of a core", NAN);
    bench_row("hw_can", "marie-canbus_cpu", 100.0 * (cpu_s(bus) - b0) / wall, "% of a core", NAN);
    rc = 0;
out_sub:
    marie_wheel_encoders_t_unsubscribe(lcm, se);
out:
    marie_loop_destroy(loop);
    can_bus_close(spy);
    test_stop(gyr);
    test_stop(drv);
    test_stop(dev);
    test_stop(bus);
    if (lcm)
        lcm_destroy(lcm);
    unlink(sock);
    return rc;
}
