/* test_gyro: the gyro master against the virtual gyro on an in-memory bus, and the bias
 * estimator. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "hw/canopen/emcy.h"
#include "hw/gyro/gyro_bias.h"
#include "hw/gyro/gyro_ctl.h"
#include "hw/gyro/gyro_proto.h"
#include "hw/gyro/vgyro.h"

/* The master's default node id: the virtual gyro's in these rigs. */
#define GYRO_NODE ((uint8_t)((gyro_cfg_t)GYRO_CFG_DEFAULTS).node)

typedef struct {
    gyro_ctl_t *ctl;
    vgyro_t *dev;
    int64_t now;
    bool cut, drop_odd;
    int ev[16];
    uint32_t code[16];
    int samples;
    double sum, last;
    uint8_t last_status;
} rig_t;

static void on_sample(void *u, double rate, uint8_t status)
{
    rig_t *r = u;
    r->samples++;
    r->sum += rate;
    r->last = rate;
    r->last_status = status;
}

static void on_ev(void *u, gyro_ev_t e, uint32_t code)
{
    rig_t *r = u;
    r->ev[e]++;
    r->code[e] = code;
}

static void exchange(rig_t *r, struct can_frame *f, int n, bool from_dev)
{
    struct can_frame q[64], tx[16];
    int qn = 0;
    for (int i = 0; i < n; i++) { q[qn] = f[i]; qn++; }
    bool src_dev[64];
    for (int i = 0; i < qn; i++) src_dev[i] = from_dev;
    for (int i = 0; i < qn; i++) {
        if (r->cut)
            continue;
        if (src_dev[i]) {
            int k = gyro_ctl_feed(r->ctl, &q[i], r->now, tx, 16);
            for (int j = 0; j < k && qn < 64; j++) { q[qn] = tx[j]; src_dev[qn++] = false; }
        } else {
            int k = vgyro_feed(r->dev, &q[i], r->now, tx, 16);
            for (int j = 0; j < k && qn < 64; j++) { q[qn] = tx[j]; src_dev[qn++] = true; }
        }
    }
}

static void run(rig_t *r, int ms)
{
    struct can_frame tx[16];
    for (int k = 0; k < ms; k++) {
        r->now += 1000;
        int n = vgyro_poll(r->dev, r->now, tx, 16);
        if (r->drop_odd && n > 0 && tx[0].can_id == 0x1A0 && (tx[0].data[5] & 1))
            n = 0;
        exchange(r, tx, n, true);
        if (k % 10 == 0)
            exchange(r, tx, gyro_ctl_poll(r->ctl, r->now, tx, 16), false);
    }
}

static int setup(void **state)
{
    rig_t *r = calloc(1, sizeof *r);
    gyro_cfg_t cfg;
    gyro_cfg_default(&cfg);
    cfg.rate_hz = 100;
    r->ctl = gyro_ctl_create(&cfg, on_sample, on_ev, r);
    vgyro_cfg_t vc;
    vgyro_cfg_default(&vc, GYRO_NODE);
    vc.bias = 0.02;
    vc.noise = 0.001;
    r->dev = vgyro_create(&vc);
    r->now = 5000000;
    struct can_frame tx[16];
    exchange(r, tx, vgyro_boot(r->dev, r->now, tx, 16), true);
    exchange(r, tx, gyro_ctl_start(r->ctl, r->now, tx, 16), false);
    *state = r;
    return 0;
}

static int teardown(void **state)
{
    rig_t *r = *state;
    gyro_ctl_destroy(r->ctl);
    vgyro_destroy(r->dev);
    free(r);
    return 0;
}

static void configures_and_streams_samples(void **state)
{
    rig_t *r = *state;
    vgyro_set_rate(r->dev, 0.5);
    run(r, 1000);
    assert_true(gyro_ctl_running(r->ctl));
    assert_int_equal(r->ev[GYRO_EV_CONFIGURED], 1);
    assert_string_equal(gyro_ctl_name(r->ctl), "marie vgyro");
    assert_int_equal(vgyro_nmt(r->dev), CO_NMT_OPERATIONAL);
    assert_true(r->samples >= 95 && r->samples <= 101);     /* 100 Hz event timer */
    assert_true(fabs(r->sum / r->samples - 0.52) < 0.002);  /* truth + bias */
    assert_int_equal(r->ev[GYRO_EV_LOST], 0);
    assert_int_equal(r->last_status, GYRO_STATUS_OK);
}

