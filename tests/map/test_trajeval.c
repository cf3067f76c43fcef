/* test_trajeval: ATE after the rigid alignment and relation errors over lengths of path, on
 * trajectories whose errors are known by construction. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <cmocka.h>

#include "map/trajeval.h"

#define N 200

/* A square of `side` steps walked in 0.2 m steps; the estimate is the same path seen from another
 * frame (rotated by th, shifted by dx, dy), its steps scaled by `scale`. */
static void walk(traj_pose_t *ref, traj_pose_t *est, double th, double dx, double dy, double scale, int side)
{
    double x = 0, y = 0, h = 0, ex = 0, ey = 0;
    for (int i = 0; i < N; i++) {
        if (i && i % side == 0)
            h += M_PI / 2;
        if (i) {
            x += 0.2 * cos(h), y += 0.2 * sin(h);
            ex += 0.2 * scale * cos(h), ey += 0.2 * scale * sin(h);
        }
        ref[i] = (traj_pose_t){ 1000000 * (int64_t)i, x, y, h };
        est[i] = (traj_pose_t){ 1000000 * (int64_t)i, dx + cos(th) * ex - sin(th) * ey, dy + sin(th) * ex + cos(th) * ey,
                                atan2(sin(h + th), cos(h + th)) };
    }
}

static void test_a_moved_copy_has_no_error(void **state)
{
    traj_pose_t ref[N], est[N];
    walk(ref, est, 0.7, 3, -2, 1.0, 50);
    trajeval_t e;
    const double d[2] = { 1, 5 };
    assert_int_equal(trajeval_run(est, ref, N, d, 2, &e), 0);
    assert_true(e.ate_rms < 1e-9 && e.ate_max < 1e-9);
    assert_true(fabs(e.align[2] + 0.7) < 1e-9);
    assert_true(e.rel[0].trans_mean < 1e-9 && e.rel[1].trans_mean < 1e-9);
    assert_int_equal(e.rel[0].n, N - 5);        /* every pose but the last 5 starts a 1 m relation */
    assert_true(fabs(e.path - 0.2 * (N - 1)) < 1e-9);
}

/* Steps 2 % too long along a straight 40 m: 2 cm over each metre, 10 cm over five, whatever frame
 * the estimate is in. */
static void test_relations_see_a_scale_error(void **state)
{
    traj_pose_t ref[N], est[N];
    walk(ref, est, -1.2, 50, 7, 1.02, N);
    trajeval_t e;
    const double d[2] = { 1, 5 };
    assert_int_equal(trajeval_run(est, ref, N, d, 2, &e), 0);
    assert_true(fabs(e.rel[0].trans_mean - 0.02) < 1e-3);
    assert_true(fabs(e.rel[1].trans_mean - 0.10) < 1e-3);
    assert_true(e.rel[0].rot_mean < 1e-9);
    /* 40 m drawn 2 % longer: after the best alignment the ends are 0.4 m off, the RMS 0.23 m. */
    assert_true(fabs(e.ate_max - 0.398) < 0.01);
    assert_true(fabs(e.ate_rms - 0.398 / sqrt(3)) < 0.01);
}

/* One pose 1 m off: ATE's RMS sees it, the alignment is hardly moved by it. */
static void test_ate_after_alignment(void **state)
{
    traj_pose_t ref[N], est[N];
    walk(ref, est, 0, 0, 0, 1.0, 50);
    est[120].x += 1.0;
    trajeval_t e;
    assert_int_equal(trajeval_run(est, ref, N, NULL, 0, &e), 0);
    assert_true(fabs(e.ate_rms - 1.0 / sqrt(N)) < 0.01);
    assert_true(e.ate_max > 0.98 && e.ate_max < 1.0);
    assert_int_equal(e.nrel, 0);
}

static void test_pairing(void **state)
{
    traj_pose_t ref[3] = { { 0, 0, 0, 0 }, { 1000, 1, 0, 0.2 }, { 5000000, 9, 9, 0 } };
    traj_pose_t est[4] = { { 0, 5, 5, 0 }, { 500, 6, 5, 0 }, { 1000, 7, 5, 0 }, { 3000000, 8, 5, 0 } };
    traj_pose_t pe[4], pr[4];
    /* 0 and 1000 exactly, 500 between them; 3 s lies in a gap of 5 s, longer than allowed. */
    size_t n = trajeval_pair(est, 4, ref, 3, 1000000, pe, pr);
    assert_int_equal(n, 3);
    assert_true(fabs(pr[1].x - 0.5) < 1e-12 && fabs(pr[1].th - 0.1) < 1e-12);
    assert_int_equal(pe[2].utime, 1000);
    trajeval_t e;
    assert_int_equal(trajeval_run(pe, pr, 1, NULL, 0, &e), -1);
    assert_int_equal(errno, EINVAL);
    const double bad = 0;
    assert_int_equal(trajeval_run(pe, pr, 3, &bad, 1, &e), -1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_a_moved_copy_has_no_error),
        cmocka_unit_test(test_relations_see_a_scale_error),
        cmocka_unit_test(test_ate_after_alignment),
        cmocka_unit_test(test_pairing),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
