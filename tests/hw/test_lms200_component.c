/* test_lms200_component: marie-lms200 and marie-vlms200 as separate processes over a pty, seen
 * from the bus: scans on LASER, counters in the heartbeat, events on reconnect, a driver
 * killed mid-stream and replaced, the heartbeat saying degraded while the device is silent. */
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <setjmp.h>
#include <stdbool.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmocka.h>
#include <lcm/lcm.h>

#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_heartbeat_t.h"
#include "lcmtypes/marie_laser_scan_t.h"
#include "lcmtypes/marie_lifecycle_command_t.h"
#include "tests/proc.h"

static int64_t mono_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

typedef struct {
    int scans, bad_scans, scans_after_reconnect;
    bool reconnected;
    int64_t crc_errors, reconnects, truncated, garbage;
    int64_t hb_bad_input;
    char kinds[512];
} seen_t;

static void on_scan(const lcm_recv_buf_t *rb, const char *ch, const marie_laser_scan_t *m, void *user)
{
    seen_t *s = user;
    s->scans++;
    if (s->reconnected)
        s->scans_after_reconnect++;
    bool ok = m->nranges == 181 && fabsf(m->angle_min + (float)M_PI / 2) < 1e-6f &&
              fabsf(m->angle_increment - (float)(M_PI / 180)) < 1e-6f && m->range_max > 8.0f;
    /* The emulator's default pattern: 1 m at the right, +1 cm per degree. */
    for (int i = 0; ok && i < m->nranges; i++)
        ok = fabsf(m->ranges[i] - (1.0f + 0.01f * (float)i)) < 1e-4f;
    if (!ok)
        s->bad_scans++;
}

static void on_hb(const lcm_recv_buf_t *rb, const char *ch, const marie_heartbeat_t *m, void *user)
{
    seen_t *s = user;
    if (strcmp(m->component, "lms200") != 0)
        return;
    s->hb_bad_input = m->bad_input;
    for (int i = 0; i < m->ncounters; i++) {
        const char *n = m->counters[i].name;
        int64_t v = m->counters[i].value;
        if (!strcmp(n, "crc_errors")) s->crc_errors = v;
        else if (!strcmp(n, "reconnects")) s->reconnects = v;
        else if (!strcmp(n, "truncated")) s->truncated = v;
        else if (!strcmp(n, "garbage_bytes")) s->garbage = v;
    }
}

static void on_event(const lcm_recv_buf_t *rb, const char *ch, const marie_event_t *m, void *user)
{
    seen_t *s = user;
    if (strcmp(m->source, "lms200") != 0)
        return;
    if (strlen(s->kinds) + strlen(m->kind) + 2 < sizeof s->kinds) {
        strcat(s->kinds, m->kind);
        strcat(s->kinds, " ");
    }
    if (!strcmp(m->kind, "laser_reconnected"))
        s->reconnected = true;
}

static void pump(lcm_t *lcm, int ms)
{
    struct pollfd p = { .fd = lcm_get_fileno(lcm), .events = POLLIN };
    if (poll(&p, 1, ms) > 0)
        lcm_handle(lcm);
}

