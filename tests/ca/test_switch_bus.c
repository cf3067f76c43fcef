/* test_switch_bus: a marie-ca switch process over real LCM: only the selected input is
 * forwarded, selection by message, refusal of unknown inputs with an event, the selection
 * kept across a restart, mistyped payloads counted. */
#include <errno.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_gyro_t.h"
#include "lcmtypes/marie_motor_command_t.h"
#include "lcmtypes/marie_switch_select_t.h"
#include "lcmtypes/marie_switch_state_t.h"
#include "tests/ca/ca_test.h"

static cat_bus_t *bus;
static marie_motor_command_t_subscription_t *sub_cmd;
static marie_switch_state_t_subscription_t *sub_state;
static marie_event_t_subscription_t *sub_event;
static pid_t pid;
static char dir[256], state_arg[400];

typedef struct {
    int from_auto, from_teleop, other;
    int refused_events;
    int64_t state_req;
    int8_t state_status;
    char selected[64];
} seen_t;
static seen_t seen;

static void on_cmd(const lcm_recv_buf_t *rbuf, const char *channel, const marie_motor_command_t *msg, void *user)
{
    if (strcmp(msg->source, "auto") == 0)
        seen.from_auto++;
    else if (strcmp(msg->source, "teleop") == 0)
        seen.from_teleop++;
    else
        seen.other++;
}

static void on_state(const lcm_recv_buf_t *rbuf, const char *channel, const marie_switch_state_t *msg, void *user)
{
    seen.state_req = msg->request_id;
    seen.state_status = msg->status;
    snprintf(seen.selected, sizeof seen.selected, "%s", msg->selected);
}

static void on_event(const lcm_recv_buf_t *rbuf, const char *channel, const marie_event_t *msg, void *user)
{
    if (strcmp(msg->source, "sw") == 0 && strcmp(msg->kind, "switch_unknown_input") == 0)
        seen.refused_events++;
}

static void start(void)
{
    const char *args[] = { "switch", "--name", "sw", "--param", "type=marie.motor_command_t",
        "--param", "output=CMD", "--param", "inputs={auto: CMD_AUTO, teleop: CMD_TELEOP}",
        "--param", "initial=auto", "--param", state_arg, NULL };
    pid = cat_spawn(args);
    assert_true(cat_wait_running(bus, "sw", 5000));
}

static int setup(void **state)
{
    bus = cat_bus_create();
    cat_tmpdir(dir, sizeof dir);
    snprintf(state_arg, sizeof state_arg, "state_file=%s/sw.sel", dir);
    sub_cmd = marie_motor_command_t_subscribe(cat_lcm(bus), "CMD", on_cmd, NULL);
    sub_state = marie_switch_state_t_subscribe(cat_lcm(bus), "CMD\\.STATE", on_state, NULL);
    sub_event = marie_event_t_subscribe(cat_lcm(bus), "MARIE_EVENT", on_event, NULL);
    start();
    return 0;
}

static int teardown(void **state)
{
    int st = cat_stop(pid, SIGTERM);
    marie_motor_command_t_unsubscribe(cat_lcm(bus), sub_cmd);
    marie_switch_state_t_unsubscribe(cat_lcm(bus), sub_state);
    marie_event_t_unsubscribe(cat_lcm(bus), sub_event);
    cat_bus_destroy(bus);
    cat_rmdir(dir);
    return WIFEXITED(st) && WEXITSTATUS(st) == 0 ? 0 : -1;
}

static int expect;
static bool all_in(void *user) { return seen.from_auto + seen.from_teleop + seen.other >= expect; }

/* Publish n commands on each input and let them through: wait for the n expected ones,
 * then a little longer for any that should not come. */
static void send_both(int n)
{
    memset(&seen.from_auto, 0, 3 * sizeof(int));
    for (int i = 0; i < n; i++) {
        marie_motor_command_t a = { .v = 1, .source = "auto" }, t = { .v = 2, .source = "teleop" };
        marie_motor_command_t_publish(cat_lcm(bus), "CMD_AUTO", &a);
        marie_motor_command_t_publish(cat_lcm(bus), "CMD_TELEOP", &t);
    }
    expect = n;
    cat_spin(bus, 5000, all_in, NULL);
    cat_spin(bus, 100, NULL, NULL);
}

static bool state_answered(void *user) { return seen.state_req == *(int64_t *)user; }

static void select_input(const char *name, int64_t id)
{
    marie_switch_select_t s = { .request_id = id, .requester = "test", .input = (char *)name };
    marie_switch_select_t_publish(cat_lcm(bus), "CMD.SELECT", &s);
    assert_true(cat_spin(bus, 2000, state_answered, &id));
}

static void test_forwards_only_selected(void **state)
{
    send_both(10);
    assert_int_equal(seen.from_auto, 10);
    assert_int_equal(seen.from_teleop, 0);
    select_input("teleop", 1);
    assert_int_equal(seen.state_status, MARIE_SWITCH_STATE_T_STATUS_OK);
    assert_string_equal(seen.selected, "teleop");
    send_both(10);
    assert_int_equal(seen.from_auto, 0);
    assert_int_equal(seen.from_teleop, 10);
}

static void test_unknown_selection_refused_with_event(void **state)
{
    select_input("joystick", 2);
    assert_int_equal(seen.state_status, MARIE_SWITCH_STATE_T_STATUS_UNKNOWN_INPUT);
    assert_string_equal(seen.selected, "teleop");
    cat_spin(bus, 200, NULL, NULL);
    assert_int_equal(seen.refused_events, 1);
    send_both(5);
    assert_int_equal(seen.from_teleop, 5);
    assert_int_equal(seen.from_auto, 0);
}

static void test_selection_survives_restart(void **state)
{
    assert_true(WIFSIGNALED(cat_stop(pid, SIGKILL)));
    start();
    send_both(5);
    assert_int_equal(seen.from_teleop, 5);      /* not the configured initial 'auto' */
    assert_int_equal(seen.from_auto, 0);
}

static void test_mistyped_and_malformed_counted(void **state)
{
    marie_gyro_t g = {0};
    marie_gyro_t_publish(cat_lcm(bus), "CMD_TELEOP", &g);
    lcm_publish(cat_lcm(bus), "CMD.SELECT", "\x01\x02\x03", 3);
    marie_gyro_t_publish(cat_lcm(bus), "CMD.SELECT", &g);
    cat_spin(bus, 200, NULL, NULL);
    assert_int_equal(seen.other, 0);    /* nothing but motor commands came out */
    assert_true(cat_wait_counter(bus, "sw", "bad_fingerprint", 1, 3000, NULL));
    assert_true(cat_wait_counter(bus, "sw", "bad_request", 2, 3000, NULL));
    assert_true(cat_wait_counter(bus, "sw", "bad_input", 3, 3000, NULL));
    assert_true(cat_alive(pid));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_forwards_only_selected),
        cmocka_unit_test(test_unknown_selection_refused_with_event),
        cmocka_unit_test(test_selection_survives_restart),
        cmocka_unit_test(test_mistyped_and_malformed_counted),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
