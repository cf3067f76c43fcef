/* test_carmen: the CARMEN reader behind `marie log import carmen`: the robot's own odometry out of
 * a GMapping-corrected log, no-return codes as REP 117's +inf, times, laser geometry, the newer
 * laser lines, and malformed lines reported by file:line:col. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "tools/log/carmen.h"

#define MAXMSG 64

typedef struct {
    carmen_msg_t m[MAXMSG];
    float ranges[MAXMSG][8];
    int n;
} got_t;

static void on_msg(void *user, const carmen_msg_t *m)
{
    got_t *g = user;
    assert_true(g->n < MAXMSG);
    g->m[g->n] = *m;
    if (m->kind == CARMEN_LASER) {
        assert_true(m->n <= 8);
        memcpy(g->ranges[g->n], m->ranges, sizeof(float) * (size_t)m->n);
        g->m[g->n].ranges = g->ranges[g->n];
    }
    g->n++;
}

/* Both passes over the lines; the reader's statistics in *st, errors in errs. */
static void run(const char *const *lines, int n, got_t *g, carmen_stats_t *st, marie_errors_t *errs, int max_errors)
{
    carmen_opts_t o = CARMEN_OPTS_DEFAULT;
    memset(g, 0, sizeof *g);
    carmen_t *c = carmen_create(&o, on_msg, g);
    assert_non_null(c);
    for (int i = 0; i < n; i++)
        carmen_survey(c, lines[i]);
    carmen_begin(c);
    for (int i = 0; i < n; i++)
        carmen_line(c, lines[i], "t.log", errs, max_errors);
    *st = *carmen_stats(c);
    carmen_destroy(c);
}

static const carmen_msg_t *nth(const got_t *g, carmen_kind_t k, int i)
{
    for (int j = 0; j < g->n; j++)
        if (g->m[j].kind == k && i-- == 0)
            return &g->m[j];
    fail_msg("no message %d of kind %d", i, k);
    return NULL;
}

/* GMapping's corrected logs write, after each scan, an ODOM line at its own estimate of the scan's
 * pose and go on from there: the robot's motion is what the lines within each stretch say. */
static void test_odometry_chained_across_rebasing(void **state)
{
    const char *lines[] = {
        "ODOM 0 0 0 0 0 0 1.0 h 1.0",
        "ODOM 1 0 0 0.5 0 0 2.0 h 2.0",
        "FLASER 3 1 2 3 5.0 5.0 1.0 5.0 5.0 1.0 2.0 h 2.0",
        "ODOM 5.0 5.0 1.0 0 0 0 0 h 0",         /* the re-basing: GMapping's pose, no motion */
        "NEFF 30",
        "ODOM 5.540302 5.841471 1.0 0.5 0 0 3.0 h 3.0",    /* 1 m ahead of the estimate */
        "FLASER 3 1 2 3 6 6 1.1 6 6 1.1 3.0 h 3.0",
    };
    got_t g;
    carmen_stats_t st;
    run(lines, 7, &g, &st, NULL, 0);
    assert_int_equal(st.scans, 2);
    assert_int_equal(st.rebased, 1);
    assert_int_equal(st.odometry, 3);
    const carmen_msg_t *o = nth(&g, CARMEN_ODOMETRY, 2);
    /* 1 m further along x from (1, 0, 0), never at GMapping's (5, 5). */
    assert_true(fabs(o->pose[0] - 2.0) < 1e-5 && fabs(o->pose[1]) < 1e-5 && fabs(o->pose[2]) < 1e-6);
    assert_true(fabs(o->distance - 2.0) < 1e-5);
    const carmen_msg_t *l = nth(&g, CARMEN_LASER, 1);
    assert_true(l->has_reference);
    assert_true(l->reference[0] == 6 && l->reference[1] == 6 && fabs(l->reference[2] - 1.1) < 1e-12);
    assert_int_equal(l->utime, 3000001);       /* just after the odometry of its instant */
    assert_true(st.log_times);
}

static void test_no_return_code_is_infinity(void **state)
{
    /* 81.91 m (an LMS200's "nothing seen" in its 80 m mode) is most of the longest readings. */
    const char *lines[] = {
        "ODOM 0 0 0 0 0 0 1.0 h 1.0",
        "FLASER 4 81.91 2 0 81.91 0 0 0 0 0 0 1.0 h 1.0",
        "ODOM 0 0 0 0 0 0 2.0 h 2.0",
        "FLASER 4 81.91 3 81.91 4 0 0 0 0 0 0 2.0 h 2.0",
    };
    got_t g;
    carmen_stats_t st;
    run(lines, 4, &g, &st, NULL, 0);
    const carmen_msg_t *a = nth(&g, CARMEN_LASER, 0), *b = nth(&g, CARMEN_LASER, 1);
    assert_true(isinf(a->ranges[0]) && a->ranges[0] > 0);
    assert_true(a->ranges[1] == 2);
    assert_true(isnan(a->ranges[2]));          /* a zero is no reading */
    assert_true(b->ranges[1] == 3 && b->ranges[3] == 4);
    assert_true(fabs(st.no_return_m - 81.91) < 0.011);
    assert_true(fabs(a->range_max - st.no_return_m) < 1e-6);
    assert_int_equal(st.no_returns, 4);
    assert_int_equal(st.no_readings, 1);
    /* FLASER's beams span 180 degrees: 4 beams at pi/4 from -pi/2. */
    assert_true(fabs(a->angle_min + M_PI / 2) < 1e-9 && fabs(a->angle_increment - M_PI / 4) < 1e-9);
}

