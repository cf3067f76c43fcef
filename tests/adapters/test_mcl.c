/* test_mcl: the particle filter tracks and finds a simulated robot in an office map. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "adapters/localizer/mcl.h"
#include "adapters/localizer/seek.h"
#include "tests/adapters/simworld.h"

#define NB 181
#define RANGE_MAX 8.0

typedef struct {
    double rms, max, final;
    int steps;
} run_result_t;

/* The robot lives in the frame of map m; the filter's map frame is that frame moved by xf
 * (x, y, yaw): how a map.yaml's origin places its image. */
static const double no_xf[3] = { 0, 0, 0 };

static void to_filter_frame(const double xf[3], const double p[3], double out[3])
{
    out[0] = xf[0] + cos(xf[2]) * p[0] - sin(xf[2]) * p[1];
    out[1] = xf[1] + sin(xf[2]) * p[0] + cos(xf[2]) * p[1];
    out[2] = p[2] + xf[2];
}

/* Drive along the corridor, weaving, turning around at both ends; localize at 10 Hz. */
static run_result_t run_in(occmap_t *m, const double xf[3], mcl_t *f, simrobot_t *r, double seconds, double settle_s)
{
    float ranges[NB];
    double H = m->height * m->resolution, W = m->width * m->resolution;
    double dir = 1, sum2 = 0, maxe = 0, e = 0;
    int n = 0;
    const double dt = 0.1;
    for (int step = 0; step < (int)(seconds / dt); step++) {
        double t = step * dt;
        double v = 0.6, w;
        double want = dir > 0 ? 0.0 : M_PI;
        double yerr = (H / 2 + 0.4 * sin(t * 0.5)) - r->truth[1];
        double herr = atan2(sin(want + dir * 0.8 * yerr - r->truth[2]), cos(want + dir * 0.8 * yerr - r->truth[2]));
        w = 1.5 * herr;
        if (fabs(herr) > 0.6)
            v = 0.05;
        if ((dir > 0 && r->truth[0] > W - 2.0) || (dir < 0 && r->truth[0] < 2.0))
            dir = -dir;
        sim_move(r, m, v, w, dt);
        sim_scan(r, m, ranges, NB, RANGE_MAX, 0.02, 0.03);
        mcl_scan_t scan = { ranges, NB, -M_PI / 2, M_PI / 180, 0.05, RANGE_MAX };
        mcl_step(f, r->odom, &scan, false);
        double est[3], cov[9];
        mcl_estimate(f, est, cov);
        double truth[3];
        to_filter_frame(xf, r->truth, truth);
        e = hypot(est[0] - truth[0], est[1] - truth[1]);
        if (t >= settle_s) {
            sum2 += e * e;
            if (e > maxe)
                maxe = e;
            n++;
        }
    }
    run_result_t res = { n ? sqrt(sum2 / n) : 0, maxe, e, n };
    return res;
}

static run_result_t run(occmap_t *m, mcl_t *f, simrobot_t *r, double seconds, double settle_s)
{
    return run_in(m, no_xf, f, r, seconds, settle_s);
}

static simrobot_t robot_at(double x, double y, double th, uint64_t seed)
{
    simrobot_t r = { { x, y, th }, { 0, 0, 0 }, 1.03, 0.01, 0.02, 0.02, { seed } };
    /* Odometry starts at its own origin, unrelated to the map frame. */
    return r;
}

static void test_tracking_from_known_pose(void **state)
{
    occmap_t *m = occmap_make_office(16, 12, 0.05, 7);
    assert_non_null(m);
    mcl_params_t p;
    mcl_params_default(&p);
    p.particles_max = 1500;
    mcl_t *f = mcl_create(m, &p, 42);
    assert_non_null(f);
    simrobot_t r = robot_at(2.0, 6.0, 0.1, 99);
    double start[3] = { 2.2, 5.9, 0.0 }, sig[3] = { 0.2, 0.2, 0.1 };  /* 20 cm, 0.1 rad off */
    mcl_init_pose(f, start, sig);
    run_result_t res = run(m, f, &r, 90, 2.0);
    printf("tracking: rms %.3f m, max %.3f m over %d steps, %d particles\n", res.rms, res.max, res.steps, mcl_count(f));
    assert_true(res.rms < 0.10);
    assert_true(res.max < 0.30);
    /* KLD shrinks the set once the pose is known. */
    assert_true(mcl_count(f) < 1500);
    double est[3], cov[9];
    mcl_estimate(f, est, cov);
    assert_true(cov[0] > 0 && cov[4] > 0 && cov[8] > 0);
    assert_true(cov[0] < 0.05 && cov[4] < 0.05);
    mcl_destroy(f);
    occmap_destroy(m);
}

