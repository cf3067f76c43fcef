/* test_lms200_driver: the LMS200 driver against the virtual LMS200 over a real pty, in one
 * poll loop: init sequence, both resolutions, CRC errors, garbage, truncation, silence and
 * an unplugged device that comes back. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <pty.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>

#include "hw/lms200/driver.h"
#include "hw/lms200/vlms200.h"

static int64_t mono_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000 + ts.tv_nsec / 1000;
}

typedef struct {
    vlms200_t *emu;
    lms200_driver_t *drv;
    char dir[64], link[96];
    int64_t scans, bad_ranges, events;
    int last_n;
    char last_event[64];
    int reconnect_events;
    int open_failed_events;
    bool moving;                /* ranges change every scan: check their shape only */
    double last_wall;
    int moving_bad;
    int degraded_calls, recovered_calls;
    bool degraded;
    bool stalled;               /* the driver does nothing, the device streams on (a loaded machine) */
    int64_t lag_us;             /* the driver reads this late (its clock says so) */
    int64_t stamp[512];         /* each scan's time as the driver gave it */
    int64_t wall_mm[512];       /* and its ranges (all alike when moving), in mm */
    int64_t read_at[512];       /* and when the rig handed the driver the read that brought it */
    int nstamp;
    int64_t io_now;             /* the time given to the driver's io and tick of this step */
} rig_t;

static void on_scan(void *user, const lms200_scan_t *s, int res_cdeg, int64_t t)
{
    rig_t *r = user;
    r->scans++;
    r->last_n = s->n;
    double w = lms200_value_m(s->values[0], s->unit);
    if (r->nstamp < 512) {
        r->read_at[r->nstamp] = r->io_now;
        r->wall_mm[r->nstamp] = llround(w * 1000);
        r->stamp[r->nstamp++] = t;
    }
    if (r->moving) {
        /* Every beam sees the same wall, a little further than in the scan before. */
        for (int i = 1; i < s->n; i++)
            if (fabs(lms200_value_m(s->values[i], s->unit) - w) > 1e-9)
                r->moving_bad++;
        if (w <= r->last_wall)
            r->moving_bad++;
        r->last_wall = w;
        return;
    }
    for (int i = 0; i < s->n; i++) {
        double want = vlms200_expected_range(r->emu, i, res_cdeg);
        double got = lms200_value_m(s->values[i], s->unit);
        if (!(fabs(want - got) < 1e-6) && !(isinf(want) && isinf(got)))
            r->bad_ranges++;
    }
}

static void on_event(void *user, int sev, const char *kind, const char *text)
{
    rig_t *r = user;
    r->events++;
    snprintf(r->last_event, sizeof r->last_event, "%s", kind);
    if (strcmp(kind, "laser_reconnected") == 0)
        r->reconnect_events++;
    if (strcmp(kind, "laser_open_failed") == 0)
        r->open_failed_events++;
}

static void on_health(void *user, bool degraded, const char *why)
{
    rig_t *r = user;
    r->degraded = degraded;
    if (degraded)
        r->degraded_calls++;
    else
        r->recovered_calls++;
}

static const lms200_driver_ops_t ops = { .on_scan = on_scan, .on_event = on_event, .on_health = on_health };

/* The driver's defaults with a test's device, line rate and resolution (1/100 degree). */
static lms200_driver_cfg_t drv_cfg(const char *device, int baud, int res_cdeg)
{
    lms200_driver_cfg_t c = LMS200_DRIVER_DEFAULTS;
    c.device = device;
    c.baud = baud;
    c.resolution = res_cdeg / 100.0;
    return c;
}

static void rig_open(rig_t *r, const vlms200_cfg_t *ecfg, int baud, int res)
{
    memset(r, 0, sizeof *r);
    snprintf(r->dir, sizeof r->dir, "/tmp/lms200-test-XXXXXX");
    assert_non_null(mkdtemp(r->dir));
    snprintf(r->link, sizeof r->link, "%s/ttyLMS", r->dir);
    r->emu = vlms200_create(ecfg);
    assert_non_null(r->emu);
    assert_int_equal(vlms200_open(r->emu, r->link), 0);
    lms200_driver_cfg_t cfg = drv_cfg(r->link, baud, res);
    cfg.reply_timeout_ms = 150;
    cfg.config_timeout_ms = 500;
    cfg.retries = 2;
    cfg.data_timeout_ms = 800;
    cfg.reopen_ms = 100;
    r->drv = lms200_driver_create(&cfg, &ops, r);
    assert_non_null(r->drv);
}

