/* test_sim_world: wall merging, and the physics and sensors
 * of the simulated robot against the known geometry of sim/worlds/test. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "map/occmap.h"
#include "sim/world.h"

static occmap_t *load(const char *path)
{
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load(path, &errs);
    if (!m)
        marie_errors_print(&errs, stderr);
    marie_errors_clear(&errs);
    return m;
}

/* Every cell not known free is in exactly one rectangle, and rectangles hold only such cells. */
static void check_rects(const char *path, long max_rects)
{
    occmap_t *m = load(path);
    assert_non_null(m);
    sim_rect_t *r = NULL;
    long n = sim_walls_rects(m, &r);
    assert_true(n > 0 && n <= max_rects);
    unsigned char *cover = calloc((size_t)m->width * m->height, 1);
    for (long k = 0; k < n; k++)
        for (int j = r[k].j; j < r[k].j + r[k].h; j++)
            for (int i = r[k].i; i < r[k].i + r[k].w; i++) {
                assert_true(occmap_get(m, i, j) != OCCMAP_FREE);
                cover[(size_t)j * m->width + i]++;
            }
    for (int j = 0; j < m->height; j++)
        for (int i = 0; i < m->width; i++)
            assert_int_equal(cover[(size_t)j * m->width + i], occmap_get(m, i, j) != OCCMAP_FREE);
    fprintf(stderr, "%s: %dx%d cells, %ld wall boxes\n", path, m->width, m->height, n);
    free(cover);
    free(r);
    occmap_destroy(m);
}

static void test_map_rects(void **state)
{
    (void)state;
    check_rects("sim/worlds/test.yaml", 16);
    check_rects("sim/worlds/office.yaml", 400);
    check_rects("tests/data/nav2/tb3_sandbox.yaml", 2000);     /* unknown all around: solid too */
}

static sim_world_t *test_world(double x, double y, double th, uint64_t seed)
{
    occmap_t *m = load("sim/worlds/test.yaml");
    assert_non_null(m);
    sim_params_t p;
    sim_params_default(&p);
    p.start_x = x;
    p.start_y = y;
    p.start_theta = th;
    p.seed = seed;
    sim_world_t *w = sim_world_create(m, &p);
    assert_non_null(w);
    occmap_destroy(m);
    return w;
}

static void run(sim_world_t *w, double seconds)
{
    long n = lround(seconds / sim_world_step_s(w));
    for (long i = 0; i < n; i++)
        sim_world_step(w);
}

static double wrap(double a)
{
    return atan2(sin(a), cos(a));
}

static void test_straight(void **state)
{
    (void)state;
    sim_world_t *w = test_world(2.0, 2.0, 0.0, 1);
    run(w, 0.5);                                /* settle on the ground */
    double x0, y0, t0, x, y, t, v, om;
    sim_world_pose(w, &x0, &y0, &t0);
    assert_true(fabs(x0 - 2.0) < 0.01 && fabs(y0 - 2.0) < 0.01 && fabs(t0) < 0.01);
    sim_world_set_velocity(w, 0.5, 0.0);
    run(w, 4.0);
    sim_world_velocity(w, &v, &om);
    assert_true(fabs(v - 0.5) < 0.01);
    assert_true(fabs(om) < 0.01);
    sim_world_pose(w, &x, &y, &t);
    /* 4 s at 0.5 m/s less the ramp at 1.5 m/s^2 (1/3 s, 0.083 m lost). */
    double expect = 0.5 * 4.0 - 0.5 * (0.5 / 1.5) / 2;
    fprintf(stderr, "straight: %.4f m (expected %.4f), y drift %.4f, heading %.4f\n", x - x0, expect, y - y0, t);
    assert_true(fabs((x - x0) - expect) < 0.05 * expect);
    assert_true(fabs(y - y0) < 0.02);
    assert_true(fabs(wrap(t - t0)) < 0.02);
    /* Encoders: the wheels turned distance / r, 4096 ticks per turn. */
    int32_t l, r;
    sim_world_encoders(w, &l, &r);
    double turns = (x - x0) / (2 * M_PI * 0.1);
    assert_true(fabs(l / 4096.0 - turns) < 0.03 * turns);
    assert_true(fabs(r / 4096.0 - turns) < 0.03 * turns);
    /* Stop: the ramp brings it to rest. */
    sim_world_set_velocity(w, 0.0, 0.0);
    run(w, 1.0);
    sim_world_velocity(w, &v, &om);
    assert_true(fabs(v) < 0.005);
    sim_world_destroy(w);
}

