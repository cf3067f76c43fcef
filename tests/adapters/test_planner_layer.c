/* test_planner_layer: a laser return in the middle of a corridor barely wider than the robot
 * closes the only way to the goal; marie-planner forgets its laser layer and plans on the map
 * instead of reporting no path for as long as the scans repeat the return (over real LCM, with
 * the program itself). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>
#include <lcm/lcm.h>

#include "core/time.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_types.h"
#include "map/occmap.h"
#include "tests/proc.h"

#define NB 181
#define WORLD "sim/worlds/small.yaml"

typedef struct {
    int64_t forgotten, beats;
    int paths_ok, paths_failed;
} seen_t;

static void on_msg(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    seen_t *k = user;
    if (!strcmp(ch, "PATH")) {
        marie_path_t p;
        if (marie_decode_checked(&marie_type_path_t, rb->data, rb->data_size, &p) < 0)
            return;
        if (p.goal_id == 7) {
            if (p.status == MARIE_PATH_T_STATUS_OK && p.nposes >= 2)
                k->paths_ok++;
            else
                k->paths_failed++;
        }
        marie_path_t_decode_cleanup(&p);
        return;
    }
    marie_heartbeat_t hb;
    if (marie_decode_checked(&marie_type_heartbeat_t, rb->data, rb->data_size, &hb) < 0)
        return;
    if (!strcmp(hb.component, "planner")) {
        k->beats++;
        for (int i = 0; i < hb.ncounters; i++)
            if (!strcmp(hb.counters[i].name, "obstacles_forgotten"))
                k->forgotten = hb.counters[i].value;
    }
    marie_heartbeat_t_decode_cleanup(&hb);
}

/* The small robot (0.18 m + 0.06 m) stands at the west end of the small world's 0.7 m corridor
 * (y 2.0-2.7), the only way into the south-east room; its scans show, besides the walls, a
 * return 1.2 m ahead in the corridor's middle. After 1 s of scans a goal in that room. */
static void a_return_closing_the_corridor_is_forgotten(void **state)
{
    lcm_t *l = lcm_create(NULL);
    assert_non_null(l);
    seen_t k = { 0 };
    lcm_subscribe(l, "MARIE_HEARTBEAT", on_msg, &k);
    lcm_subscribe(l, "PATH", on_msg, &k);
    const char *b = getenv("B") ? getenv("B") : "build";
    char bin[256];
    snprintf(bin, sizeof bin, "%s/bin/marie-planner", b);
    char *argv[] = { bin, "--param", "map=" WORLD, "--param", "robot_radius=0.18", "--param", "robot_clearance=0.06",
                     "--port", "odom=NO_ODOMETRY", NULL };
    pid_t pid = test_spawn(argv, "/dev/null");
    assert_true(pid > 0);
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load(WORLD, &errs);
    assert_non_null(m);
    while (k.beats == 0)
        lcm_handle_timeout(l, 100);

    const double x = 6.8, y = 2.35;
    float ranges[NB];
    int64_t t0 = marie_wall_us(), next_scan = t0;
    bool goal_sent = false;
    while (marie_wall_us() - t0 < 6000000 && k.paths_ok == 0) {
        int64_t t = marie_wall_us();
        if (t >= next_scan) {
            for (int i = 0; i < NB; i++)
                ranges[i] = (float)occmap_raycast(m, x, y, -M_PI / 2 + i * M_PI / 180, 8.0);
            ranges[90] = 1.2f;                  /* straight ahead: the phantom */
            marie_laser_scan_t sc = { .utime = t, .angle_min = -M_PI / 2, .angle_increment = M_PI / 180,
                                      .range_min = 0.05f, .range_max = 8.0f, .nranges = NB, .ranges = ranges };
            marie_pose_cov_t p = { .utime = t, .frame = "map", .pose = { x, y, 0 } };
            marie_pose_cov_t_publish(l, "POSE", &p);
            marie_laser_scan_t_publish(l, "LASER", &sc);
            next_scan += 100000;
        }
        if (!goal_sent && t - t0 > 1000000) {
            marie_goal_t g = { .utime = t, .id = 7, .name = "south-east room", .pose = { 9.4, 1.0, 0 },
                               .tolerance = 0.2 };
            marie_goal_t_publish(l, "GOAL", &g);
            goal_sent = true;
        }
        lcm_handle_timeout(l, 5);
    }
    int64_t beats = k.beats;
    while (k.beats < beats + 2)
        lcm_handle_timeout(l, 100);
    test_stop(pid);
    occmap_destroy(m);
    lcm_destroy(l);
    printf("paths: %d planned, %d without a way; layer forgotten %lld time(s)\n", k.paths_ok, k.paths_failed,
           (long long)k.forgotten);
    assert_true(k.paths_ok >= 1);
    assert_true(k.forgotten >= 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(a_return_closing_the_corridor_is_forgotten),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
