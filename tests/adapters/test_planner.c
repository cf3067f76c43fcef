/* test_planner: OMPL plans collision-free paths on the inflated map and around laser obstacles. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <errno.h>
#include <math.h>
#include <cmocka.h>

#include "adapters/planner/planner.h"
#include "tests/fails.h"

/* The path's vertices are free on the planner's grid, and every point along it, 2 cm apart,
 * keeps the robot's footprint circle clear of the map (checked on the map itself: the
 * planner's clearance margin absorbs its half-cell motion checks). */
static void assert_path_clear(const planner_t *pl, const occmap_t *m, const double *P, int n, double radius)
{
    for (int i = 1; i + 1 < n; i++)
        assert_true(planner_free(pl, P[3 * i], P[3 * i + 1]));
    for (int i = 0; i + 1 < n; i++) {
        double len = hypot(P[3 * i + 3] - P[3 * i], P[3 * i + 4] - P[3 * i + 1]);
        int k = (int)ceil(len / 0.02) + 1;
        for (int j = 0; j <= k; j++) {
            double x = P[3 * i] + (P[3 * i + 3] - P[3 * i]) * j / k;
            double y = P[3 * i + 1] + (P[3 * i + 4] - P[3 * i + 1]) * j / k;
            for (int a = 0; a < 32; a++)
                for (double r = 0; r <= radius; r += 0.05)
                    assert_false(occmap_occupied_at(m, x + r * cos(a * M_PI / 16), y + r * sin(a * M_PI / 16)));
        }
    }
}

static double path_length(const double *P, int n)
{
    double l = 0;
    for (int i = 0; i + 1 < n; i++)
        l += hypot(P[3 * i + 3] - P[3 * i], P[3 * i + 4] - P[3 * i + 1]);
    return l;
}

/* Every algorithm: a clear path from a room near one end to a room near the other; the grid
 * search's is the shortest of them within 1 % (the shortest on the grid, then straightened: a
 * roadmap's can still come a few cm shorter, as PRM's did once, 53.2 against 53.2x m). */
static void test_plans_between_rooms(void **state)
{
    occmap_t *m = occmap_make_office(40, 30, 0.05, 11);
    assert_non_null(m);
    static const char *names[] = { "grid", "rrtconnect", "prm" };
    double grid_len = 0;
    for (int a = 0; a < 3; a++) {
        planner_params_t p;
        planner_params_default(&p);
        p.algorithm = names[a];
        planner_t *pl = planner_create(m, &p, 1);
        assert_non_null(pl);
        /* Lower room near the left end to an upper room near the right end. */
        double s[3] = { 2.0, 5.0, 0 }, g[3] = { 37.0, 25.0, 1.0 };
        assert_true(planner_free(pl, s[0], s[1]) && planner_free(pl, g[0], g[1]));
        double *P = NULL;
        int n = 0;
        assert_int_equal(planner_plan(pl, s, g, &P, &n), 0);
        assert_true(n >= 2);
        assert_true(P[0] == s[0] && P[1] == s[1]);
        assert_true(P[3 * (n - 1)] == g[0] && P[3 * (n - 1) + 1] == g[1] && P[3 * (n - 1) + 2] == g[2]);
        assert_path_clear(pl, m, P, n, p.robot_radius);
        double len = path_length(P, n);
        printf("office path (%s): %d poses, %.1f m (straight line %.1f m)\n", names[a], n, len,
               hypot(g[0] - s[0], g[1] - s[1]));
        assert_true(len < 1.5 * (fabs(g[0] - s[0]) + fabs(g[1] - s[1])));
        if (a == 0)
            grid_len = len;
        else
            assert_true(grid_len <= len * 1.01);
        free(P);
        planner_destroy(pl);
    }
    occmap_destroy(m);
}

