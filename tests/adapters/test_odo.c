/* test_odo: encoder distance and gyro heading integrate to the right pose; bad input is refused. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <math.h>
#include <errno.h>
#include <cmocka.h>

#include "adapters/odometry/odo.h"
#include "tests/fails.h"

#define TPR 4096
static const double R = 0.1, T = 0.4;

/* Ticks for a wheel that rolled `m` metres. */
static int32_t ticks(double m)
{
    return (int32_t)lround(m / (2 * M_PI * R) * TPR);
}

static void test_straight_line(void **state)
{
    odo_params_t p; odo_params_default(&p);
    odo_t o; odo_init(&o, &p);
    assert_int_equal(odo_encoders(&o, 1000000, 0, 0, TPR), 0);
    for (int i = 1; i <= 20; i++) {
        odo_gyro(&o, 1000000 + i * 100000, 0.0, 0);
        assert_int_equal(odo_encoders(&o, 1000000 + i * 100000, ticks(0.05 * i), ticks(0.05 * i), TPR), 1);
    }
    assert_true(fabs(o.pose[0] - 1.0) < 0.002);
    assert_true(fabs(o.pose[1]) < 1e-9 && fabs(o.pose[2]) < 1e-9);
    assert_true(fabs(o.v - 0.5) < 0.01);
    assert_true(fabs(o.distance - 1.0) < 0.002);
    assert_true(o.cov[0] > 0 && o.cov[4] > 0);
}

static void test_gyro_heading_beats_slipping_wheel(void **state)
{
    /* Drive a quarter circle of radius 1 m at 0.5 m/s; the left wheel slips 10% (reads less).
     * The gyro reports the true rate, so the heading ends at pi/2 regardless. */
    odo_params_t p; odo_params_default(&p);
    odo_t o; odo_init(&o, &p);
    double w = 0.5, v = 0.5, tend = (M_PI / 2) / w;
    double l = 0, r = 0;
    int n = (int)round(tend / 0.01);
    odo_gyro(&o, 0, w, 0);
    odo_encoders(&o, 0, 0, 0, TPR);
    for (int i = 1; i <= n; i++) {
        int64_t t = (int64_t)i * 10000;
        l += (v - w * T / 2) * 0.01 * 0.9;
        r += (v + w * T / 2) * 0.01;
        odo_gyro(&o, t, w, 0);
        odo_encoders(&o, t, ticks(l), ticks(r), TPR);
    }
    printf("arc end: (%.3f, %.3f, %.3f)\n", o.pose[0], o.pose[1], o.pose[2]);
    assert_true(fabs(o.pose[2] - M_PI / 2) < 0.01);
    assert_true(fabs(o.pose[0] - 1.0) < 0.1 && fabs(o.pose[1] - 1.0) < 0.1);
    assert_int_equal(o.gyro_steps, o.steps);
}

static void test_encoder_heading_without_gyro(void **state)
{
    odo_params_t p; odo_params_default(&p);
    odo_t o; odo_init(&o, &p);
    odo_encoders(&o, 0, 0, 0, TPR);
    /* Turn on the spot by pi/2: each wheel rolls T/2 * pi/2 in opposite directions. */
    double arc = T / 2 * M_PI / 2;
    for (int i = 1; i <= 10; i++)
        odo_encoders(&o, i * 100000, ticks(-arc * i / 10), ticks(arc * i / 10), TPR);
    assert_true(fabs(o.pose[2] - M_PI / 2) < 0.01);
    assert_true(fabs(o.pose[0]) < 1e-3 && fabs(o.pose[1]) < 1e-3);
    assert_int_equal(o.gyro_steps, 0);
    assert_true(o.cov[8] > 0);
    /* A faulty gyro is ignored too. */
    odo_gyro(&o, 1100000, 5.0, 3);
    odo_encoders(&o, 1100000, ticks(-arc), ticks(arc), TPR);
    assert_true(fabs(o.pose[2] - M_PI / 2) < 0.01);
}

