/* test_ca_config: marie-ca configured from a system file: every kind starts and serves its
 * configured channels; a bad type fails the component with a reason; an unknown parameter
 * is a configuration error (exit status 2). */
#include <errno.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include "ca/sharedmap_client.h"
#include "lcmtypes/marie_pose2d_t.h"
#include "tests/ca/ca_test.h"

#define SYSTEM "tests/data/ca/system.yaml"

static char dir[256];

static pid_t start(const char *kind, const char *name)
{
    const char *args[] = { kind, "--system", SYSTEM, "--name", name, NULL };
    return cat_spawn(args);
}

static int pose_count;
static void on_pose(const lcm_recv_buf_t *rbuf, const char *channel, void *user) { pose_count++; }
static bool got_pose(void *user) { return pose_count > 0; }

static void test_all_kinds_run_from_the_system_file(void **state)
{
    cat_tmpdir(dir, sizeof dir);
    setenv("MARIE_STATE_DIR", dir, 1);
    cat_bus_t *bus = cat_bus_create();
    pid_t pids[4] = { start("mailbox", "laser_mailbox"), start("splitter", "laser_splitter"),
                      start("sharedmap", "state"), start("switch", "cmd_switch") };
    assert_true(cat_wait_running(bus, "laser_mailbox", 5000));
    assert_true(cat_wait_running(bus, "laser_splitter", 5000));
    assert_true(cat_wait_running(bus, "state", 5000));
    assert_true(cat_wait_running(bus, "cmd_switch", 5000));
    /* the splitter renames POSE_RAW to POSE */
    lcm_subscription_t *sub = lcm_subscribe(cat_lcm(bus), "POSE", on_pose, NULL);
    marie_pose2d_t p = { .x = 1 };
    marie_pose2d_t_publish(cat_lcm(bus), "POSE_RAW", &p);
    assert_true(cat_spin(bus, 2000, got_pose, NULL));
    lcm_unsubscribe(cat_lcm(bus), sub);
    /* the SharedMap listens on its configured channel and keeps its log in MARIE_STATE_DIR */
    sharedmap_client_t *cl = sharedmap_client_create(cat_lcm(bus), "STATE", "t");
    assert_int_equal(sharedmap_client_set(cl, "k", &marie_type_pose2d_t, &p, 1000), 0);
    sharedmap_client_destroy(cl);
    char path[400];
    snprintf(path, sizeof path, "%s/state.sharedmap", dir);
    assert_int_equal(access(path, F_OK), 0);
    for (int i = 0; i < 4; i++) {
        int st = cat_stop(pids[i], SIGTERM);
        assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
    }
    cat_bus_destroy(bus);
    cat_rmdir(dir);
}

static void test_bad_type_fails_with_reason(void **state)
{
    cat_bus_t *bus = cat_bus_create();
    pid_t pid = start("mailbox", "bad_type");
    /* it stays up as failed, so its manager sees why */
    char reason[256] = "";
    assert_true(cat_wait_state(bus, "bad_type", 4 /* MARIE_STATE_FAILED */, 5000, reason, sizeof reason));
    assert_non_null(strstr(reason, "unknown LCM type 'marie.no_such_t'"));
    assert_true(cat_alive(pid));
    cat_stop(pid, SIGTERM);
    cat_bus_destroy(bus);
}

static void test_unknown_parameter_is_config_error(void **state)
{
    pid_t pid = start("splitter", "bad_param");
    int st;
    waitpid(pid, &st, 0);
    assert_true(WIFEXITED(st));
    assert_int_equal(WEXITSTATUS(st), 2);
    /* an unknown kind too */
    pid = start("nonsense", "x");
    waitpid(pid, &st, 0);
    assert_int_equal(WEXITSTATUS(st), 2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_all_kinds_run_from_the_system_file),
        cmocka_unit_test(test_bad_type_fails_with_reason),
        cmocka_unit_test(test_unknown_parameter_is_config_error),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