/* Both ends' counters, for the log (and for a case that fails, before it fails). */
static void rig_report(const rig_t *r)
{
    if (r->drv) {
        const lms200_driver_stats_t *st = lms200_driver_stats(r->drv);
        const vlms200_stats_t *es = vlms200_stats(r->emu);
        print_message("driver: scans %lld crc %lld trunc %lld oversized %lld garbage %lld timeouts %lld "
                      "disconnects %lld reconnects %lld inits %lld naks %lld | device: sent %lld "
                      "mismatch %lld baud %d\n",
                      (long long)st->scans, (long long)st->crc_errors, (long long)st->truncated,
                      (long long)st->oversized, (long long)st->garbage_bytes, (long long)st->timeouts,
                      (long long)st->disconnects, (long long)st->reconnects, (long long)st->inits,
                      (long long)st->naks, (long long)es->scans_sent, (long long)es->baud_mismatch_bytes,
                      vlms200_baud(r->emu));
    }
}

static void rig_close(rig_t *r)
{
    rig_report(r);
    lms200_driver_destroy(r->drv);
    vlms200_destroy(r->emu);
    rmdir(r->dir);
}

/* One poll round over both ends. */
static void step(rig_t *r)
{
    struct pollfd p[2];
    int n = 0, ie = -1, id = -1;
    if (vlms200_fd(r->emu) >= 0) {
        ie = n;
        p[n++] = (struct pollfd){ .fd = vlms200_fd(r->emu), .events = vlms200_events(r->emu) };
    }
    if (r->drv && lms200_driver_fd(r->drv) >= 0) {
        id = n;
        p[n++] = (struct pollfd){ .fd = lms200_driver_fd(r->drv), .events = lms200_driver_events(r->drv) };
    }
    int64_t now = mono_us();
    int64_t dl = vlms200_deadline(r->emu);
    if (r->drv && lms200_driver_deadline(r->drv) < dl)
        dl = lms200_driver_deadline(r->drv);
    int timeout = 20;
    if (dl != INT64_MAX && (dl - now) / 1000 < timeout)
        timeout = dl <= now ? 0 : (int)((dl - now) / 1000) + 1;
    poll(p, (nfds_t)n, timeout);
    now = mono_us();
    r->io_now = now;
    int efd = vlms200_fd(r->emu), dfd = r->drv ? lms200_driver_fd(r->drv) : -1;
    if (ie >= 0 && p[ie].revents && p[ie].fd == efd)
        vlms200_io(r->emu, p[ie].revents, now);
    if (id >= 0 && p[id].revents && p[id].fd == dfd && !r->stalled)
        lms200_driver_io(r->drv, p[id].revents, now + r->lag_us);
    vlms200_tick(r->emu, now);
    if (r->drv && !r->stalled)
        lms200_driver_tick(r->drv, now);
}

/* Run until cond holds or max_ms passes (bounded: the machine may be slow, never hung). */
#define RUN_UNTIL(r, max_ms, cond) ({ int64_t end_ = mono_us() + (int64_t)(max_ms) * 1000; \
        while (!(cond) && mono_us() < end_) { step(r); } (cond); })

/* Open the rig, start the driver and wait up to within_ms for its first n scans. */
static bool rig_streaming(rig_t *r, const vlms200_cfg_t *e, int baud, int res_cdeg, int n, int within_ms)
{
    rig_open(r, e, baud, res_cdeg);
    lms200_driver_start(r->drv, mono_us());
    return RUN_UNTIL(r, within_ms, r->scans >= n);
}

static void run_for(rig_t *r, int ms)
{
    int64_t end = mono_us() + (int64_t)ms * 1000;
    while (mono_us() < end)
        step(r);
}

static void test_init_sequence_reaches_stream_at_500000_half_degree(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm" };
    assert_true(rig_streaming(&r, &e, 500000, 50, 5, 5000));
    assert_int_equal(lms200_driver_state(r.drv), LMS200_DRV_STREAM);
    /* Both ends agree on the rate the driver was configured for. */
    assert_int_equal(vlms200_baud(r.emu), 500000);
    assert_int_equal(lms200_driver_baud(r.drv), 500000);
    assert_int_equal(vlms200_res_cdeg(r.emu), 50);
    assert_true(vlms200_streaming(r.emu));
    assert_int_equal(r.last_n, 361);
    assert_int_equal(r.bad_ranges, 0);
    const lms200_driver_stats_t *st = lms200_driver_stats(r.drv);
    assert_true(st->inits >= 1);
    assert_int_equal(st->crc_errors, 0);
    assert_int_equal(st->truncated, 0);
    rig_close(&r);
}

static void test_one_degree_in_centimetres_at_38400(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "cm" };
    rig_open(&r, &e, 38400, 100);
    /* Feed a pattern like the simulator does: a wall with a gap that sees nothing. */
    float m[19];
    for (int i = 0; i < 19; i++)
        m[i] = (i == 9) ? INFINITY : 3.0f + 0.1f * (float)i;
    vlms200_set_ranges(r.emu, m, 19);
    lms200_driver_start(r.drv, mono_us());
    assert_true(RUN_UNTIL(&r, 5000, r.scans >= 5));
    assert_int_equal(r.last_n, 181);
    assert_int_equal(r.bad_ranges, 0);
    assert_int_equal(vlms200_baud(r.emu), 38400);
    assert_true(isinf(vlms200_expected_range(r.emu, 90, 100)));
    rig_close(&r);
}