static void test_refuses_goal_in_wall_and_unreachable(void **state)
{
    occmap_t *m = occmap_create(200, 200, 0.05, -5, -5);   /* 10 x 10 m, origin at -5,-5 */
    occmap_fill_rect(m, 1, 1, 3, 1.1, OCCMAP_OCCUPIED);    /* a closed box: x 1..3, y 1..3 */
    occmap_fill_rect(m, 1, 2.9, 3, 3, OCCMAP_OCCUPIED);
    occmap_fill_rect(m, 1, 1, 1.1, 3, OCCMAP_OCCUPIED);
    occmap_fill_rect(m, 2.9, 1, 3, 3, OCCMAP_OCCUPIED);
    occmap_fill_rect(m, -3, -3, -2, -2, OCCMAP_OCCUPIED);  /* a pillar */
    planner_params_t p;
    planner_params_default(&p);
    p.time_limit = 0.2;
    planner_t *pl = planner_create(m, &p, 1);
    double *P = NULL;
    int n = 0;
    double s[3] = { -4, -4, 0 }, wall[3] = { -2.5, -2.5, 0 }, inside[3] = { 2, 2, 0 };
    assert_fails(planner_plan(pl, s, wall, &P, &n), EINVAL);
    assert_null(P);
    assert_fails(planner_plan(pl, s, inside, &P, &n), ENOENT);
    assert_null(P);
    /* A goal just inside the inflation is snapped to the nearest free spot. */
    double near[3] = { -1.75, -2.5, 0 };
    assert_false(planner_free(pl, near[0], near[1]));
    assert_int_equal(planner_plan(pl, s, near, &P, &n), 0);
    assert_true(P[3 * (n - 1)] == near[0]);
    free(P);
    planner_destroy(pl);
    occmap_destroy(m);
}

static void test_laser_obstacle_blocks_and_replans(void **state)
{
    occmap_t *m = occmap_create(200, 100, 0.05, 0, 0);     /* 10 x 5 m open hall */
    occmap_fill_rect(m, 0, 0, 10, 0.1, OCCMAP_OCCUPIED);
    occmap_fill_rect(m, 0, 4.9, 10, 5, OCCMAP_OCCUPIED);
    planner_params_t p;
    planner_params_default(&p);
    planner_t *pl = planner_create(m, &p, 1);
    double s[3] = { 1, 2.5, 0 }, g[3] = { 9, 2.5, 0 };
    double *P = NULL;
    int n = 0;
    assert_int_equal(planner_plan(pl, s, g, &P, &n), 0);
    assert_int_equal(planner_path_blocked(pl, P, n, 1, 2.5, 20), -1);
    /* A person steps into the hall at x 5: the points are new, the path is now blocked. */
    double pts[] = { 5.0, 2.4, 5.0, 2.5, 5.0, 2.6, 5.0, 0.15 /* next to the wall: ignored */ };
    assert_int_equal(planner_add_obstacles(pl, pts, 4, 100.0), 3);
    assert_int_equal(planner_add_obstacles(pl, pts, 4, 100.5), 0);   /* seen again: refreshed */
    assert_true(planner_path_blocked(pl, P, n, 1, 2.5, 20) >= 0);
    /* Beyond the horizon it does not count yet. */
    assert_int_equal(planner_path_blocked(pl, P, n, 1, 2.5, 2.0), -1);
    free(P);
    assert_int_equal(planner_plan(pl, s, g, &P, &n), 0);
    assert_int_equal(planner_path_blocked(pl, P, n, 1, 2.5, 20), -1);
    assert_path_clear(pl, m, P, n, p.robot_radius);
    free(P);
    /* The obstacle leaves: forgotten after its time to live. */
    assert_int_equal(planner_obstacle_count(pl), 3);
    planner_add_obstacles(pl, NULL, 0, 100.5 + p.obstacle_ttl + 1);
    assert_int_equal(planner_obstacle_count(pl), 0);
    assert_true(planner_free(pl, 5.0, 2.5));
    planner_destroy(pl);
    occmap_destroy(m);
}

