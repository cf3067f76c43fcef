/* test_kidnap: the kidnapped robot. marie-sim, marie-odometry and marie-localizer run on the
 * simulator's clock over real LCM; the robot turns slowly on the spot in the test world, is
 * carried (SIM_TELEPORT) to the far side of wall A with no wheel turning, and the localizer
 * must notice (heartbeat degraded, `lost` event), relocalize over the whole map and come back
 * within a bounded time at the true pose, reporting running again. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>
#include <cmocka.h>
#include <lcm/lcm.h>

#include "lcmtypes/marie_types.h"
#include "tests/proc.h"

typedef struct {
    int64_t sim_us;                 /* newest simulated time */
    double truth[3], pose[3];
    int64_t pose_utime, npose;
    int loc_state;                  /* the localizer's heartbeat state, -1 before */
    int64_t kidnaps, relocs;
    int64_t degraded_at, running_again_at;   /* sim us; 0: not seen */
} obs_t;

static int64_t wall_us(void)
{
    struct timeval tv;
    gettimeofday(&tv, NULL);
    return (int64_t)tv.tv_sec * 1000000 + tv.tv_usec;
}

static void on_truth(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    obs_t *o = user;
    marie_pose_cov_t m;
    if (marie_pose_cov_t_decode(rb->data, 0, rb->data_size, &m) < 0)
        return;
    o->truth[0] = m.pose.x, o->truth[1] = m.pose.y, o->truth[2] = m.pose.theta;
    o->sim_us = m.utime;
    marie_pose_cov_t_decode_cleanup(&m);
}

static void on_pose(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    obs_t *o = user;
    marie_pose_cov_t m;
    if (marie_pose_cov_t_decode(rb->data, 0, rb->data_size, &m) < 0)
        return;
    o->pose[0] = m.pose.x, o->pose[1] = m.pose.y, o->pose[2] = m.pose.theta;
    o->pose_utime = m.utime;
    o->npose++;
    marie_pose_cov_t_decode_cleanup(&m);
}

static void on_heartbeat(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    obs_t *o = user;
    marie_heartbeat_t hb;
    if (marie_heartbeat_t_decode(rb->data, 0, rb->data_size, &hb) < 0)
        return;
    if (strcmp(hb.component, "localizer") == 0) {
        if (hb.state == 6 && !o->degraded_at)
            o->degraded_at = o->sim_us;
        if (hb.state == 2 && o->degraded_at && !o->running_again_at)
            o->running_again_at = o->sim_us;
        o->loc_state = hb.state;
        for (int i = 0; i < hb.ncounters; i++) {
            if (!strcmp(hb.counters[i].name, "kidnaps_detected"))
                o->kidnaps = hb.counters[i].value;
            if (!strcmp(hb.counters[i].name, "relocalizations"))
                o->relocs = hb.counters[i].value;
        }
    }
    marie_heartbeat_t_decode_cleanup(&hb);
}

static double pose_error(const obs_t *o)
{
    return hypot(o->pose[0] - o->truth[0], o->pose[1] - o->truth[1]);
}

/* Handle traffic for `sim_s` simulated seconds (bounded by wall time too), turning the robot at
 * omega; stops early when done(o) holds. */
static void run_for(lcm_t *l, obs_t *o, double sim_s, double omega, int (*done)(const obs_t *))
{
    int64_t until = o->sim_us + (int64_t)(sim_s * 1e6), wall_end = wall_us() + (int64_t)(sim_s / 2 * 1e6) + 10000000;
    int64_t next_cmd = 0;
    while (o->sim_us < until && wall_us() < wall_end && !(done && done(o))) {
        if (wall_us() >= next_cmd) {
            marie_motor_command_t cmd = { .utime = o->sim_us, .v = 0, .omega = omega, .source = "test" };
            marie_motor_command_t_publish(l, "MOTOR_COMMAND", &cmd);
            next_cmd = wall_us() + 50000;
        }
        lcm_handle_timeout(l, 20);
    }
}