/* A simulator sets each scan's ranges from the scan callback: a wall that moves away. */
static void moving_wall(void *user, vlms200_t *v, int64_t now)
{
    int *k = user;
    float m[2] = { 2.0f + 0.01f * (float)*k, 2.0f + 0.01f * (float)*k };
    vlms200_set_ranges(v, m, 2);
    (*k)++;
}

static void test_scan_callback_feeds_each_scan(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm" };
    rig_open(&r, &e, 500000, 100);
    int k = 0;
    r.moving = true;
    vlms200_on_scan(r.emu, moving_wall, &k);
    lms200_driver_start(r.drv, mono_us());
    assert_true(RUN_UNTIL(&r, 5000, r.scans >= 5));
    assert_int_equal(r.moving_bad, 0);
    assert_true(r.last_wall > 2.0);
    assert_true(k >= 5);
    assert_true(vlms200_expected_range(r.emu, 0, 100) > 2.0);
    rig_close(&r);
}

/* The end of the scans the first read from `from` on brought (those the rig gave the driver
 * in one step). After a stall the device's backlog is in the line; the emulated device, held
 * with the rig when the whole process is, may write part of it a moment later, into a later
 * read, which a device on a real line would not: a case judges the first read. */
static int first_read_end(const rig_t *r, int from)
{
    int end = from;
    while (end < r->nstamp && r->read_at[end] == r->read_at[from])
        end++;
    return end;
}

/* The driver held for ms while the device streams on, then run until it delivered n more
 * scans: the index of the first of them. */
static int held_then_read(rig_t *r, int ms, int n)
{
    int before = r->nstamp;
    r->stalled = true;
    run_for(r, ms);
    r->stalled = false;
    assert_true(RUN_UNTIL(r, 1000, r->nstamp >= before + n));
    return before;
}

/* A driver that could not read for 120 ms finds six scans waiting: they were sent one period
 * apart, so they are stamped one period apart back from the read, not all at the read. */
static void test_scans_read_late_are_stamped_one_period_apart(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm" };
    assert_true(rig_streaming(&r, &e, 500000, 100, 20, 5000));
    int before = held_then_read(&r, 120, 5);
    int end = first_read_end(&r, before);
    print_message("%d scans read at once\n", end - before);
    assert_true(end - before >= 3);
    /* The first of them after the last one read before the stall (whose own stamp is its read,
     * as late as the scheduler made it), the rest 20 ms apart, as the arrivals measured, the
     * last at the read. */
    assert_true(r.stamp[before] > r.stamp[before - 1]);
    for (int i = before + 1; i < end; i++) {
        int64_t gap = r.stamp[i] - r.stamp[i - 1];
        assert_true(gap > 10000 && gap < 30000);   /* all at the read would be 0 */
    }
    assert_true(r.stamp[end - 1] > r.read_at[before] - 20000 && r.stamp[end - 1] <= r.read_at[before]);
    rig_close(&r);
}

/* Held 250 ms: one read brings more scans than the driver stamps together (8). None of them
 * is stamped after the read: the later ones were put a period after the batch before, into
 * the future, when each batch was stamped back from the read alone. */
static void test_a_backlog_longer_than_a_batch_is_not_stamped_in_the_future(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm" };
    assert_true(rig_streaming(&r, &e, 500000, 100, 20, 5000));
    int before = r.nstamp;
    /* Held while the device sends 12 scans (250 ms; longer on a loaded machine, where its late
     * ticks skip periods: 250 ms held brought 7 then) */
    int64_t sent = vlms200_stats(r.emu)->scans_sent;
    r.stalled = true;
    run_for(&r, 250);
    RUN_UNTIL(&r, 3000, vlms200_stats(r.emu)->scans_sent >= sent + 12);
    r.stalled = false;
    assert_true(RUN_UNTIL(&r, 1000, r.nstamp >= before + 9));
    /* The scans of the first read after it (the pty holds 11; what the emulated device could
     * not write yet comes in later reads, which a device on a real line would have lost) */
    int end = first_read_end(&r, before);
    print_message("%d scans in the first read after 250 ms held; the last stamped %lld us before it\n",
                  end - before, (long long)(r.read_at[before] - r.stamp[end - 1]));
    assert_true(end - before > 8);
    for (int i = before; i < end; i++) {
        assert_true(r.stamp[i] <= r.read_at[before]);
        if (i > before)
            assert_true(r.stamp[i] - r.stamp[i - 1] > 10000 && r.stamp[i] - r.stamp[i - 1] < 30000);
    }
    rig_close(&r);
}