static void lost_samples_fault_and_timeout(void **state)
{
    rig_t *r = *state;
    run(r, 500);
    r->drop_odd = true;
    run(r, 200);
    assert_true(r->ev[GYRO_EV_LOST] >= 8);
    r->drop_odd = false;
    vgyro_set_fault(r->dev, 1);
    run(r, 50);
    assert_int_equal(r->ev[GYRO_EV_EMCY], 1);
    assert_int_equal(r->code[GYRO_EV_EMCY], CO_EMCY_SENSOR);
    assert_int_equal(r->last_status, GYRO_STATUS_SENSOR_FAULT);
    vgyro_set_fault(r->dev, 0);
    run(r, 50);
    assert_int_equal(r->code[GYRO_EV_EMCY], CO_EMCY_NO_ERROR);
    r->cut = true;
    run(r, 1000);
    assert_int_equal(r->ev[GYRO_EV_HB_TIMEOUT], 1);
    assert_false(gyro_ctl_running(r->ctl));
    r->cut = false;
    int before = r->samples;
    run(r, 3000);
    assert_true(gyro_ctl_running(r->ctl));
    assert_true(r->samples > before + 50);
}

static void saturation_is_flagged(void **state)
{
    rig_t *r = *state;
    vgyro_set_rate(r->dev, 9.0);
    run(r, 600);
    assert_int_equal(r->last_status, GYRO_STATUS_SATURATED);
    assert_true(fabs(r->last - 5.0) < 1e-6);
}

static void malformed_frames_are_reported(void **state)
{
    rig_t *r = *state;
    run(r, 500);
    struct can_frame tx[4];
    struct can_frame shortp = { .can_id = 0x1A0, .len = 3 };
    struct can_frame other = { .can_id = 0x1A1, .len = 6 };
    struct can_frame tpdo2 = { .can_id = 0x2A0, .len = 6 };
    gyro_ctl_feed(r->ctl, &shortp, r->now, tx, 4);
    gyro_ctl_feed(r->ctl, &other, r->now, tx, 4);
    gyro_ctl_feed(r->ctl, &tpdo2, r->now, tx, 4);
    assert_int_equal(r->ev[GYRO_EV_BAD_FRAME], 1);
    assert_int_equal(r->ev[GYRO_EV_UNEXPECTED], 2);
}

/* A loaded host: every frame takes `latency_ms` to reach the other side. The device boots
 * by itself `boot_ms` after the driver starts (powered up together, it is the slower); 0:
 * it was up before the driver, its boot-up long gone (the simulator's devices); < 0: never. */
typedef struct {
    struct can_frame f;
    int64_t at;
    bool to_dev;
} flight_t;

typedef struct {
    rig_t r;
    flight_t q[256];
    int n;
    int64_t latency_us;
} slow_t;

static void send_slow(slow_t *s, const struct can_frame *f, int n, bool to_dev)
{
    for (int i = 0; i < n && s->n < 256; i++)
        s->q[s->n++] = (flight_t){ f[i], s->r.now + s->latency_us, to_dev };
}

static void deliver_due(slow_t *s)
{
    struct can_frame tx[16];
    for (int i = 0; i < s->n;) {
        if (s->q[i].at > s->r.now) {
            i++;
            continue;
        }
        flight_t fl = s->q[i];
        memmove(&s->q[i], &s->q[i + 1], (size_t)(s->n - i - 1) * sizeof s->q[0]);
        s->n--;
        if (fl.to_dev)
            send_slow(s, tx, vgyro_feed(s->r.dev, &fl.f, s->r.now, tx, 16), false);
        else
            send_slow(s, tx, gyro_ctl_feed(s->r.ctl, &fl.f, s->r.now, tx, 16), true);
    }
}

static void slow_start(slow_t *s, int latency_ms, int boot_ms, int run_ms)
{
    memset(s, 0, sizeof *s);
    s->latency_us = latency_ms * 1000;
    gyro_cfg_t cfg;
    gyro_cfg_default(&cfg);
    s->r.ctl = gyro_ctl_create(&cfg, on_sample, on_ev, &s->r);
    vgyro_cfg_t vc;
    vgyro_cfg_default(&vc, GYRO_NODE);
    s->r.dev = vgyro_create(&vc);
    s->r.now = 1000000;
    struct can_frame tx[16];
    if (boot_ms == 0)
        vgyro_boot(s->r.dev, s->r.now, tx, 16);
    send_slow(s, tx, gyro_ctl_start(s->r.ctl, s->r.now, tx, 16), true);
    for (int k = 1; k <= run_ms; k++) {
        s->r.now += 1000;
        if (k == boot_ms)
            send_slow(s, tx, vgyro_boot(s->r.dev, s->r.now, tx, 16), false);
        send_slow(s, tx, vgyro_poll(s->r.dev, s->r.now, tx, 16), false);
        if (k % 10 == 0)
            send_slow(s, tx, gyro_ctl_poll(s->r.ctl, s->r.now, tx, 16), true);
        deliver_due(s);
    }
}