/* The office saved as a map_server map whose origin has a yaw, loaded by the map library: the
 * filter tracks the robot on it as well as on the unrotated map. */
static void test_tracking_on_rotated_map(void **state)
{
    occmap_t *src = occmap_make_office(16, 12, 0.05, 7);
    char dir[] = "/tmp/marie-test-mcl.XXXXXX", pgm[64], yaml[64];
    assert_non_null(mkdtemp(dir));
    snprintf(pgm, sizeof pgm, "%s/office.pgm", dir);
    snprintf(yaml, sizeof yaml, "%s/office.yaml", dir);
    FILE *f = fopen(pgm, "wb");
    fprintf(f, "P5\n%d %d\n255\n", src->width, src->height);
    for (int j = src->height - 1; j >= 0; j--)
        for (int i = 0; i < src->width; i++)
            fputc(occmap_get(src, i, j) == OCCMAP_OCCUPIED ? 0 : 254, f);
    fclose(f);
    const double xf[3] = { -3.0, 1.5, 0.3 };
    f = fopen(yaml, "w");
    fprintf(f, "image: office.pgm\nresolution: 0.05\norigin: [%g, %g, %g]\n", xf[0], xf[1], xf[2]);
    fclose(f);
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load(yaml, &errs);
    assert_non_null(m);
    unlink(pgm);
    unlink(yaml);
    rmdir(dir);

    mcl_params_t p;
    mcl_params_default(&p);
    p.particles_max = 1500;
    mcl_t *filter = mcl_create(m, &p, 42);
    assert_non_null(filter);
    simrobot_t r = robot_at(2.0, 6.0, 0.1, 99);
    double truth[3], sig[3] = { 0.2, 0.2, 0.1 };
    to_filter_frame(xf, r.truth, truth);
    double start[3] = { truth[0] + 0.2, truth[1] - 0.1, truth[2] - 0.1 };
    mcl_init_pose(filter, start, sig);
    run_result_t res = run_in(src, xf, filter, &r, 90, 2.0);
    printf("tracking on a map rotated by %.1f rad: rms %.3f m, max %.3f m\n", xf[2], res.rms, res.max);
    assert_true(res.rms < 0.10);
    assert_true(res.max < 0.30);
    mcl_destroy(filter);
    occmap_destroy(m);
    occmap_destroy(src);
}

static void test_global_localization(void **state)
{
    occmap_t *m = occmap_make_office(16, 12, 0.05, 7);
    mcl_params_t p;
    mcl_params_default(&p);
    p.particles_max = 6000;
    p.particles_min = 300;
    mcl_t *f = mcl_create(m, &p, 4242);
    assert_non_null(f);
    mcl_init_global(f);
    simrobot_t r = robot_at(3.0, 6.2, 0.0, 1234);
    /* The filter alone, from a uniform cloud: its random particles are drawn near the estimate
     * (inject_radius), so it walks to the truth rather than jumps (the localizer's search jumps). */
    run_result_t res = run(m, f, &r, 150, 100.0);
    printf("global: rms %.3f m after 100 s, max %.3f m, final %.3f m, %d particles\n", res.rms, res.max, res.final, mcl_count(f));
    assert_true(res.rms < 0.15);
    assert_true(res.final < 0.2);
    mcl_destroy(f);
    occmap_destroy(m);
}

static void test_recovers_from_wrong_start(void **state)
{
    /* Told the wrong place (4 m off): random particles near the estimate let it walk to the truth. */
    occmap_t *m = occmap_make_office(16, 12, 0.05, 7);
    mcl_params_t p;
    mcl_params_default(&p);
    p.particles_max = 4000;
    mcl_t *f = mcl_create(m, &p, 77);
    simrobot_t r = robot_at(4.0, 6.0, 0.0, 555);
    double start[3] = { 8.0, 6.0, 0.0 }, sig[3] = { 0.1, 0.1, 0.05 };
    mcl_init_pose(f, start, sig);
    run_result_t res = run(m, f, &r, 160, 120.0);
    printf("recovery: rms %.3f m over the last 40 s, final %.3f m\n", res.rms, res.final);
    assert_true(res.rms < 0.2);
    mcl_destroy(f);
    occmap_destroy(m);
}