/* The first scan of the stream read 15 ms late, the second on time: one gap of 5 ms. The
 * period the later arrivals show (20 ms) is still the one a backlog is stamped with (it stayed
 * at 5 ms for good when the first gap was the period and later ones had to be near it). */
static void test_a_first_scan_read_late_does_not_set_the_period(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm" };
    rig_open(&r, &e, 500000, 100);
    r.lag_us = 15000;           /* (the set-up's replies too: the first scan may come with them) */
    lms200_driver_start(r.drv, mono_us());
    assert_true(RUN_UNTIL(&r, 5000, r.nstamp >= 1));
    r.lag_us = 0;
    assert_true(RUN_UNTIL(&r, 5000, r.nstamp >= 30));
    int before = held_then_read(&r, 120, 5);
    int end = first_read_end(&r, before);
    assert_true(end - before >= 3);
    for (int i = before + 1; i < end; i++) {
        int64_t gap = r.stamp[i] - r.stamp[i - 1];
        print_message("late scan %d: %lld us after the one before\n", i - before, (long long)gap);
        assert_true(gap > 10000 && gap < 30000);
    }
    rig_close(&r);
}

/* A driver that could not run for longer than its data timeout (800 ms here) while the device
 * streamed on: its first act afterwards is its tick, as marie's loop runs timers before it reads
 * the fds. The scans are in the line: it reads them, and the laser is not declared silent nor
 * re-initialised (it was, each time the machine held the driver that long). */
static void test_a_driver_held_past_its_data_timeout_reads_before_it_judges(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm" };
    assert_true(rig_streaming(&r, &e, 500000, 100, 5, 5000));
    const lms200_driver_stats_t *st = lms200_driver_stats(r.drv);
    int64_t before = r.scans;
    r.stalled = true;
    run_for(&r, 1000);
    r.stalled = false;
    lms200_driver_tick(r.drv, mono_us());
    print_message("after 1 s held: %lld scans read at the tick, timeouts %lld\n", (long long)(r.scans - before),
                  (long long)st->timeouts);
    assert_int_equal(st->timeouts, 0);
    assert_true(r.scans > before);
    if (!RUN_UNTIL(&r, 5000, r.scans >= before + 60))
        rig_report(&r);         /* why, before the case fails (once on a loaded machine) */
    assert_true(r.scans >= before + 60);
    assert_int_equal(st->timeouts, 0);
    assert_int_equal(st->inits, 1);
    assert_int_equal(r.bad_ranges, 0);
    rig_close(&r);
}

/* With line_time the virtual device delivers a telegram its transfer time after the scan, as a
 * line does; marie-lms200 takes that time off the driver's arrival time again, so its stamps are
 * the scans' own instants (without it they came 7.4 ms early: 372 bytes at 500 kbaud that the
 * pty delivered at once). */
static int64_t taken[512];
static int ntaken;
/* Each scan the device takes sees a wall of its own, 1 m + 2 mm a scan: the driver's scan
 * says which one it is. */
#define WALL_MM(k) (1000 + 2 * (k))
static void note_taken(void *user, vlms200_t *v, int64_t now)
{
    if (ntaken >= 512)
        return;
    float m[2] = { WALL_MM(ntaken) / 1000.0f, WALL_MM(ntaken) / 1000.0f };
    vlms200_set_ranges(v, m, 2);
    taken[ntaken++] = now;
}

static int cmp_i64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

/* Scans read on time: alone in their read, within 2 ms of the end on the line of the scan
 * itself, which its wall says (it was the scan the device took last before the read: on a
 * loaded machine the device's late tick took the next one as the one before came out of the
 * line, and a scan read 7 ms after it was taken looked taken at its read). Their stamps less
 * the wire time against the instants the device took them. */
static int on_time_offsets(const rig_t *r, int64_t wire, int64_t *d, int max)
{
    int n = 0;
    for (int i = 10; i + 1 < r->nstamp && n < max; i++) {     /* past the stream's start */
        if (r->read_at[i] == r->read_at[i - 1] || r->read_at[i] == r->read_at[i + 1])
            continue;
        int64_t k = (r->wall_mm[i] - WALL_MM(0)) / 2;
        if (k >= 0 && k < ntaken && WALL_MM(k) == r->wall_mm[i] && taken[k] < r->read_at[i] &&
            r->read_at[i] - taken[k] < wire + 2000)
            d[n++] = r->stamp[i] - wire - taken[k];
    }
    return n;
}