static void test_scans_counters_and_reconnect_over_the_bus(void **state)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    char dir[] = "/tmp/lms200-proc-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char link[128], emu[256], drv[256], dev[160];
    snprintf(link, sizeof link, "%s/ttyLMS", dir);
    snprintf(emu, sizeof emu, "%s/bin/marie-vlms200", b);
    snprintf(drv, sizeof drv, "%s/bin/marie-lms200", b);
    snprintf(dev, sizeof dev, "device=%s", link);

    lcm_t *lcm = lcm_create(NULL);
    assert_non_null(lcm);
    seen_t s = { 0 };
    marie_laser_scan_t_subscription_t *s1 = marie_laser_scan_t_subscribe(lcm, "LASER", on_scan, &s);
    marie_heartbeat_t_subscription_t *s2 = marie_heartbeat_t_subscribe(lcm, "MARIE_HEARTBEAT", on_hb, &s);
    marie_event_t_subscription_t *s3 = marie_event_t_subscribe(lcm, "MARIE_EVENT", on_event, &s);

    /* A device with a bad CRC every 5th scan that is unplugged after 3 s for 0.5 s. */
    char *eargv[] = { emu, "--link", link, "--rate", "20", "--corrupt-every", "5",
                      "--unplug-at", "3000", "--unplug-ms", "500", NULL };
    pid_t pe = test_spawn(eargv, NULL);
    int64_t end = mono_ms() + 3000;
    while (access(link, F_OK) != 0 && mono_ms() < end)
        usleep(20000);
    assert_int_equal(access(link, F_OK), 0);
    char *dargv[] = { drv, "--param", dev, "--param", "baud=38400", "--param", "resolution=1",
                      "--param", "reply_timeout_ms=150", "--param", "config_timeout_ms=500",
                      "--param", "data_timeout_ms=1000",
                      "--param", "reopen_ms=100", NULL };
    pid_t pd = test_spawn(dargv, NULL);

    end = mono_ms() + 20000;
    while (mono_ms() < end &&
           !(s.scans >= 10 && s.scans_after_reconnect >= 5 && s.reconnects >= 1 && s.crc_errors >= 1))
        pump(lcm, 50);
    test_stop(pd);
    test_stop(pe);
    marie_laser_scan_t_unsubscribe(lcm, s1);
    marie_heartbeat_t_unsubscribe(lcm, s2);
    marie_event_t_unsubscribe(lcm, s3);
    lcm_destroy(lcm);
    char tmp[200];
    snprintf(tmp, sizeof tmp, "%s.tmp%d", link, (int)pe);
    unlink(tmp);
    unlink(link);
    rmdir(dir);

    print_message("scans %d (bad %d, after reconnect %d) crc %lld reconnects %lld bad_input %lld events: %s\n",
                  s.scans, s.bad_scans, s.scans_after_reconnect, (long long)s.crc_errors,
                  (long long)s.reconnects, (long long)s.hb_bad_input, s.kinds);
    assert_true(s.scans >= 10);
    assert_int_equal(s.bad_scans, 0);
    assert_true(s.crc_errors >= 1);
    assert_true(s.hb_bad_input >= s.crc_errors);
    assert_true(s.reconnects >= 1);
    assert_true(s.scans_after_reconnect >= 5);
    assert_non_null(strstr(s.kinds, "laser_streaming"));
    assert_non_null(strstr(s.kinds, "laser_disconnected"));
    assert_non_null(strstr(s.kinds, "laser_reconnected"));
}

/* The emulator on a pty behind a symlink in a scratch directory, and the LCM side. */
typedef struct {
    char dir[32], link[128], emu[256], drv[256], dev[160];
    lcm_t *lcm;
    marie_laser_scan_t_subscription_t *scan_sub;
    marie_heartbeat_t_subscription_t *hb_sub;
    pid_t pe;
    int scans;
    int8_t hb_state;            /* newest heartbeat state of the driver, -1 none yet */
    int running_hbs, degraded_hbs, running_after_degraded;
    char degraded_reason[256];
} rig_t;

static void rig_on_scan(const lcm_recv_buf_t *rb, const char *ch, const marie_laser_scan_t *m, void *user)
{
    ((rig_t *)user)->scans++;
}

static void rig_on_hb(const lcm_recv_buf_t *rb, const char *ch, const marie_heartbeat_t *m, void *user)
{
    rig_t *r = user;
    if (strcmp(m->component, "lms200") != 0)
        return;
    r->hb_state = m->state;
    if (m->state == MARIE_LIFECYCLE_COMMAND_T_STATE_RUNNING) {
        r->running_hbs++;
        r->running_after_degraded += r->degraded_hbs > 0;
    } else if (m->state == MARIE_LIFECYCLE_COMMAND_T_STATE_DEGRADED) {
        r->degraded_hbs++;
        snprintf(r->degraded_reason, sizeof r->degraded_reason, "%s", m->reason);
    }
}

static void rig_open(rig_t *r, char **emu_args)
{
    memset(r, 0, sizeof *r);
    r->hb_state = -1;
    const char *b = getenv("B") ? getenv("B") : "build";
    snprintf(r->dir, sizeof r->dir, "/tmp/lms200-proc-XXXXXX");
    assert_non_null(mkdtemp(r->dir));
    snprintf(r->link, sizeof r->link, "%s/ttyLMS", r->dir);
    snprintf(r->emu, sizeof r->emu, "%s/bin/marie-vlms200", b);
    snprintf(r->drv, sizeof r->drv, "%s/bin/marie-lms200", b);
    snprintf(r->dev, sizeof r->dev, "device=%s", r->link);
    r->lcm = lcm_create(NULL);
    assert_non_null(r->lcm);
    r->scan_sub = marie_laser_scan_t_subscribe(r->lcm, "LASER", rig_on_scan, r);
    r->hb_sub = marie_heartbeat_t_subscribe(r->lcm, "MARIE_HEARTBEAT", rig_on_hb, r);
    char *argv[24] = { r->emu, "--link", r->link };
    int n = 3;
    for (int i = 0; emu_args[i] && n < 23; i++)
        argv[n++] = emu_args[i];
    r->pe = test_spawn(argv, NULL);
    int64_t end = mono_ms() + 3000;
    while (access(r->link, F_OK) != 0 && mono_ms() < end)
        usleep(20000);
    assert_int_equal(access(r->link, F_OK), 0);
}