static int relocalized(const obs_t *o)
{
    return o->running_again_at && o->pose_utime > o->running_again_at - 1000000 && pose_error(o) < 0.5;
}

static void kidnapped_robot_is_found_again(void **state)
{
    lcm_t *l = lcm_create(NULL);
    assert_non_null(l);
    obs_t o = { .loc_state = -1 };
    lcm_subscribe(l, "SIM_TRUTH", on_truth, &o);
    lcm_subscribe(l, "POSE", on_pose, &o);
    lcm_subscribe(l, "MARIE_HEARTBEAT", on_heartbeat, &o);
    const char *b = getenv("B") ? getenv("B") : "build";
    char sim[256], odo[256], loc[256];
    snprintf(sim, sizeof sim, "%s/bin/marie-sim", b);
    snprintf(odo, sizeof odo, "%s/bin/marie-odometry", b);
    snprintf(loc, sizeof loc, "%s/bin/marie-localizer", b);
    char *sa[] = { sim, "--name", "sim", "--param", "world=test", "--param", "mode=channel", "--param", "speed=2",
                   "--param", "start_x=3.0", "--param", "start_y=2.0", NULL };
    char *oa[] = { odo, "--name", "odometry", "--clock", "sim", NULL };
    char *la[] = { loc, "--name", "localizer", "--clock", "sim", "--param", "map=sim/worlds/test.yaml", "--param",
                   "init_x=3.0", "--param", "init_y=2.0", "--param", "resume_max_age_s=0", NULL };
    pid_t ps = test_spawn(sa, "/dev/null"), po = test_spawn(oa, "/dev/null"), pl = test_spawn(la, "/dev/null");
    assert_true(ps > 0 && po > 0 && pl > 0);

    /* Turning on the spot where it started: tracked, and no false alarm. */
    run_for(l, &o, 20, 0.4, NULL);
    printf("before: %lld poses, error %.2f m, state %d, kidnaps %lld\n", (long long)o.npose, pose_error(&o),
           o.loc_state, (long long)o.kidnaps);
    assert_true(o.npose > 50);
    assert_true(pose_error(&o) < 0.2);
    assert_int_equal(o.kidnaps, 0);
    assert_int_equal(o.loc_state, 2);

    /* Carried behind wall A, facing the other way. */
    marie_pose_cov_t t = { .utime = o.sim_us, .frame = "map", .pose = { 8.5, 6.0, 2.5 } };
    marie_pose_cov_t_publish(l, "SIM_TELEPORT", &t);
    int64_t kidnap_at = o.sim_us;
    run_for(l, &o, 5, 0.4, NULL);
    assert_true(hypot(o.truth[0] - 8.5, o.truth[1] - 6.0) < 0.3);     /* the simulator did carry it */
    run_for(l, &o, 120, 0.4, relocalized);
    double t_lost = o.degraded_at ? (o.degraded_at - kidnap_at) / 1e6 : -1;
    double t_back = o.running_again_at ? (o.running_again_at - kidnap_at) / 1e6 : -1;
    printf("kidnapped at %.1f s: lost after %.1f s, relocalized after %.1f s, error %.2f m, "
           "kidnaps %lld, relocalizations %lld\n", kidnap_at / 1e6, t_lost, t_back, pose_error(&o),
           (long long)o.kidnaps, (long long)o.relocs);
    assert_true(o.kidnaps >= 1);                        /* detected ... */
    assert_true(t_lost > 0 && t_lost < 20);             /* ... soon, and said so in the heartbeat */
    assert_true(t_back > 0 && t_back < 90);             /* found again within a bounded time */
    assert_true(o.relocs >= 1);
    assert_true(pose_error(&o) < 0.5);                  /* at the true pose */
    assert_int_equal(o.loc_state, 2);                   /* and running, no longer degraded */

    test_stop(pl);
    test_stop(po);
    test_stop(ps);
    lcm_destroy(l);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(kidnapped_robot_is_found_again),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