static void test_line_time_puts_stamps_on_the_scans_instants(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm", .line_time = true };
    rig_open(&r, &e, 500000, 100);
    ntaken = 0;
    vlms200_on_scan(r.emu, note_taken, NULL);
    lms200_driver_start(r.drv, mono_us());
    int64_t d[30], wire = lms200_wire_us(lms200_scan_telegram_len(181), 500000);     /* as lms200_main.c */
    /* A scan read late is stamped late (by the read's delay): on a loaded machine a third of
     * the runs had a median past 4 ms, and a lower quartile too when the machine held the
     * process most of the window. So the scans compared are those read on time, as many as
     * come within 10 s (a telegram the pty delivered at once, at the scan's instant, counts as
     * on time: its stamp is 7.4 ms early, which is what this checks). */
    assert_true(RUN_UNTIL(&r, 10000, r.nstamp >= 40 && on_time_offsets(&r, wire, d, 30) >= 20));
    int n = on_time_offsets(&r, wire, d, 30);
    qsort(d, n, sizeof d[0], cmp_i64);
    print_message("stamp - scan, %d scans read on time of %d: median %lld us\n", n, r.nstamp, (long long)d[n / 2]);
    assert_true(d[n / 2] > -3000 && d[n / 2] < 4000);
    rig_close(&r);
}

static void test_stays_at_9600_when_configured(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm" };
    /* 181 values at 9600 baud take 0.38 s each: the device is slower, not broken. */
    assert_true(rig_streaming(&r, &e, 9600, 100, 2, 8000));
    assert_int_equal(vlms200_stats(r.emu)->baud_changes, 0);
    assert_int_equal(lms200_driver_stats(r.drv)->timeouts, 0);
    assert_int_equal(r.bad_ranges, 0);
    rig_close(&r);
}

/* At 9600 baud a 0.5 degree scan takes 0.76 s on the line: one damaged telegram leaves 1.52 s
 * between good scans, beyond the rig's fixed 800 ms (the production 1000 ms alike). The wait
 * follows the line instead (3 telegram times, 2.49 s): damage is counted, the laser is not
 * declared silent, nor re-initialised. */
static void test_a_bad_telegram_at_9600_is_no_silence(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm", .corrupt_every = 3 };
    assert_true(rig_streaming(&r, &e, 9600, 50, 1, 10000));
    const lms200_driver_stats_t *st = lms200_driver_stats(r.drv);
    int64_t scans = r.scans;
    RUN_UNTIL(&r, 8000, st->crc_errors >= 2 && r.scans >= scans + 4);
    assert_true(st->crc_errors >= 2);
    assert_true(r.scans >= scans + 4);
    assert_int_equal(st->timeouts, 0);
    assert_int_equal(st->inits, 1);
    assert_int_equal(st->garbage_bytes, 0);
    assert_int_equal(r.bad_ranges, 0);
    assert_int_equal(lms200_driver_data_timeout_ms(r.drv), 2487);     /* 3 x 762.5 ms + 200 */
    rig_close(&r);
}

static void test_crc_errors_counted_and_skipped(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 60, .units = "mm", .corrupt_every = 3 };
    assert_true(rig_streaming(&r, &e, 500000, 50, 20, 8000));
    const lms200_driver_stats_t *st = lms200_driver_stats(r.drv);
    assert_true(st->crc_errors >= 5);
    assert_int_equal(r.bad_ranges, 0);              /* no corrupt scan got through */
    assert_int_equal(st->reconnects, 0);            /* and none stopped the stream */
    rig_close(&r);
}

static void test_garbage_between_scans_resyncs(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 60, .units = "mm", .garbage_every = 2 };
    assert_true(rig_streaming(&r, &e, 500000, 50, 20, 8000));
    const lms200_driver_stats_t *st = lms200_driver_stats(r.drv);
    assert_true(st->garbage_bytes + st->truncated + st->crc_errors + st->oversized > 0);
    assert_int_equal(r.bad_ranges, 0);
    /* Garbage costs at most the odd scan whose start it swallowed. */
    assert_true(r.scans * 10 >= vlms200_stats(r.emu)->scans_sent * 6);
    rig_close(&r);
}

static void test_truncated_telegrams_counted(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 60, .units = "mm", .truncate_every = 4 };
    assert_true(rig_streaming(&r, &e, 500000, 50, 20, 8000));
    const lms200_driver_stats_t *st = lms200_driver_stats(r.drv);
    assert_true(st->truncated >= 3);
    assert_int_equal(r.bad_ranges, 0);
    rig_close(&r);
}

static void test_silent_device_reinitialised(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm" };
    assert_true(rig_streaming(&r, &e, 38400, 50, 3, 5000));
    vlms200_silence(r.emu, mono_us() + 2000 * 1000);
    const lms200_driver_stats_t *st = lms200_driver_stats(r.drv);
    assert_true(RUN_UNTIL(&r, 15000, st->reconnects >= 1));
    int64_t before = r.scans;
    assert_true(RUN_UNTIL(&r, 5000, r.scans >= before + 3));
    assert_true(st->timeouts >= 1);
    assert_true(r.reconnect_events >= 1);
    assert_int_equal(r.bad_ranges, 0);
    rig_close(&r);
}

