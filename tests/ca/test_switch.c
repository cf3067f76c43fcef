/* test_switch: selection, persistence across re-creation, refusal of unknown inputs, without a bus. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "ca/switch.h"
#include "lcmtypes/marie_motor_command_t.h"
#include "lcmtypes/marie_gyro_t.h"
#include "lcmtypes/marie_switch_state_t.h"
#include "tests/fails.h"

typedef struct {
    int out, states, events_refused, bad;
    marie_switch_state_t last;
    int have_last;
} capture_t;

static int cap_publish(void *user, const char *channel, const void *buf, size_t len)
{
    capture_t *c = user;
    if (strcmp(channel, "CMD") == 0)
        c->out++;
    if (strcmp(channel, "CMD.STATE") == 0) {
        if (c->have_last)
            marie_switch_state_t_decode_cleanup(&c->last);
        assert_true(marie_switch_state_t_decode(buf, 0, (int)len, &c->last) >= 0);
        c->have_last = 1;
        c->states++;
    }
    return 0;
}

static void cap_note(void *user, ca_note_kind_t kind, const char *counter, int64_t n, const char *text)
{
    capture_t *c = user;
    if (kind == CA_NOTE_EVENT && strcmp(counter, "switch_unknown_input") == 0)
        c->events_refused++;
    if (kind == CA_NOTE_BAD_INPUT)
        c->bad++;
}

static char path[256];

static ca_switch_t *make(capture_t *c)
{
    ca_sink_t sink = { .note = cap_note, .publish = cap_publish, .user = c };
    ca_switch_t *sw = ca_switch_create("CMD", &marie_type_motor_command_t, path, &sink);
    assert_non_null(sw);
    assert_int_equal(ca_switch_add_input(sw, "auto", "CMD_AUTO"), 0);
    assert_int_equal(ca_switch_add_input(sw, "teleop", "CMD_TELEOP"), 0);
    assert_fails(ca_switch_add_input(sw, "teleop", "X"), EEXIST);
    ca_switch_set_state_channel(sw, "CMD.STATE", "sw");
    return sw;
}

static void test_forwards_selected_and_persists(void **state)
{
    snprintf(path, sizeof path, "/tmp/marie-test-switch-%d", (int)getpid());
    unlink(path);
    capture_t c = {0};
    ca_switch_t *sw = make(&c);
    assert_int_equal(ca_switch_restore(sw, "auto"), 0);
    assert_string_equal(ca_switch_selected(sw), "auto");
    uint8_t buf[128];
    marie_motor_command_t m = { .source = "test" };
    int n = marie_motor_command_t_encode(buf, 0, sizeof buf, &m);
    assert_int_equal(ca_switch_push(sw, 0, buf, (size_t)n), 1);
    assert_int_equal(ca_switch_push(sw, 1, buf, (size_t)n), 0);
    assert_int_equal(c.out, 1);

    marie_switch_select_t sel = { .request_id = 5, .requester = "op", .input = "teleop" };
    assert_int_equal(ca_switch_handle_select(sw, &sel, 1), 0);
    assert_int_equal(c.states, 1);
    assert_int_equal(c.last.status, MARIE_SWITCH_STATE_T_STATUS_OK);
    assert_string_equal(c.last.selected, "teleop");
    assert_int_equal(c.last.ninputs, 2);
    assert_int_equal(ca_switch_push(sw, 0, buf, (size_t)n), 0);
    assert_int_equal(ca_switch_push(sw, 1, buf, (size_t)n), 1);
    ca_switch_destroy(sw);

    /* a new Switch (a restart) comes back on teleop, not on its initial input */
    sw = make(&c);
    assert_int_equal(ca_switch_restore(sw, "auto"), 1);
    assert_string_equal(ca_switch_selected(sw), "teleop");
    ca_switch_destroy(sw);
    if (c.have_last)
        marie_switch_state_t_decode_cleanup(&c.last);
    unlink(path);
}

static void test_unknown_selection_refused_with_event(void **state)
{
    snprintf(path, sizeof path, "/tmp/marie-test-switch-%d", (int)getpid());
    unlink(path);
    capture_t c = {0};
    ca_switch_t *sw = make(&c);
    ca_switch_restore(sw, "auto");
    marie_switch_select_t sel = { .request_id = 9, .requester = "op", .input = "joystick" };
    assert_fails(ca_switch_handle_select(sw, &sel, 1), ENOENT);
    assert_int_equal(c.events_refused, 1);
    assert_int_equal(c.last.status, MARIE_SWITCH_STATE_T_STATUS_UNKNOWN_INPUT);
    assert_int_equal(c.last.request_id, 9);
    assert_string_equal(c.last.selected, "auto");
    assert_int_equal(ca_switch_stats(sw)->refused, 1);
    /* mistyped payloads and undecodable requests are counted and dropped */
    uint8_t buf[128];
    marie_gyro_t g = {0};
    int n = marie_gyro_t_encode(buf, 0, sizeof buf, &g);
    assert_fails(ca_switch_push(sw, 0, buf, (size_t)n), EBADMSG);
    assert_fails(ca_switch_handle_select_raw(sw, buf, (size_t)n, 1), EBADMSG);
    assert_int_equal(c.bad, 2);
    assert_int_equal(c.out, 0);
    ca_switch_destroy(sw);
    marie_switch_state_t_decode_cleanup(&c.last);
    unlink(path);
}

static void test_unsaved_selection_not_made(void **state)
{
    snprintf(path, sizeof path, "/nonexistent-dir/sw.sel");
    capture_t c = {0};
    ca_switch_t *sw = make(&c);
    ca_switch_restore(sw, "auto");
    marie_switch_select_t sel = { .request_id = 3, .requester = "op", .input = "teleop" };
    assert_fails(ca_switch_handle_select(sw, &sel, 1), EIO);
    assert_int_equal(c.last.status, MARIE_SWITCH_STATE_T_STATUS_IO_ERROR);
    assert_string_equal(ca_switch_selected(sw), "auto");
    ca_switch_destroy(sw);
    marie_switch_state_t_decode_cleanup(&c.last);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_forwards_selected_and_persists),
        cmocka_unit_test(test_unknown_selection_refused_with_event),
        cmocka_unit_test(test_unsaved_selection_not_made),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
