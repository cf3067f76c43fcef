/* test_scanwait: laser scans wait, in order, for the odometry of their own instant. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include "adapters/common/scanwait.h"

/* What the handler saw: each scan's time and the newest odometry when it ran. */
static int64_t ran[64], odom_then[64];
static int nran;
static posebuf_t odom;

static void handler(marie_component_t *c, const marie_laser_scan_t *m)
{
    ran[nran] = m->utime;
    odom_then[nran] = posebuf_newest(&odom);
    nran++;
}

static float ranges[3] = { 1, 2, 3 };

static void scan(scanwait_t *w, int64_t t)
{
    marie_laser_scan_t m = { .utime = t, .nranges = 3, .ranges = ranges };
    scanwait_scan(w, NULL, &odom, &m, handler);
}

static void odometry(scanwait_t *w, int64_t t)
{
    posebuf_add(&odom, t, (const double[3]){ 0, 0, 0 });
    scanwait_odometry(w, NULL, t, handler);
}

static int setup(void **state)
{
    nran = 0;
    posebuf_clear(&odom);
    return 0;
}

static void a_covered_scan_runs_at_once_and_one_without_odometry_never(void **state)
{
    scanwait_t w = { 0 };
    scan(&w, 100);                      /* no odometry yet: dropped */
    odometry(&w, 200);
    scan(&w, 150);
    assert_int_equal(nran, 1);
    assert_int_equal(ran[0], 150);
    assert_int_equal(scanwait_waiting(&w), 0);
    odometry(&w, 300);
    assert_int_equal(nran, 1);          /* the dropped one does not come back */
    scanwait_free(&w);
}

/* Three scans ahead of the odometry (it is one hop further from the devices): each runs once
 * odometry at or after its time is there, oldest first, never with older odometry. */
static void scans_ahead_of_odometry_wait_in_order(void **state)
{
    scanwait_t w = { 0 };
    odometry(&w, 1000);
    scan(&w, 1032);
    scan(&w, 1132);
    scan(&w, 1232);
    assert_int_equal(nran, 0);
    assert_int_equal(scanwait_waiting(&w), 3);
    odometry(&w, 1060);
    assert_int_equal(nran, 1);
    odometry(&w, 1260);
    assert_int_equal(nran, 3);
    for (int i = 0; i < 3; i++) {
        assert_int_equal(ran[i], 1032 + 100 * i);
        assert_true(odom_then[i] >= ran[i]);
    }
    scanwait_free(&w);
}

/* A scan the odometry already covers runs after the older ones still waiting. */
static void a_covered_scan_runs_after_the_waiting_ones(void **state)
{
    scanwait_t w = { 0 };
    odometry(&w, 1000);
    scan(&w, 1100);
    scan(&w, 1200);
    posebuf_add(&odom, 1300, (const double[3]){ 0, 0, 0 });   /* odometry added, not yet told */
    scan(&w, 1250);
    assert_int_equal(nran, 3);
    assert_true(ran[0] == 1100 && ran[1] == 1200 && ran[2] == 1250);
    scanwait_free(&w);
}

/* At most SCANWAIT_CAP wait: past that the oldest is dropped, never run with older odometry. */
static void past_the_bound_the_oldest_is_dropped(void **state)
{
    scanwait_t w = { 0 };
    odometry(&w, 0);
    for (int i = 1; i <= SCANWAIT_CAP + 2; i++)
        scan(&w, 100 * i);
    assert_int_equal(nran, 0);
    assert_int_equal(scanwait_waiting(&w), SCANWAIT_CAP);
    odometry(&w, 100000);
    assert_int_equal(nran, SCANWAIT_CAP);
    for (int i = 0; i < nran; i++) {
        assert_int_equal(ran[i], 100 * (i + 3));
        assert_true(odom_then[i] >= ran[i]);
    }
    scanwait_free(&w);
}

/* A scan stamped at or before the newest waiting one (a driver that stamped two telegrams
 * alike) is dropped; dropping the queue (the odometry frame changed) forgets the waiting ones. */
static void out_of_order_scans_and_a_dropped_queue_never_run(void **state)
{
    scanwait_t w = { 0 };
    odometry(&w, 0);
    scan(&w, 100);
    scan(&w, 100);
    scan(&w, 50);
    assert_int_equal(scanwait_waiting(&w), 1);
    scan(&w, 200);
    scanwait_drop(&w);
    odometry(&w, 1000);
    assert_int_equal(nran, 0);
    scan(&w, 300);                      /* and it works on afterwards */
    assert_int_equal(nran, 1);
    scanwait_free(&w);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(a_covered_scan_runs_at_once_and_one_without_odometry_never, setup),
        cmocka_unit_test_setup(scans_ahead_of_odometry_wait_in_order, setup),
        cmocka_unit_test_setup(a_covered_scan_runs_after_the_waiting_ones, setup),
        cmocka_unit_test_setup(past_the_bound_the_oldest_is_dropped, setup),
        cmocka_unit_test_setup(out_of_order_scans_and_a_dropped_queue_never_run, setup),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
