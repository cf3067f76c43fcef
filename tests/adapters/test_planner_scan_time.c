/* test_planner_scan_time: marie-planner places each laser return from where the robot was when
 * the scan was taken, so a robot turning fast while its POSE lags 0.2 s behind sees no phantom
 * obstacles in free space (over real LCM, with the program itself). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>
#include <unistd.h>
#include <cmocka.h>
#include <lcm/lcm.h>

#include "adapters/common/posebuf.h"
#include "lcmtypes/marie_types.h"
#include "map/occmap.h"
#include "tests/proc.h"

#define NB 181
#define WORLD "sim/worlds/test.yaml"

static int64_t now_us(void)
{
    struct timeval tv;
    gettimeofday(&tv, NULL);
    return (int64_t)tv.tv_sec * 1000000 + tv.tv_usec;
}

typedef struct {
    int64_t obstacle_cells, scans_without_pose, beats;
} counters_t;

static void on_heartbeat(const lcm_recv_buf_t *rbuf, const char *ch, void *user)
{
    counters_t *k = user;
    marie_heartbeat_t hb;
    if (marie_heartbeat_t_decode(rbuf->data, 0, rbuf->data_size, &hb) < 0)
        return;
    if (strcmp(hb.component, "planner") == 0) {
        k->beats++;
        for (int i = 0; i < hb.ncounters; i++) {
            if (!strcmp(hb.counters[i].name, "obstacle_cells"))
                k->obstacle_cells = hb.counters[i].value;
            if (!strcmp(hb.counters[i].name, "scans_without_pose"))
                k->scans_without_pose = hb.counters[i].value;
        }
    }
    marie_heartbeat_t_decode_cleanup(&hb);
}

/* The robot spins in place at 1.5 rad/s in the test world for `seconds`, its POSE published 0.2 s
 * late (as a localizer's would be), odometry at 20 Hz in a frame offset from the map's, scans at
 * 10 Hz from the true pose; then the planner's counters from its heartbeat. */
static counters_t spin(bool with_odometry, double seconds)
{
    lcm_t *l = lcm_create(NULL);
    assert_non_null(l);
    counters_t k = { 0 };
    lcm_subscribe(l, "MARIE_HEARTBEAT", on_heartbeat, &k);
    const char *b = getenv("B") ? getenv("B") : "build";
    char bin[256];
    snprintf(bin, sizeof bin, "%s/bin/marie-planner", b);
    char *argv[] = { bin, "--param", "map=" WORLD, "--port", with_odometry ? "odom=ODOMETRY" : "odom=NO_ODOMETRY", NULL };
    pid_t pid = test_spawn(argv, "/dev/null");
    assert_true(pid > 0);
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load(WORLD, &errs);
    assert_non_null(m);
    while (k.beats == 0)                /* it is up */
        lcm_handle_timeout(l, 100);

    const double x = 5.0, y = 2.0, omega = 1.5, odom_in_map[3] = { 1.0, -0.5, 0.4 };
    int64_t t0 = now_us(), next_odom = t0, next_scan = t0;
    float ranges[NB];
    while (now_us() - t0 < (int64_t)(seconds * 1e6)) {
        int64_t t = now_us();
        double truth[3] = { x, y, remainder(omega * (t - t0) / 1e6, 2 * M_PI) };
        if (t >= next_odom) {
            double o[3], inv[3];
            pose2d_between(odom_in_map, (const double[3]){ 0, 0, 0 }, inv);
            pose2d_compose(inv, truth, o);
            marie_odometry_t od = { .utime = t, .pose = { o[0], o[1], o[2] }, .omega = omega };
            marie_odometry_t_publish(l, "ODOMETRY", &od);
            next_odom += 50000;
        }
        if (t >= next_scan) {
            for (int i = 0; i < NB; i++)
                ranges[i] = (float)occmap_raycast(m, x, y, truth[2] - M_PI / 2 + i * M_PI / 180, 8.0);
            marie_laser_scan_t sc = { .utime = t, .angle_min = -M_PI / 2, .angle_increment = M_PI / 180,
                                      .range_min = 0.05f, .range_max = 8.0f, .nranges = NB, .ranges = ranges };
            marie_laser_scan_t_publish(l, "LASER", &sc);
            int64_t late = t - 200000;
            marie_pose_cov_t p = { .utime = late, .frame = "map",
                                   .pose = { x, y, remainder(omega * (late - t0) / 1e6, 2 * M_PI) } };
            marie_pose_cov_t_publish(l, "POSE", &p);
            next_scan += 100000;
        }
        lcm_handle_timeout(l, 5);
    }
    int64_t beats = k.beats;
    while (k.beats < beats + 2)         /* two heartbeats after the last scan: all counted */
        lcm_handle_timeout(l, 100);
    test_stop(pid);
    occmap_destroy(m);
    lcm_destroy(l);
    return k;
}

static void turning_robot_sees_no_phantom_obstacles(void **state)
{
    counters_t k = spin(true, 5.0);
    printf("with odometry: %lld obstacle cells, %lld scans without a pose\n", (long long)k.obstacle_cells,
           (long long)k.scans_without_pose);
    /* The walls explain every return (the old newest-pose projection marked over 100 cells);
     * the first scans may come before odometry covers the first POSE. */
    assert_true(k.obstacle_cells <= 5);
    assert_true(k.scans_without_pose <= 5);
}

static void without_odometry_late_poses_place_no_scan(void **state)
{
    counters_t k = spin(false, 3.0);
    printf("without odometry: %lld obstacle cells, %lld scans without a pose\n", (long long)k.obstacle_cells,
           (long long)k.scans_without_pose);
    assert_true(k.obstacle_cells <= 5);
    assert_true(k.scans_without_pose >= 20);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(turning_robot_sees_no_phantom_obstacles),
        cmocka_unit_test(without_odometry_late_poses_place_no_scan),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