static void slow_end(slow_t *s)
{
    gyro_ctl_destroy(s->r.ctl);
    vgyro_destroy(s->r.dev);
}

/* The demo's start: driver and device come up together on a busy machine. Nothing failed,
 * so no fault may be reported; the gyro must still be configured and sampling. */
static void normal_start_on_a_slow_bus_raises_no_fault(void **state)
{
    static const struct { int latency_ms, boot_ms; } cases[] = { { 0, 500 }, { 40, 0 }, { 60, 500 } };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        slow_t s;
        slow_start(&s, cases[i].latency_ms, cases[i].boot_ms, 6000);
        print_message("latency %d ms, device boots at %d ms: configured %d, hb_timeout %d, not_found %d, "
                      "samples %d\n", cases[i].latency_ms, cases[i].boot_ms, s.r.ev[GYRO_EV_CONFIGURED],
                      s.r.ev[GYRO_EV_HB_TIMEOUT], s.r.ev[GYRO_EV_NOT_FOUND], s.r.samples);
        assert_int_equal(s.r.ev[GYRO_EV_HB_TIMEOUT], 0);
        assert_int_equal(s.r.ev[GYRO_EV_NOT_FOUND], 0);
        assert_int_equal(s.r.ev[GYRO_EV_CONFIG_FAILED], 0);
        assert_int_equal(s.r.ev[GYRO_EV_CONFIGURED], 1);
        assert_true(gyro_ctl_running(s.r.ctl));
        assert_true(s.r.samples > 100);
        slow_end(&s);
    }
}

/* A gyro that never boots is reported, once, as not found; a heartbeat it never had is
 * not "lost". */
static void absent_gyro_reported_once_as_not_found(void **state)
{
    slow_t s;
    slow_start(&s, 0, -1, 7000);
    assert_int_equal(s.r.ev[GYRO_EV_NOT_FOUND], 1);
    assert_int_equal(s.r.ev[GYRO_EV_HB_TIMEOUT], 0);
    assert_false(gyro_ctl_running(s.r.ctl));
    slow_end(&s);
}

static void bias_learned_at_standstill_only(void **state)
{
    gyro_bias_t b;
    gyro_bias_init(&b, 0.5, 10.0, 50, 0.1);
    int64_t t = 0;
    /* moving: nothing learned */
    for (int i = 0; i < 200; i++, t += 10000)
        assert_false(gyro_bias_feed(&b, 0.3, false, t, 0.01));
    assert_false(b.valid);
    /* still, but within the settle time: nothing yet */
    for (int i = 0; i < 40; i++, t += 10000)
        gyro_bias_feed(&b, 0.015 + (i % 2 ? 0.001 : -0.001), true, t, 0.01);
    assert_false(b.valid);
    for (int i = 0; i < 100; i++, t += 10000)
        gyro_bias_feed(&b, 0.015 + (i % 2 ? 0.001 : -0.001), true, t, 0.01);
    assert_true(b.valid);
    assert_true(fabs(b.bias - 0.015) < 1e-4);
    /* "still" but turning fast: someone pushes the robot; the bias does not move */
    for (int i = 0; i < 100; i++, t += 10000)
        assert_false(gyro_bias_feed(&b, 0.8, true, t, 0.01));
    assert_true(fabs(b.bias - 0.015) < 1e-4);
    /* slow drift is followed with the time constant */
    for (int i = 0; i < 3000; i++, t += 10000)
        gyro_bias_feed(&b, 0.025, true, t, 0.01);
    assert_true(fabs(b.bias - 0.025) < 0.001);
    assert_false(gyro_bias_feed(&b, NAN, true, t, 0.01));
}

int main(void)
{
#define T(x) cmocka_unit_test_setup_teardown(x, setup, teardown)
    const struct CMUnitTest tests[] = {
        T(configures_and_streams_samples),
        T(lost_samples_fault_and_timeout),
        T(saturation_is_flagged),
        T(malformed_frames_are_reported),
        cmocka_unit_test(normal_start_on_a_slow_bus_raises_no_fault),
        cmocka_unit_test(absent_gyro_reported_once_as_not_found),
        cmocka_unit_test(bias_learned_at_standstill_only),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