static void test_rotate_and_arc(void **state)
{
    (void)state;
    sim_world_t *w = test_world(4.0, 3.0, 0.5, 2);
    run(w, 0.5);
    double x0, y0, t0, x, y, t, v, om;
    sim_world_pose(w, &x0, &y0, &t0);
    sim_world_set_velocity(w, 0.0, 1.0);
    double turned = 0, prev = t0;
    for (int i = 0; i < 600; i++) {             /* 3 s */
        sim_world_step(w);
        sim_world_pose(w, &x, &y, &t);
        turned += wrap(t - prev);
        prev = t;
    }
    sim_world_velocity(w, &v, &om);
    assert_true(fabs(om - 1.0) < 0.02);
    /* rim speed 0.2 m/s reached in 0.133 s at 1.5 m/s^2: 0.067 rad lost */
    double expect = 3.0 - 0.2 / 1.5 / 2;
    fprintf(stderr, "rotate: %.4f rad (expected %.4f), moved %.4f m\n", turned, expect, hypot(x - x0, y - y0));
    assert_true(fabs(turned - expect) < 0.05 * expect);
    assert_true(hypot(x - x0, y - y0) < 0.03);

    /* An arc of radius 1 m: v and omega as commanded, then a circle about the centre
     * found once the ramp is over. */
    sim_world_set_velocity(w, 0.0, 0.0);
    run(w, 1.0);
    sim_world_set_velocity(w, 0.4, 0.4);
    run(w, 1.0);
    sim_world_pose(w, &x0, &y0, &t0);
    double cx = x0 - sin(t0), cy = y0 + cos(t0);   /* centre to the left */
    double worst = 0;
    for (int i = 0; i < 800; i++) {             /* 4 s, most of a turn */
        sim_world_step(w);
        sim_world_pose(w, &x, &y, &t);
        worst = fmax(worst, fabs(hypot(x - cx, y - cy) - 1.0));
    }
    sim_world_velocity(w, &v, &om);
    fprintf(stderr, "arc: v %.4f omega %.4f, radius error up to %.4f m\n", v, om, worst);
    assert_true(fabs(v - 0.4) < 0.01 && fabs(om - 0.4) < 0.01);
    assert_true(worst < 0.02);
    assert_int_equal(sim_world_wall_contacts(w), 0);
    sim_world_destroy(w);
}

static void test_laser_known_walls(void **state)
{
    (void)state;
    sim_world_t *w = test_world(3.0, 2.0, 0.0, 3);
    run(w, 0.5);
    double x, y, t;
    sim_world_pose(w, &x, &y, &t);
    float r[181], e[181];
    assert_int_equal(sim_world_laser_exact(w, e, 181), 181);
    /* Beam 90 straight ahead meets wall A (x = 7.0); beam 180 (left) the top wall (y = 7.9);
     * beam 0 (right) the bottom wall (y = 0.1); beam 45 (-45 deg) the bottom wall; beam 135
     * (+45 deg) passes over wall A and reaches nothing within 8 m. */
    fprintf(stderr, "laser at (%.3f %.3f %.4f): %.3f %.3f %.3f %.3f %.3f\n", x, y, t, e[0], e[45], e[90], e[135], e[180]);
    assert_true(fabs(e[90] - (7.0 - x)) < 0.02);
    assert_true(fabs(e[180] - (7.9 - y)) < 0.02);
    assert_true(fabs(e[0] - (y - 0.1)) < 0.02);
    assert_true(fabs(e[45] - (y - 0.1) * sqrt(2.0)) < 0.03);
    assert_true(e[135] == 8.0f);
    /* The noisy scan: mean error near zero, spread near the configured 0.01 m. */
    assert_int_equal(sim_world_laser(w, r, 181), 181);
    double sum = 0, sum2 = 0;
    int n = 0;
    for (int i = 0; i < 181; i++) {
        if (e[i] >= 8.0f) {
            assert_true(r[i] == 8.0f);
            continue;
        }
        double d = r[i] - e[i];
        sum += d;
        sum2 += d * d;
        n++;
    }
    double mean = sum / n, sd = sqrt(sum2 / n - mean * mean);
    fprintf(stderr, "laser noise over %d beams: mean %.4f sd %.4f\n", n, mean, sd);
    assert_true(fabs(mean) < 0.005);
    assert_true(sd > 0.006 && sd < 0.014);
    sim_world_destroy(w);
}