static void test_unplugged_mid_scan_and_back(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm" };
    assert_true(rig_streaming(&r, &e, 500000, 50, 3, 5000));
    /* Pull the cable with a scan half written, then plug in a power-cycled device. */
    run_for(&r, 5);
    vlms200_unplug(r.emu, mono_us(), 500 * 1000);
    int64_t sent = vlms200_stats(r.emu)->scans_sent;
    /* Nothing at the path until the device is back: a link left to the freed pty named the
     * next pty anyone opened, and in a parallel make test the driver streamed from another
     * test's emulator (this device, back meanwhile, stayed at 9600). */
    struct stat sb;
    assert_int_equal(lstat(r.link, &sb), -1);
    assert_int_equal(errno, ENOENT);
    const lms200_driver_stats_t *st = lms200_driver_stats(r.drv);
    assert_true(RUN_UNTIL(&r, 3000, st->disconnects >= 1));
    assert_int_equal(lms200_driver_fd(r.drv), -1);
    assert_true(RUN_UNTIL(&r, 10000, st->reconnects >= 1));
    int64_t before = r.scans;
    assert_true(RUN_UNTIL(&r, 5000, r.scans >= before + 3));
    /* Scans from this device (it sent them all since it came back), which started at 9600:
     * the driver switched it to 500000 again. */
    assert_true(vlms200_stats(r.emu)->scans_sent - sent >= r.scans - before);
    assert_int_equal(vlms200_baud(r.emu), 500000);
    assert_true(st->inits >= 2);
    assert_int_equal(r.bad_ranges, 0);
    rig_close(&r);
}

static void test_restarted_driver_finds_streaming_device(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm" };
    assert_true(rig_streaming(&r, &e, 38400, 50, 3, 5000));
    /* The driver process dies without stopping the device: it keeps streaming at 38400. */
    lms200_driver_destroy(r.drv);
    r.drv = NULL;
    run_for(&r, 100);
    assert_true(vlms200_streaming(r.emu));
    lms200_driver_cfg_t cfg = drv_cfg(r.link, 38400, 50);
    cfg.reply_timeout_ms = 150;
    cfg.config_timeout_ms = 500;
    cfg.retries = 2;
    cfg.data_timeout_ms = 800;
    cfg.reopen_ms = 100;
    r.drv = lms200_driver_create(&cfg, &ops, &r);
    int64_t before = r.scans;
    lms200_driver_start(r.drv, mono_us());
    assert_true(RUN_UNTIL(&r, 8000, r.scans >= before + 3));
    /* It asked at 9600 first (garbled for a device at 38400), then found it. */
    assert_true(vlms200_stats(r.emu)->baud_mismatch_bytes > 0);
    assert_int_equal(r.bad_ranges, 0);
    rig_close(&r);
}

/* The driver dies without stopping the device (kill -9: no "stop continuous output"); the
 * device streams on into the void; a new driver with the production timeouts starts.
 * Returns the ms from its start to its first scan (-1: none within max_ms). */
static int64_t restart_driver(rig_t *r, int baud, int res, int max_ms)
{
    lms200_driver_destroy(r->drv);
    r->drv = NULL;
    run_for(r, 300);
    assert_true(vlms200_streaming(r->emu));
    lms200_driver_cfg_t cfg = drv_cfg(r->link, baud, res);
    r->drv = lms200_driver_create(&cfg, &ops, r);
    assert_non_null(r->drv);
    int64_t before = r->scans, t0 = mono_us();
    lms200_driver_start(r->drv, t0);
    bool ok = RUN_UNTIL(r, max_ms, r->scans > before);
    if (!ok)
        return -1;
    return (mono_us() - t0) / 1000;
}

static void test_restart_mid_stream_at_each_rate(void **state)
{
    /* As in the simulator: 181 beams, 10 scans per simulated second at 4x speed. */
    static const int rates[] = { 9600, 38400, 500000 };
    for (size_t i = 0; i < sizeof rates / sizeof rates[0]; i++) {
        rig_t r;
        vlms200_cfg_t e = { .rate_hz = 40, .units = "mm" };
        assert_true(rig_streaming(&r, &e, rates[i], 100, 3, 8000));
        assert_int_equal(vlms200_baud(r.emu), rates[i]);
        int64_t ms = restart_driver(&r, rates[i], 100, 5000);
        print_message("device streaming at %d baud: first scan %lld ms after the new driver started\n",
                      rates[i], (long long)ms);
        assert_true(ms >= 0);
        assert_true(ms <= 2000);
        assert_int_equal(r.bad_ranges, 0);
        rig_close(&r);
    }
}

