/* test_posebuf: the pose at a given time from buffered odometry, and SE(2) composition. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "adapters/common/posebuf.h"

#define NEAR(a, b) assert_true(fabs((a) - (b)) < 1e-9)

static void interpolates_between_samples(void **state)
{
    posebuf_t b;
    posebuf_clear(&b);
    double out[3];
    assert_false(posebuf_at(&b, 0, out));
    posebuf_add(&b, 1000000, (const double[3]){ 0, 0, 3.0 });
    posebuf_add(&b, 1100000, (const double[3]){ 1, 2, -3.0 });    /* heading wraps past pi */
    assert_true(posebuf_at(&b, 1050000, out));
    NEAR(out[0], 0.5);
    NEAR(out[1], 1.0);
    NEAR(fabs(out[2]), M_PI);        /* halfway the short way round, not through 0 */
    posebuf_at(&b, 0, out);           /* before the oldest: clamped */
    NEAR(out[2], 3.0);
    posebuf_at(&b, 2000000, out);     /* after the newest: clamped */
    NEAR(out[0], 1);
    assert_int_equal(posebuf_newest(&b), 1100000);
    assert_true(posebuf_covers(&b, 1000000, 0) && posebuf_covers(&b, 1150000, 50000));
    assert_false(posebuf_covers(&b, 999999, 0) || posebuf_covers(&b, 1150001, 50000));
}

static void keeps_the_newest_when_full(void **state)
{
    posebuf_t b;
    posebuf_clear(&b);
    for (int k = 0; k < POSEBUF_CAP + 10; k++)
        posebuf_add(&b, k * 100000, (const double[3]){ k, 0, 0 });
    assert_int_equal(b.n, POSEBUF_CAP);
    double out[3];
    posebuf_at(&b, 0, out);
    NEAR(out[0], 10);                 /* the oldest kept */
    posebuf_at(&b, (POSEBUF_CAP + 5) * 100000 + 50000, out);
    NEAR(out[0], POSEBUF_CAP + 5.5);
    assert_true(posebuf_last(&b, out));
    NEAR(out[0], POSEBUF_CAP + 9);
}

static void compose_and_between_are_inverse(void **state)
{
    const double a[3] = { 1.0, -2.0, 0.7 }, b[3] = { 0.3, 0.4, -2.9 };
    double ab[3], back[3];
    pose2d_compose(a, b, ab);
    pose2d_between(a, ab, back);
    NEAR(back[0], b[0]);
    NEAR(back[1], b[1]);
    NEAR(back[2], b[2]);
    /* A point 1 m ahead of a robot at heading pi/2 is 1 m up. */
    double r[3] = { 2, 3, M_PI / 2 }, ahead[3] = { 1, 0, 0 }, w[3];
    pose2d_compose(r, ahead, w);
    NEAR(w[0], 2);
    NEAR(w[1], 4);
}

/* A restarted odometry (distance from zero again), a replayed log (time back) or a jump no
 * robot makes is a new frame; driving on at 1 m/s is not. */
static void tells_a_new_odometry_frame(void **state)
{
    posebuf_t b;
    posebuf_clear(&b);
    marie_odometry_t m = { .utime = 2000000, .pose = { 2.0, 0, 0 }, .distance = 2.0 };
    double jump;
    assert_false(posebuf_frame_changed(&b, &m, 0, &jump));           /* nothing before */
    posebuf_add(&b, 2000000, (const double[3]){ 2.0, 0, 0 });
    m = (marie_odometry_t){ .utime = 2100000, .pose = { 2.1, 0, 0 }, .distance = 2.1 };
    assert_false(posebuf_frame_changed(&b, &m, 2.0, &jump));
    NEAR(jump, 0.1);
    m = (marie_odometry_t){ .utime = 2100000, .pose = { 0, 0, 0 }, .distance = 0 };
    assert_true(posebuf_frame_changed(&b, &m, 2.0, &jump));          /* restarted */
    m = (marie_odometry_t){ .utime = 1900000, .pose = { 2.0, 0, 0 }, .distance = 2.0 };
    assert_true(posebuf_frame_changed(&b, &m, 2.0, &jump));          /* time went back */
    m = (marie_odometry_t){ .utime = 2100000, .pose = { 3.5, 0, 0 }, .distance = 3.5 };
    assert_true(posebuf_frame_changed(&b, &m, 2.0, &jump));          /* 1.5 m in 0.1 s */
    NEAR(jump, 1.5);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(interpolates_between_samples),
        cmocka_unit_test(keeps_the_newest_when_full),
        cmocka_unit_test(compose_and_between_are_inverse),
        cmocka_unit_test(tells_a_new_odometry_frame),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