/* The robot in a 5 cm world, the filter on a 20 cm map of it: the beams end on the walls' faces,
 * up to half a coarse cell in front of the coarse cells' centres. It tracks, and the scan fits the
 * map at the estimate (the mean per-beam likelihood stays above 0.45: measured from the cells'
 * centres, a 0.2 m map read 0.36 at best, and wrong poses that fit as well took the robot). */
static void test_tracking_on_a_coarse_map(void **state)
{
    occmap_t *world = occmap_make_office(16, 12, 0.05, 7), *map = occmap_coarsen(world, 0.2);
    mcl_params_t p;
    mcl_params_default(&p);
    p.particles_max = 1500;
    mcl_t *f = mcl_create(map, &p, 42);
    assert_non_null(f);
    simrobot_t r = robot_at(2.0, 6.0, 0.1, 99);
    double start[3] = { 2.1, 5.9, 0.05 }, sig[3] = { 0.1, 0.1, 0.05 };
    mcl_init_pose(f, start, sig);
    double least = INFINITY, sum = 0;
    int n = 0;
    run_result_t res = { 0 };
    for (int leg = 0; leg < 180; leg++) {       /* 90 s, the fit read every 0.5 s */
        res = run(world, f, &r, 0.5, 0);
        if (leg >= 20) {
            least = fmin(least, mcl_likelihood(f));
            sum += res.rms * res.rms * res.steps;
            n += res.steps;
        }
    }
    printf("0.2 m map: rms %.3f m, final %.3f m, least fit %.2f\n", sqrt(sum / n), res.final, least);
    assert_true(sqrt(sum / n) < 0.12);
    assert_true(least > 0.45);
    mcl_destroy(f);
    occmap_destroy(map);
    occmap_destroy(world);
}

/* A lost robot's search (seek.h) driving the simulated robot in the office of sim/worlds: where a
 * turn on the spot tells the place, it is found there; in the cross corridor, whose other half is
 * its mirror image for metres around, it is found at its true place (by driving on) or gives up,
 * never found elsewhere; in a bare room, the same turned by half a turn, it gives up and says
 * why. */
static seek_event_t seek_from(const occmap_t *m, double x, double y, double th, double *err, char *why, size_t len)
{
    mcl_params_t p;
    mcl_params_default(&p);
    mcl_t *f = mcl_create(m, &p, 1);
    simrobot_t r = { { x, y, th }, { 0, 0, 0 }, 1.01, 0.0005, 0.01, 0.005, { 5 } };
    seek_params_t sp = SEEK_PARAMS_DEFAULTS;
    seek_t s;
    assert_int_equal(seek_init(&s, &sp, (const double[3]){ 0, 0, 0 }), 0);
    seek_begin(&s, r.odom, 0);
    float ranges[NB];
    double v = 0, w = 0;
    seek_out_t o = { 0 };
    for (int k = 0; k < 4000 && o.event != SEEK_FOUND && o.event != SEEK_GAVE_UP; k++) {
        sim_move(&r, m, v, w, 0.1);
        sim_scan(&r, m, ranges, NB, RANGE_MAX, 0.01, 0.01);
        mcl_scan_t scan = { ranges, NB, -M_PI / 2, M_PI / 180, 0.05, RANGE_MAX };
        seek_step(&s, f, r.odom, &scan, k * 0.1, &o);
        if (o.update_filter)
            mcl_step(f, r.odom, &scan, true);
        v = o.move ? o.v : 0;
        w = o.move ? o.omega : 0;
    }
    *err = hypot(o.best_now[0] - r.truth[0], o.best_now[1] - r.truth[1]);
    snprintf(why, len, "%s", o.why);
    printf("search from (%.1f, %.1f): %s after %lld searches, error %.2f m %s\n", x, y,
           o.event == SEEK_FOUND ? "found" : o.event == SEEK_GAVE_UP ? "gave up" : "nothing", (long long)s.searches,
           *err, why);
    seek_free(&s);
    mcl_destroy(f);
    return o.event;
}

