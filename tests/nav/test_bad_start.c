/* test_bad_start: a start the robot cannot have is refused and said, not taken. marie-localizer
 * started with its pose inside a wall fails its init naming the place; marie-planner, given a
 * start or a goal where the robot does not fit, says which of the two and why (over real LCM,
 * with the programs themselves). */
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
#include "tests/proc.h"

/* The program under test, stopped by the teardown too when a check failed. */
static pid_t prog = -1;

static int stop_prog(void **state)
{
    test_stop(prog);
    prog = -1;
    return 0;
}

typedef struct {
    int8_t loc_state;
    char loc_reason[300];
    int path_status;
    char no_path[600];
} seen_t;

static void on_msg(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    seen_t *k = user;
    if (!strcmp(ch, "PATH")) {
        marie_path_t p;
        if (marie_decode_checked(&marie_type_path_t, rb->data, rb->data_size, &p) < 0)
            return;
        k->path_status = p.status;
        marie_path_t_decode_cleanup(&p);
    } else if (!strcmp(ch, "MARIE_EVENT")) {
        marie_event_t e;
        if (marie_decode_checked(&marie_type_event_t, rb->data, rb->data_size, &e) < 0)
            return;
        if (!strcmp(e.kind, "no_path"))
            snprintf(k->no_path, sizeof k->no_path, "%s", e.text);
        marie_event_t_decode_cleanup(&e);
    } else {
        marie_heartbeat_t hb;
        if (marie_decode_checked(&marie_type_heartbeat_t, rb->data, rb->data_size, &hb) < 0)
            return;
        if (!strcmp(hb.component, "localizer")) {
            k->loc_state = hb.state;
            snprintf(k->loc_reason, sizeof k->loc_reason, "%s", hb.reason);
        }
        marie_heartbeat_t_decode_cleanup(&hb);
    }
}

static void handle_for(lcm_t *l, int ms)
{
    int64_t end = marie_mono_us() + ms * 1000LL;
    while (marie_mono_us() < end)
        lcm_handle_timeout(l, 20);
}

static const char *bin(const char *name)
{
    static char path[4][256];
    static int i;
    i = (i + 1) % 4;
    snprintf(path[i], sizeof path[i], "%s/bin/%s", getenv("B") ? getenv("B") : "build", name);
    return path[i];
}

/* The test world's wall A stands at x 7.0-7.2, y 0.1-5.0. */
static void localizer_refuses_a_start_inside_a_wall(void **state)
{
    lcm_t *l = lcm_create(NULL);
    seen_t k = { .loc_state = -1 };
    lcm_subscribe(l, "MARIE_HEARTBEAT", on_msg, &k);
    char *argv[] = { (char *)bin("marie-localizer"), "--name", "localizer", "--param", "map=sim/worlds/test.yaml",
                     "--param", "init_x=7.1", "--param", "init_y=2.0", "--param", "resume_max_age_s=0", NULL };
    prog = test_spawn(argv, "/dev/null");
    for (int i = 0; i < 100 && k.loc_state < 0; i++)
        handle_for(l, 100);
    handle_for(l, 300);
    printf("localizer: state %d: %s\n", k.loc_state, k.loc_reason);
    assert_int_equal(k.loc_state, MARIE_LIFECYCLE_COMMAND_T_STATE_FAILED);
    assert_non_null(strstr(k.loc_reason, "(7.10, 2.00) is inside a wall"));
    lcm_destroy(l);
}

/* A goal, and the pose the plan starts from: the planner's path status and its no_path text. */
static void ask(lcm_t *l, seen_t *k, int id, double sx, double sy, double gx, double gy)
{
    k->path_status = -1;
    k->no_path[0] = 0;
    for (int i = 0; i < 30 && (k->path_status < 0 || !k->no_path[0]); i++) {
        marie_pose_cov_t pose = { .utime = marie_wall_us(), .frame = "map", .pose = { sx, sy, 0 } };
        marie_pose_cov_t_publish(l, "POSE", &pose);
        marie_goal_t g = { .utime = marie_wall_us(), .id = id, .name = "test", .pose = { gx, gy, 0 }, .tolerance = 0.3 };
        marie_goal_t_publish(l, "GOAL", &g);
        handle_for(l, 200);
    }
    printf("goal %d: status %d: %s\n", id, k->path_status, k->no_path);
}

static void planner_says_which_end_is_blocked(void **state)
{
    lcm_t *l = lcm_create(NULL);
    seen_t k = { .loc_state = -1 };
    lcm_subscribe(l, "PATH", on_msg, &k);
    lcm_subscribe(l, "MARIE_EVENT", on_msg, &k);
    char *argv[] = { (char *)bin("marie-planner"), "--name", "planner", "--param", "map=sim/worlds/test.yaml",
                     "--param", "use_scan=false", NULL };
    prog = test_spawn(argv, "/dev/null");
    handle_for(l, 1500);
    ask(l, &k, 1, 7.1, 2.0, 3.0, 3.0);          /* start inside wall A */
    assert_int_equal(k.path_status, MARIE_PATH_T_STATUS_INVALID_START);
    assert_non_null(strstr(k.no_path, "start (7.10, 2.00) inside a wall"));
    ask(l, &k, 2, 3.0, 3.0, 1.5, 5.5);          /* goal inside pillar B */
    assert_int_equal(k.path_status, MARIE_PATH_T_STATUS_INVALID_GOAL);
    assert_non_null(strstr(k.no_path, "goal (1.50, 5.50) inside a wall"));
    ask(l, &k, 3, 3.0, 3.0, 0.2, 0.2);          /* a goal in the corner, where no robot fits */
    assert_int_equal(k.path_status, MARIE_PATH_T_STATUS_INVALID_GOAL);
    assert_non_null(strstr(k.no_path, "goal (0.20, 0.20) 0."));
    assert_non_null(strstr(k.no_path, "m from a wall (the robot needs 0.40 m)"));
    lcm_destroy(l);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(localizer_refuses_a_start_inside_a_wall, stop_prog),
        cmocka_unit_test_teardown(planner_says_which_end_is_blocked, stop_prog),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