static void test_restart_finds_device_left_at_another_rate(void **state)
{
    /* The last run used 38400 (RS-232); this one is configured for 500000 (RS-422). */
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 40, .units = "mm" };
    assert_true(rig_streaming(&r, &e, 38400, 100, 3, 8000));
    int64_t ms = restart_driver(&r, 500000, 100, 8000);
    print_message("device left at 38400, driver for 500000: first scan after %lld ms\n", (long long)ms);
    assert_true(ms >= 0);
    assert_int_equal(vlms200_baud(r.emu), 500000);
    assert_int_equal(lms200_driver_baud(r.drv), 500000);
    assert_int_equal(r.bad_ranges, 0);
    rig_close(&r);
}

static void test_degraded_while_silent_then_running(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 40, .units = "mm" };
    rig_open(&r, &e, 500000, 100);
    lms200_driver_destroy(r.drv);
    lms200_driver_cfg_t cfg = drv_cfg(r.link, 500000, 100);
    cfg.reply_timeout_ms = 150;
    cfg.data_timeout_ms = 500;
    cfg.degraded_ms = 1000;
    r.drv = lms200_driver_create(&cfg, &ops, &r);
    lms200_driver_start(r.drv, mono_us());
    assert_true(RUN_UNTIL(&r, 5000, r.scans >= 3));
    assert_false(lms200_driver_degraded(r.drv));
    assert_int_equal(r.degraded_calls, 0);
    int64_t t0 = mono_us();
    vlms200_silence(r.emu, t0 + 3000 * 1000);
    assert_true(RUN_UNTIL(&r, 5000, r.degraded));
    int64_t after = (mono_us() - t0) / 1000;
    print_message("degraded %lld ms after the device went silent\n", (long long)after);
    assert_true(after >= 900);                      /* not before degraded_ms without a scan */
    assert_true(lms200_driver_degraded(r.drv));
    assert_int_equal(r.degraded_calls, 1);          /* said once, not on every probe */
    assert_true(RUN_UNTIL(&r, 10000, !r.degraded));
    assert_true(mono_us() >= t0 + 3000 * 1000);
    assert_int_equal(r.recovered_calls, 1);
    assert_int_equal(lms200_driver_stats(r.drv)->degraded, 1);
    rig_close(&r);
}

/* What a simulator's lockstep relies on: a scan just written counts as unread until the driver
 * has read it, the moment it is written. The kernel hands a pty's bytes to the reading side
 * through a worker; a count that does not wait for it read 0 here for most scans. */
static void test_unread_counts_a_scan_the_moment_it_is_written(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm" };
    assert_true(rig_streaming(&r, &e, 500000, 100, 2, 5000));
    int seen_at_once = 0;
    for (int i = 0; i < 30; i++) {
        /* The device's side only (step() leaves a rig without driver alone): nothing reads. */
        lms200_driver_t *drv = r.drv;
        r.drv = NULL;
        int64_t sent = vlms200_stats(r.emu)->scans_sent, end = mono_us() + 2000000;
        while (vlms200_stats(r.emu)->scans_sent == sent && mono_us() < end)
            step(&r);
        r.drv = drv;
        assert_true(vlms200_stats(r.emu)->scans_sent > sent);
        if (vlms200_unread(r.emu) > 0)
            seen_at_once++;
        /* The driver reads it all: nothing is left unread then. */
        int64_t scans = r.scans;
        end = mono_us() + 2000000;
        while (r.scans == scans && mono_us() < end) {
            struct pollfd p = { .fd = lms200_driver_fd(r.drv), .events = POLLIN };
            if (poll(&p, 1, 20) > 0)
                lms200_driver_io(r.drv, p.revents, mono_us());
        }
        assert_true(r.scans > scans);
        assert_int_equal(vlms200_unread(r.emu), 0);
    }
    assert_int_equal(seen_at_once, 30);
    rig_close(&r);
}

static void test_missing_device_retried_until_it_appears(void **state)
{
    rig_t r;
    vlms200_cfg_t e = { .rate_hz = 50, .units = "mm" };
    rig_open(&r, &e, 38400, 100);
    vlms200_unplug(r.emu, mono_us(), 600 * 1000);
    lms200_driver_start(r.drv, mono_us());
    assert_int_equal(lms200_driver_fd(r.drv), -1);
    assert_true(RUN_UNTIL(&r, 8000, r.scans >= 3));
    assert_int_equal(r.open_failed_events, 1);     /* reported once, not once per attempt */
    /* Streaming now. Not which event said so: a stall of this one process (device and driver
     * both) on a loaded machine can time a probe out and make it a reconnection. */
    assert_int_equal(lms200_driver_state(r.drv), LMS200_DRV_STREAM);
    rig_close(&r);
}