static void test_lost_robot_is_found_or_asks(void **state)
{
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load("sim/worlds/office.yaml", &errs);
    assert_non_null(m);
    double err;
    char why[200];
    assert_int_equal(seek_from(m, 12.0, 25.0, -1.0, &err, why, sizeof why), SEEK_FOUND);
    assert_true(err < 0.2);
    assert_int_equal(seek_from(m, 35.0, 5.0, 2.0, &err, why, sizeof why), SEEK_FOUND);
    assert_true(err < 0.2);
    if (seek_from(m, 20.0, 3.0, 1.3, &err, why, sizeof why) == SEEK_FOUND)
        assert_true(err < 0.2);
    occmap_destroy(m);
    m = occmap_create(160, 100, 0.05, 0, 0);        /* 8 x 5 m, walls 0.1 m thick */
    occmap_fill_rect(m, 0, 0, 8, 0.1, OCCMAP_OCCUPIED);
    occmap_fill_rect(m, 0, 4.9, 8, 5, OCCMAP_OCCUPIED);
    occmap_fill_rect(m, 0, 0, 0.1, 5, OCCMAP_OCCUPIED);
    occmap_fill_rect(m, 7.9, 0, 8, 5, OCCMAP_OCCUPIED);
    assert_int_equal(seek_from(m, 3.0, 2.0, 0.4, &err, why, sizeof why), SEEK_GAVE_UP);
    assert_non_null(strstr(why, "several places fit alike"));
    occmap_destroy(m);
}

static void test_rejects_bad_params(void **state)
{
    occmap_t *m = occmap_create(10, 10, 0.1, 0, 0);
    mcl_params_t p;
    mcl_params_default(&p);
    p.particles_min = 5000;
    p.particles_max = 100;
    assert_null(mcl_create(m, &p, 1));
    mcl_params_default(&p);
    p.sigma_hit = 0;
    assert_null(mcl_create(m, &p, 1));
    assert_null(mcl_create(NULL, &p, 1));
    mcl_destroy(NULL);
    occmap_destroy(m);
}

static void test_skips_update_when_still(void **state)
{
    occmap_t *m = occmap_make_office(16, 12, 0.05, 7);
    mcl_params_t p;
    mcl_params_default(&p);
    p.particles_max = 500;
    mcl_t *f = mcl_create(m, &p, 3);
    double pose[3] = { 3, 6, 0 }, sig[3] = { 0.1, 0.1, 0.1 }, odom[3] = { 0, 0, 0 };
    mcl_init_pose(f, pose, sig);
    float ranges[NB];
    simrobot_t r = robot_at(3, 6, 0, 9);
    sim_scan(&r, m, ranges, NB, RANGE_MAX, 0.0, 0.0);
    mcl_scan_t scan = { ranges, NB, -M_PI / 2, M_PI / 180, 0.05, RANGE_MAX };
    assert_int_equal(mcl_step(f, odom, &scan, false), 0);   /* first odometry only anchors */
    assert_int_equal(mcl_step(f, odom, &scan, false), 0);   /* not moved */
    assert_int_equal(mcl_step(f, odom, &scan, true), 1);    /* forced */
    odom[0] = 0.2;
    assert_int_equal(mcl_step(f, odom, &scan, false), 1);
    assert_int_equal(mcl_updates(f), 2);
    /* Garbage ranges (NaN, negative, beyond max) are ignored, not trusted. */
    for (int k = 0; k < NB; k++)
        ranges[k] = k % 3 == 0 ? NAN : k % 3 == 1 ? -1.0f : 1e9f;
    odom[0] = 0.4;
    assert_int_equal(mcl_step(f, odom, &scan, false), 1);
    double est[3], cov[9];
    mcl_estimate(f, est, cov);
    assert_true(isfinite(est[0]) && isfinite(est[1]) && isfinite(est[2]));
    mcl_destroy(f);
    occmap_destroy(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rejects_bad_params),
        cmocka_unit_test(test_skips_update_when_still),
        cmocka_unit_test(test_tracking_from_known_pose),
        cmocka_unit_test(test_tracking_on_rotated_map),
        cmocka_unit_test(test_tracking_on_a_coarse_map),
        cmocka_unit_test(test_lost_robot_is_found_or_asks),
        cmocka_unit_test(test_global_localization),
        cmocka_unit_test(test_recovers_from_wrong_start),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