static void test_map_change_invalidates_path(void **state)
{
    occmap_t *m = occmap_create(200, 100, 0.05, 0, 0);     /* 10 x 5 m open hall */
    planner_params_t p;
    planner_params_default(&p);
    planner_t *pl = planner_create(m, &p, 1);
    double s[3] = { 1, 2.5, 0 }, g[3] = { 9, 2.5, 0 };
    double *P = NULL;
    int n = 0;
    assert_int_equal(planner_plan(pl, s, g, &P, &n), 0);
    assert_int_equal(planner_path_collides(pl, P, n), -1);
    /* The map now has a wall across the hall with a gap at the top: the old path collides,
     * a new plan goes through the gap. */
    occmap_fill_rect(m, 5.0, 0, 5.2, 3.8, OCCMAP_OCCUPIED);
    planner_t *pl2 = planner_create(m, &p, 1);
    assert_true(planner_path_collides(pl2, P, n) >= 0);
    free(P);
    assert_int_equal(planner_plan(pl2, s, g, &P, &n), 0);
    assert_int_equal(planner_path_collides(pl2, P, n), -1);
    assert_path_clear(pl2, m, P, n, p.robot_radius);
    free(P);
    planner_destroy(pl2);
    planner_destroy(pl);
    occmap_destroy(m);
}

static void test_prm_reuses_roadmap(void **state)
{
    occmap_t *m = occmap_make_office(20, 15, 0.05, 3);
    planner_params_t p;
    planner_params_default(&p);
    p.algorithm = "prm";
    planner_t *pl = planner_create(m, &p, 1);
    assert_non_null(pl);
    double a[3] = { 2, 7.5, 0 }, b[3] = { 18, 7.5, 0 };
    for (int i = 0; i < 3; i++) {
        double *P = NULL;
        int n = 0;
        assert_int_equal(planner_plan(pl, i % 2 ? b : a, i % 2 ? a : b, &P, &n), 0);
        assert_path_clear(pl, m, P, n, p.robot_radius);
        free(P);
    }
    planner_destroy(pl);
    occmap_destroy(m);
}

/* The small-robot world's 0.6 m door: closed to Spartacus' footprint (0.3 m + 0.1 m), open to
 * the small profile's (0.18 m + 0.06 m), and the path found (the grid search behind OMPL when
 * sampling misses the narrow passage) keeps the small footprint off the walls. */
static void test_small_footprint_passes_the_06m_door(void **state)
{
    marie_errors_t e = { 0 };
    occmap_t *m = occmap_load("sim/worlds/small.yaml", &e);
    assert_non_null(m);
    planner_params_t p;
    planner_params_default(&p);
    p.time_limit = 0.2;
    double s[3] = { 1.5, 3.0, 0 }, g[3] = { 5.5, 3.0, 0 };
    planner_t *big = planner_create(m, &p, 1);
    assert_non_null(big);
    double *P = NULL;
    int n = 0;
    assert_int_not_equal(planner_plan(big, s, g, &P, &n), 0);
    planner_destroy(big);
    p.robot_radius = 0.18;
    p.robot_clearance = 0.06;
    planner_t *small = planner_create(m, &p, 1);
    assert_non_null(small);
    assert_int_equal(planner_plan(small, s, g, &P, &n), 0);
    assert_path_clear(small, m, P, n, p.robot_radius);
    double len = path_length(P, n);
    printf("small world path through the 0.6 m door: %d poses, %.2f m\n", n, len);
    assert_true(len < 1.2 * hypot(g[0] - s[0], g[1] - s[1]));
    free(P);
    planner_destroy(small);
    occmap_destroy(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_plans_between_rooms),
        cmocka_unit_test(test_refuses_goal_in_wall_and_unreachable),
        cmocka_unit_test(test_laser_obstacle_blocks_and_replans),
        cmocka_unit_test(test_map_change_invalidates_path),
        cmocka_unit_test(test_prm_reuses_roadmap),
        cmocka_unit_test(test_small_footprint_passes_the_06m_door),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