/* A log whose clock stands still gets times of its own, spaced by the odometry's motion; one
 * whose clock jumps back now and then keeps its times in the file's order. */
static void test_times(void **state)
{
    const char *still[] = {
        "ODOM 0 0 0 0 0 0 5 h 5",
        "FLASER 2 1 2 0 0 0 0 0 0 5 h 5",
        "ODOM 3 0 0 0 0 0 5 h 5",          /* 3 m: at 0.5 m/s, 6 s */
        "FLASER 2 1 2 3 0 0 3 0 0 5 h 5",
    };
    got_t g;
    carmen_stats_t st;
    run(still, 4, &g, &st, NULL, 0);
    assert_false(st.log_times);
    assert_int_equal(nth(&g, CARMEN_LASER, 0)->utime, nth(&g, CARMEN_ODOMETRY, 0)->utime);
    int64_t dt = nth(&g, CARMEN_ODOMETRY, 1)->utime - nth(&g, CARMEN_ODOMETRY, 0)->utime;
    assert_true(dt >= 6000000 && dt < 6100000);
    assert_int_equal(nth(&g, CARMEN_LASER, 1)->utime, nth(&g, CARMEN_ODOMETRY, 1)->utime);

    const char *jumpy[] = {
        "ODOM 0 0 0 0 0 0 10 h 10", "FLASER 2 1 2 0 0 0 0 0 0 10 h 10",
        "ODOM 0.1 0 0 0 0 0 11 h 11", "FLASER 2 1 2 0.1 0 0 0.1 0 0 11 h 11",
        "ODOM 0.2 0 0 0 0 0 10.5 h 10.5", "FLASER 2 1 2 0.2 0 0 0.2 0 0 12 h 12",
    };
    run(jumpy, 6, &g, &st, NULL, 0);
    assert_true(st.log_times);
    assert_int_equal(st.times_moved, 1);
    for (int i = 1; i < g.n; i++)
        assert_true(g.m[i].utime >= g.m[i - 1].utime);
    assert_int_equal(nth(&g, CARMEN_ODOMETRY, 2)->utime, 11000002);
}

static void test_robotlaser_and_rawlaser(void **state)
{
    const char *lines[] = {
        "ODOM 0 0 0 0 0 0 1.0 h 1.0",
        /* type start fov res maxrange accuracy remission n r... nrem laser_pose robot_pose tv rv fwd side turn t */
        "ROBOTLASER1 0 -1.5 3.0 0.75 8.0 0.01 0 5 1 2 8.0 0 0.5 0 0.4 0 0 0.3 0 0 0 0 0 0 0 1.5 h 1.5",
        "RAWLASER1 0 -1.0 2.0 1.0 4.0 0.01 0 3 1 5 2 0 2.0 h 2.0",
        "ODOM 0 0 0 0 0 0 2.5 h 2.5",
    };
    got_t g;
    carmen_stats_t st;
    run(lines, 4, &g, &st, NULL, 0);
    assert_int_equal(st.scans, 2);
    const carmen_msg_t *a = nth(&g, CARMEN_LASER, 0), *b = nth(&g, CARMEN_LASER, 1);
    assert_int_equal(a->n, 5);
    assert_true(a->angle_min == -1.5 && a->angle_increment == 0.75 && a->range_max == 8.0);
    assert_true(isinf(a->ranges[2]) && isnan(a->ranges[3]) && a->ranges[4] == 0.5f);
    assert_true(a->has_reference && a->reference[0] == 0.3);
    assert_int_equal(a->utime, 1500000);
    assert_false(b->has_reference);
    assert_true(isinf(b->ranges[1]) && b->ranges[2] == 2);
}

static void test_malformed_lines_reported(void **state)
{
    const char *lines[] = {
        "ODOM 0 0 zero 0 0 0 1.0 h 1.0",
        "FLASER 3 1 2",
        "FLASER -4 1 2 3",
        "FLASER 2 1 x 0 0 0 0 0 0 2 h 2",
        "ODOM 0 0 0 0 0 0 2.5 h 2.5",
        "FLASER 2 1 1 0 0 0 0 0 0 3 h 3",
        "GPS whatever",
    };
    got_t g;
    carmen_stats_t st;
    marie_errors_t errs = { 0 };
    run(lines, 7, &g, &st, &errs, 3);
    assert_int_equal(st.bad, 4);
    assert_int_equal(st.scans, 1);
    assert_int_equal(st.skipped, 1);
    assert_int_equal((int)errs.n, 3);      /* at most max_errors messages, all counted */
    assert_string_equal(errs.msgs[0], "t.log:1:10: ODOM line: expected a number");
    assert_non_null(strstr(errs.msgs[2], "t.log:3:8:"));
    marie_errors_clear(&errs);
    carmen_opts_t bad = CARMEN_OPTS_DEFAULT;
    bad.step = 0;
    assert_null(carmen_create(&bad, on_msg, NULL));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_odometry_chained_across_rebasing),
        cmocka_unit_test(test_no_return_code_is_infinity),
        cmocka_unit_test(test_times),
        cmocka_unit_test(test_robotlaser_and_rawlaser),
        cmocka_unit_test(test_malformed_lines_reported),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