static void rig_close(rig_t *r)
{
    test_stop(r->pe);
    marie_laser_scan_t_unsubscribe(r->lcm, r->scan_sub);
    marie_heartbeat_t_unsubscribe(r->lcm, r->hb_sub);
    lcm_destroy(r->lcm);
    char tmp[200];
    snprintf(tmp, sizeof tmp, "%s.tmp%d", r->link, (int)r->pe);
    unlink(tmp);
    unlink(r->link);
    rmdir(r->dir);
}

/* marie-lms200 with the production timeouts, streaming at `baud`, 1 degree. */
static pid_t start_driver(rig_t *r, int baud, const char *extra)
{
    char b[32];
    snprintf(b, sizeof b, "baud=%d", baud);
    char *argv[] = { r->drv, "--param", r->dev, "--param", b, "--param", "resolution=1",
                     extra ? "--param" : NULL, (char *)extra, NULL };
    return test_spawn(argv, NULL);
}

/* Pump the bus until cond holds or max_ms passes. */
#define PUMP_UNTIL(r, max_ms, cond) ({ int64_t end_ = mono_ms() + (max_ms); \
        while (!(cond) && mono_ms() < end_) { pump((r)->lcm, 20); } (cond); })

static void test_killed_driver_replaced_scans_within_2s(void **state)
{
    static const int rates[] = { 9600, 38400, 500000 };
    /* 40 scans a second, as the simulator's LMS200 at 4x speed (the line caps it at 9600). */
    char *eargs[] = { "--rate", "40", NULL };
    rig_t r;
    rig_open(&r, eargs);
    for (size_t i = 0; i < sizeof rates / sizeof rates[0]; i++) {
        pid_t pd = start_driver(&r, rates[i], NULL);
        int before = r.scans;
        assert_true(PUMP_UNTIL(&r, 10000, r.scans >= before + 3));
        /* Killed mid-stream: no "stop continuous output", the device streams on. */
        kill(pd, SIGKILL);
        waitpid(pd, NULL, 0);
        PUMP_UNTIL(&r, 300, false);     /* let the dead driver's last scans drain */
        before = r.scans;
        int64_t t0 = mono_ms();
        pd = start_driver(&r, rates[i], NULL);
        bool back = PUMP_UNTIL(&r, 6000, r.scans > before);
        int64_t ms = mono_ms() - t0;
        print_message("%d baud: LASER back %lld ms after the new driver started\n", rates[i], (long long)ms);
        test_stop(pd);
        assert_true(back);
        assert_true(ms <= 2000);
    }
    rig_close(&r);
}

static void test_heartbeat_degraded_while_device_silent(void **state)
{
    /* Silent from 2.5 s to 6.5 s after the emulator starts. */
    char *eargs[] = { "--rate", "20", "--silent-at", "2500", "--silent-ms", "4000", NULL };
    rig_t r;
    rig_open(&r, eargs);
    int64_t t0 = mono_ms();
    pid_t pd = start_driver(&r, 38400, "degraded_ms=1000");
    assert_true(PUMP_UNTIL(&r, 2400, r.scans >= 3 && r.running_hbs >= 1));
    assert_int_equal(r.degraded_hbs, 0);
    assert_true(PUMP_UNTIL(&r, 6000, r.hb_state == MARIE_LIFECYCLE_COMMAND_T_STATE_DEGRADED));
    int64_t at = mono_ms() - t0;
    print_message("degraded at %lld ms (silent from 2500 ms): %s\n", (long long)at, r.degraded_reason);
    assert_true(at >= 3400);                    /* silence + degraded_ms, not before */
    assert_non_null(strstr(r.degraded_reason, "no valid scan"));
    int scans = r.scans;
    assert_true(PUMP_UNTIL(&r, 8000, r.hb_state == MARIE_LIFECYCLE_COMMAND_T_STATE_RUNNING));
    print_message("running again at %lld ms\n", (long long)(mono_ms() - t0));
    assert_true(mono_ms() - t0 >= 6400);
    assert_true(PUMP_UNTIL(&r, 3000, r.scans >= scans + 3));
    test_stop(pd);
    rig_close(&r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_scans_counters_and_reconnect_over_the_bus),
        cmocka_unit_test(test_killed_driver_replaced_scans_within_2s),
        cmocka_unit_test(test_heartbeat_degraded_while_device_silent),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
