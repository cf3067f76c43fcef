/* bench_lms200: LMS200 parsing throughput, and CPU/RSS of marie-lms200 streaming from
 * marie-vlms200 over a pty at the LMS200's nominal rate. TSV rows on stdout. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "bench/bench.h"
#include "core/loop.h"
#include "core/procstat.h"
#include "core/time.h"
#include "hw/lms200/lms200.h"
#include "lcmtypes/marie_laser_scan_t.h"
#include "tests/proc.h"

static void row(const char *bench, const char *metric, double value, const char *unit)
{
    bench_row(bench, metric, value, unit, NAN);
}

static long scans;
static void on_telegram(void *user, const lms200_telegram_t *t)
{
    static lms200_scan_t s;
    if (lms200_decode_scan(t, &s) == 0)
        scans++;
}

static void bench_parse(void)
{
    uint16_t v[361];
    for (int i = 0; i < 361; i++)
        v[i] = (uint16_t)(1000 + 7 * i);
    enum { COPIES = 64 };
    static uint8_t stream[COPIES * LMS200_MAX_TELEGRAM];
    size_t len = 0;
    for (int k = 0; k < COPIES; k++)
        len += lms200_encode_scan(stream + len, sizeof stream - len, 0, LMS200_UNIT_MM, v, 361, 0x10);
    lms200_parser_t *p = lms200_parser_create(on_telegram, NULL, NULL);
    /* Serial reads deliver a few hundred bytes at a time: feed 256-byte chunks. */
    int64_t t0 = marie_mono_us(), t;
    long bytes = 0;
    do {
        for (size_t off = 0; off < len; off += 256) {
            size_t n = len - off < 256 ? len - off : 256;
            lms200_parser_feed(p, stream + off, n);
        }
        bytes += (long)len;
        t = marie_mono_us();
    } while (t - t0 < 1000000);
    double s = (double)(t - t0) / 1e6;
    row("lms200_parse", "scans_per_s_361", (double)scans / s, "scans/s");
    row("lms200_parse", "throughput", (double)bytes / s / 1e6, "MB/s");
    lms200_parser_destroy(p);
}

static long bus_scans;
static void on_scan(const lcm_recv_buf_t *rb, const char *ch, const marie_laser_scan_t *m, void *user)
{
    bus_scans++;
}

/* The program `name` of the build b: out, "B/bin/NAME". */
static char *bin_path(char out[256], const char *b, const char *name)
{
    snprintf(out, 256, "%s/bin/%s", b, name);
    return out;
}

static void bench_driver(const char *b, const char *res, const char *rate, const char *label)
{
    char dir[] = "/tmp/lms200-bench-XXXXXX";
    if (!mkdtemp(dir))
        return;
    char link[128], emu[256], drv[256], dev[160], resp[64];
    snprintf(link, sizeof link, "%s/tty", dir);
    snprintf(dev, sizeof dev, "device=%s", link);
    snprintf(resp, sizeof resp, "resolution=%s", res);
    char *eargv[] = { bin_path(emu, b, "marie-vlms200"), "--link", link, "--rate", (char *)rate, NULL };
    pid_t pe = test_spawn(eargv, NULL);
    for (int i = 0; i < 100 && access(link, F_OK) != 0; i++)
        usleep(20000);
    char *dargv[] = { bin_path(drv, b, "marie-lms200"), "--param", dev, "--param", "baud=500000", "--param", resp, NULL };
    pid_t pd = test_spawn(dargv, NULL);
    lcm_t *lcm = lcm_create(NULL);
    marie_laser_scan_t_subscription_t *sub = marie_laser_scan_t_subscribe(lcm, "LASER", on_scan, NULL);
    marie_loop_t *loop = marie_loop_create();
    marie_loop_add_bus(loop, lcm, 1);
    /* Warm up until streaming, then measure over a fixed window. */
    int64_t end = marie_mono_us() + 5000000;
    while (bus_scans < 5 && marie_mono_us() < end)
        marie_loop_run_once(loop, 50);
    int64_t c0 = -1, e0 = -1, c1 = -1, e1 = -1, rss;
    marie_proc_usage(pd, &c0, &rss);
    marie_proc_usage(pe, &e0, &rss);
    long s0 = bus_scans;
    int64_t t0 = marie_mono_us();
    end = t0 + 10000000;   /* CPU time comes in 10 ms ticks: a long window */
    while (marie_mono_us() < end)
        marie_loop_run_once(loop, 50);
    double secs = (double)(marie_mono_us() - t0) / 1e6;
    marie_proc_usage(pd, &c1, &rss);
    marie_proc_usage(pe, &e1, &rss);
    char bench[64];
    snprintf(bench, sizeof bench, "lms200_driver_%s", label);
    if (c0 >= 0 && c1 >= 0) {
        row(bench, "scans_published", (double)(bus_scans - s0) / secs, "scans/s");
        row(bench, "cpu", 100.0 * (double)(c1 - c0) / 1e6 / secs, "%core");
        row(bench, "rss", (double)marie_proc_field_bytes(pd, "status", "VmRSS") / 1048576.0, "MB");
        row(bench, "rss_anon", (double)marie_proc_field_bytes(pd, "status", "RssAnon") / 1048576.0, "MB");
        row(bench, "pss", (double)marie_proc_field_bytes(pd, "smaps_rollup", "Pss") / 1048576.0, "MB");
        row(bench, "emulator_cpu", 100.0 * (double)(e1 - e0) / 1e6 / secs, "%core");
    } else {
        fprintf(stderr, "bench_lms200: marie-lms200 is not running\n");
    }
    marie_laser_scan_t_unsubscribe(lcm, sub);
    marie_loop_destroy(loop);
    lcm_destroy(lcm);
    test_stop(pd);
    test_stop(pe);
    char tmp[200];
    snprintf(tmp, sizeof tmp, "%s.tmp%d", link, (int)pe);
    unlink(tmp);
    unlink(link);
    rmdir(dir);
    bus_scans = 0;
}

int main(void)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    bench_parse();
    /* A real LMS200 turns at 75 Hz: every turn at 1 deg, every second one (interlaced) at 0.5. */
    bench_driver(b, "0.5", "37.5", "361x37.5hz");
    bench_driver(b, "1", "75", "181x75hz");
    return 0;
}