static void test_wall_stops_robot(void **state)
{
    (void)state;
    sim_world_t *w = test_world(5.0, 2.0, 0.0, 4);
    run(w, 0.5);
    sim_world_set_velocity(w, 0.5, 0.0);
    int touched = 0;
    for (int i = 0; i < 2000; i++) {            /* 10 s: would be 5 m in the open */
        sim_world_step(w);
        touched |= sim_world_wall_contacts(w) > 0;
    }
    double x, y, t, v, om;
    sim_world_pose(w, &x, &y, &t);
    sim_world_velocity(w, &v, &om);
    fprintf(stderr, "wall: stopped at x %.4f (wall at 7.0, chassis half-length 0.25), v %.4f, heading %.4f\n", x, v, t);
    assert_true(touched);
    assert_true(x < 7.0 - 0.25 + 0.02);
    assert_true(x > 6.5);
    assert_true(fabs(v) < 0.02);
    sim_world_destroy(w);
}

static void test_estop(void **state)
{
    (void)state;
    sim_world_t *w = test_world(2.0, 4.0, 0.0, 5);
    run(w, 0.5);
    sim_world_set_velocity(w, 0.5, 0.0);
    run(w, 2.0);
    double x0, y0, t0, x, y, t, v, om;
    sim_world_pose(w, &x0, &y0, &t0);
    sim_world_set_estop(w, true);
    run(w, 1.0);
    sim_world_pose(w, &x, &y, &t);
    sim_world_velocity(w, &v, &om);
    /* 0.5 m/s quick-stopped at 4 m/s^2: 0.125 s, 0.031 m */
    fprintf(stderr, "e-stop: stopped in %.4f m\n", x - x0);
    assert_true(fabs(v) < 0.005);
    assert_true(x - x0 < 0.05);
    sim_world_set_velocity(w, 0.5, 0.0);        /* ignored while pressed */
    run(w, 0.5);
    sim_world_velocity(w, &v, &om);
    assert_true(fabs(v) < 0.005);
    sim_world_set_estop(w, false);
    run(w, 1.0);
    sim_world_velocity(w, &v, &om);
    assert_true(fabs(v - 0.5) < 0.01);
    sim_world_destroy(w);
}

/* The same seed and the same commands give the same trajectory and readings, bit for bit. */
static void trajectory(uint64_t seed, double *out, int n)
{
    sim_world_t *w = test_world(2.5, 2.5, 0.3, seed);
    float scan[181];
    int k = 0;
    for (int i = 0; i < 1600; i++) {
        if (i % 200 == 0)
            sim_world_set_velocity(w, 0.3 + 0.1 * (i / 200 % 3), i / 200 % 2 ? 0.6 : -0.4);
        sim_world_step(w);
        if (i % 20 == 0) {
            sim_world_laser(w, scan, 181);
            double g = sim_world_gyro(w), x, y, t;
            sim_world_pose(w, &x, &y, &t);
            if (k + 5 <= n) {
                out[k++] = x; out[k++] = y; out[k++] = t; out[k++] = g; out[k++] = scan[17];
            }
        }
    }
    sim_world_destroy(w);
}

static void test_determinism(void **state)
{
    (void)state;
    enum { N = 5 * 80 };
    double a[N], b[N], c[N];
    trajectory(42, a, N);
    trajectory(42, b, N);
    trajectory(43, c, N);
    assert_memory_equal(a, b, sizeof(a));
    assert_memory_not_equal(a, c, sizeof(a));   /* the noise differs with the seed */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_map_rects),
        cmocka_unit_test(test_straight),
        cmocka_unit_test(test_rotate_and_arc),
        cmocka_unit_test(test_laser_known_walls),
        cmocka_unit_test(test_wall_stops_robot),
        cmocka_unit_test(test_estop),
        cmocka_unit_test(test_determinism),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