static void test_wrap_and_glitches(void **state)
{
    odo_params_t p; odo_params_default(&p);
    odo_t o; odo_init(&o, &p);
    int32_t start = INT32_MAX - 100;
    odo_encoders(&o, 0, start, start, TPR);
    /* 200 ticks forward wraps the counters: still 200 ticks. */
    assert_int_equal(odo_encoders(&o, 100000, (int32_t)((uint32_t)start + 200), (int32_t)((uint32_t)start + 200), TPR), 1);
    assert_true(fabs(o.pose[0] - 200.0 / TPR * 2 * M_PI * R) < 1e-9);
    double x = o.pose[0];
    /* A jump of a million ticks in 0.1 s is a glitch: refused, pose unchanged, next re-anchors. */
    assert_fails(odo_encoders(&o, 200000, 1000000, 1000000, TPR), EINVAL);
    assert_true(o.pose[0] == x);
    assert_int_equal(odo_encoders(&o, 300000, 1000000 + 41, 1000000 + 41, TPR), 1);
    assert_true(o.pose[0] > x);
    /* Time going backwards, zero ticks per rev, NaN gyro: refused. */
    assert_fails(odo_encoders(&o, 100, 0, 0, TPR), EINVAL);
    assert_fails(odo_encoders(&o, 400000, 0, 0, 0), EINVAL);
    assert_fails(odo_gyro(&o, 400000, NAN, 0), EINVAL);
    assert_int_equal(o.glitches, 1);
}

/* A drive that faulted (or whose driver restarted) for 4 s reads far from where it was: that is
 * no motion. Before, 4 s allowed enough ticks for a 22 m jump. */
static void test_encoder_outage_is_a_new_reference(void **state)
{
    odo_params_t p; odo_params_default(&p);
    odo_t o; odo_init(&o, &p);
    odo_encoders(&o, 0, 0, 0, TPR);
    for (int i = 1; i <= 10; i++)
        odo_encoders(&o, i * 100000, ticks(0.05 * i), ticks(0.05 * i), TPR);
    double x = o.pose[0], dist = o.distance;
    odo_encoders_lost(&o);
    assert_int_equal(odo_encoders(&o, 5000000, 153175, 153175, TPR), 0);
    assert_true(fabs(o.pose[0] - x) < 1e-12 && fabs(o.distance - dist) < 1e-12);
    assert_int_equal(o.utime, 5000000);
    /* and motion after it counts again */
    assert_int_equal(odo_encoders(&o, 5100000, 153175 + ticks(0.05), 153175 + ticks(0.05), TPR), 1);
    assert_true(fabs(o.pose[0] - x - 0.05) < 0.002);
}

static void test_covariance_grows_with_distance(void **state)
{
    odo_params_t p; odo_params_default(&p);
    odo_t o; odo_init(&o, &p);
    odo_encoders(&o, 0, 0, 0, TPR);
    double prev = 0;
    for (int i = 1; i <= 50; i++) {
        odo_gyro(&o, i * 100000, 0.1, 0);
        odo_encoders(&o, i * 100000, ticks(0.05 * i), ticks(0.05 * i), TPR);
        assert_true(o.cov[4] >= prev);
        prev = o.cov[4];
    }
    /* Heading uncertainty feeds the lateral one: it grows faster than linearly. */
    assert_true(o.cov[4] > o.cov[8]);
    assert_true(o.cov[1] == o.cov[3]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_straight_line),
        cmocka_unit_test(test_gyro_heading_beats_slipping_wheel),
        cmocka_unit_test(test_encoder_heading_without_gyro),
        cmocka_unit_test(test_wrap_and_glitches),
        cmocka_unit_test(test_encoder_outage_is_a_new_reference),
        cmocka_unit_test(test_covariance_grows_with_distance),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
