/* test_unmapped: what the world has and the map lacks is a normal day, not being lost. The whole
 * navigation stack (marie-sim, -odometry, -localizer, -planner, -behaviours) runs over real LCM on
 * the simulator's clock in a world made of a map no one here drew (nav2's depot) plus an obstacle
 * the robot's map does not have, and drives to a goal past it. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "map/occmap.h"
#include "tests/nav/navrig.h"

/* The map with rectangles filled in, saved as DIR/world.yaml for the simulator. */
static void world_with(const rig_t *r, const char *map, const double (*rects)[4], int n, char *out, size_t len)
{
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load(map, &errs);
    assert_non_null(m);
    for (int i = 0; i < n; i++)
        occmap_fill_rect(m, rects[i][0], rects[i][1], rects[i][2], rects[i][3], OCCMAP_OCCUPIED);
    snprintf(out, len, "%s/world.yaml", r->dir);
    assert_int_equal(occmap_save(m, out), 0);
    occmap_destroy(m);
}

static double goal_xy[2];
static int near_goal(const rig_t *r)
{
    return hypot(r->truth[0] - goal_xy[0], r->truth[1] - goal_xy[1]) < 0.3;
}

/* The stack in `world`, the robot given `map`, starting at (x, y, th). */
static void start_stack(rig_t *r, const char *world, const char *map, double x, double y, double th)
{
    char w[320], m[320], sx[64], sy[64], st[64], lx[64], ly[64], lt[64];
    snprintf(w, sizeof w, "world=%s", world);
    snprintf(m, sizeof m, "map=%s", map);
    snprintf(sx, sizeof sx, "start_x=%g", x), snprintf(sy, sizeof sy, "start_y=%g", y);
    snprintf(st, sizeof st, "start_theta=%g", th);
    snprintf(lx, sizeof lx, "init_x=%g", x), snprintf(ly, sizeof ly, "init_y=%g", y);
    snprintf(lt, sizeof lt, "init_theta=%g", th);
    rig_start(r, "sim", w, "mode=channel", "speed=3", sx, sy, st, "seed=3", NULL);
    rig_start(r, "odometry", NULL);
    rig_start(r, "localizer", m, lx, ly, lt, "resume_max_age_s=0", NULL);
    rig_start(r, "planner", m, NULL);
    rig_start(r, "behaviours", "input_mode=subscribe", NULL);
}

/* nav2's depot, a 0.6 m box in the middle of the 6 m straight from (4, 8) to (10, 8): the box is
 * what most of the scan sees (the walls are 4 to 8 m off), and the map has none of it. */
static void a_box_on_the_way_is_not_being_lost(void **state)
{
    rig_t *r = rig_open("test_unmapped_box");
    static const double box[][4] = { { 6.7, 7.7, 7.3, 8.3 } };
    char world[300];
    world_with(r, "tests/data/nav2/depot.yaml", box, 1, world, sizeof world);
    start_stack(r, world, "tests/data/nav2/depot.yaml", 4.0, 8.0, 0.0);
    rig_run(r, 3, false, 0, 0, NULL);
    goal_xy[0] = 10.0, goal_xy[1] = 8.0;
    rig_goal(r, 1, goal_xy[0], goal_xy[1]);
    rig_run(r, 60, false, 0, 0, near_goal);
    rig_run(r, 1.5, false, 0, 0, NULL);         /* a heartbeat more */
    printf("box: robot at (%.2f, %.2f), pose error %.2f m, lost %lld, collisions %lld\n", r->truth[0], r->truth[1],
           rig_error(r), (long long)r->lost, (long long)r->collisions);
    assert_true(near_goal(r) || hypot(r->truth[0] - goal_xy[0], r->truth[1] - goal_xy[1]) < 0.5);
    assert_int_equal(r->lost, 0);
    assert_false(rig_event(r, "lost"));
    assert_true(rig_error(r) < 0.3);
    assert_int_equal(r->collisions, 0);
}

/* nav2's depot with a 4 m wall 1.5 m beside the way from (3, 8) to (13, 8), which the map lacks:
 * the wall explains the scan as well as the depot's own outer walls would from elsewhere, and
 * must not pull the robot there. */
static void a_wall_the_map_lacks_is_not_a_look_alike(void **state)
{
    rig_t *r = rig_open("test_unmapped_wall");
    static const double wall[][4] = { { 6.0, 6.4, 10.0, 6.55 } };
    char world[300];
    world_with(r, "tests/data/nav2/depot.yaml", wall, 1, world, sizeof world);
    start_stack(r, world, "tests/data/nav2/depot.yaml", 3.0, 8.0, 0.0);
    rig_run(r, 3, false, 0, 0, NULL);
    goal_xy[0] = 13.0, goal_xy[1] = 8.0;
    rig_goal(r, 1, goal_xy[0], goal_xy[1]);
    double worst = 0;
    for (int k = 0; k < 60 && !near_goal(r); k++) {
        rig_run(r, 1, false, 0, 0, near_goal);
        if (r->pose_utime > r->sim_us - 500000)
            worst = fmax(worst, rig_error(r));
    }
    rig_run(r, 1.5, false, 0, 0, NULL);
    printf("wall: robot at (%.2f, %.2f), worst pose error %.2f m, lost %lld, collisions %lld\n", r->truth[0], r->truth[1],
           worst, (long long)r->lost, (long long)r->collisions);
    assert_true(hypot(r->truth[0] - goal_xy[0], r->truth[1] - goal_xy[1]) < 0.5);
    assert_int_equal(r->lost, 0);
    assert_true(worst < 0.5);
    assert_int_equal(r->collisions, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(a_box_on_the_way_is_not_being_lost, rig_teardown),
        cmocka_unit_test_teardown(a_wall_the_map_lacks_is_not_a_look_alike, rig_teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