/* A line that takes no byte (its far end stopped reading) never blocks the driver: the probe is
 * held and goes out, whole, once the line drains. */
static void test_full_line_never_blocks_and_command_goes_out_later(void **state)
{
    int master, slave;
    char path[64];
    assert_int_equal(openpty(&master, &slave, path, NULL, NULL), 0);
    struct termios t;
    tcgetattr(slave, &t);
    cfmakeraw(&t);
    tcsetattr(slave, TCSANOW, &t);
    fcntl(slave, F_SETFL, fcntl(slave, F_GETFL) | O_NONBLOCK);
    /* Full until the far end reads: a pty moves written bytes on to the reading side in a kernel
     * worker, which frees room after the first EAGAIN; write until a write 20 ms after the last
     * EAGAIN still finds no room. */
    static uint8_t fill[4096];
    size_t filled = 0;
    for (int room = 1; room;) {
        room = 0;
        for (ssize_t n; (n = write(slave, fill, sizeof fill)) > 0; room = 1)
            filled += (size_t)n;
        assert_true(errno == EAGAIN);
        usleep(20000);
    }
    lms200_driver_cfg_t cfg = drv_cfg(path, 9600, 100);
    cfg.reply_timeout_ms = 300;
    lms200_driver_t *d = lms200_driver_create(&cfg, NULL, NULL);
    assert_non_null(d);
    int64_t t0 = mono_us();
    lms200_driver_start(d, t0);
    assert_true(mono_us() - t0 < 100000);
    assert_true(lms200_driver_fd(d) >= 0);
    assert_true(lms200_driver_events(d) & POLLOUT);
    /* the far end reads again: the fill, then the whole probe ("stop continuous output") */
    static uint8_t in[8192];
    size_t got = 0, want = filled + 8;
    for (int round = 0; round < 100 && got < want; round++) {
        struct pollfd p = { .fd = master, .events = POLLIN };
        if (poll(&p, 1, 20) > 0) {
            ssize_t n = read(master, in, sizeof in);
            for (ssize_t i = 0; i < n; i++, got++)
                if (got == filled)
                    assert_int_equal(in[i], LMS200_STX);
        }
        struct pollfd q = { .fd = lms200_driver_fd(d), .events = lms200_driver_events(d) };
        if (poll(&q, 1, 0) > 0)
            lms200_driver_io(d, q.revents, mono_us());
    }
    assert_true(got >= want);
    assert_int_equal(lms200_driver_events(d), POLLIN);
    assert_int_equal(lms200_driver_stats(d)->disconnects, 0);
    lms200_driver_destroy(d);
    close(slave);
    close(master);
}

static void test_bad_config_refused(void **state)
{
    lms200_driver_cfg_t cfg = drv_cfg("/dev/null", 115200, 50);
    assert_null(lms200_driver_create(&cfg, &ops, NULL));
    assert_int_equal(errno, EINVAL);
    cfg.baud = 38400;
    cfg.resolution = 0.25;
    assert_null(lms200_driver_create(&cfg, &ops, NULL));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_init_sequence_reaches_stream_at_500000_half_degree),
        cmocka_unit_test(test_one_degree_in_centimetres_at_38400),
        cmocka_unit_test(test_scan_callback_feeds_each_scan),
        cmocka_unit_test(test_scans_read_late_are_stamped_one_period_apart),
        cmocka_unit_test(test_a_driver_held_past_its_data_timeout_reads_before_it_judges),
        cmocka_unit_test(test_a_first_scan_read_late_does_not_set_the_period),
        cmocka_unit_test(test_a_backlog_longer_than_a_batch_is_not_stamped_in_the_future),
        cmocka_unit_test(test_line_time_puts_stamps_on_the_scans_instants),
        cmocka_unit_test(test_stays_at_9600_when_configured),
        cmocka_unit_test(test_a_bad_telegram_at_9600_is_no_silence),
        cmocka_unit_test(test_crc_errors_counted_and_skipped),
        cmocka_unit_test(test_garbage_between_scans_resyncs),
        cmocka_unit_test(test_truncated_telegrams_counted),
        cmocka_unit_test(test_silent_device_reinitialised),
        cmocka_unit_test(test_unplugged_mid_scan_and_back),
        cmocka_unit_test(test_restarted_driver_finds_streaming_device),
        cmocka_unit_test(test_restart_mid_stream_at_each_rate),
        cmocka_unit_test(test_restart_finds_device_left_at_another_rate),
        cmocka_unit_test(test_degraded_while_silent_then_running),
        cmocka_unit_test(test_unread_counts_a_scan_the_moment_it_is_written),
        cmocka_unit_test(test_missing_device_retried_until_it_appears),
        cmocka_unit_test(test_full_line_never_blocks_and_command_goes_out_later),
        cmocka_unit_test(test_bad_config_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
