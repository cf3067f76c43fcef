/* test_vision_msgmap: the messages list maps tag ids to events and goals, and every mistake
 * in it is reported with its file:line:col. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "adapters/vision/vision_msgmap.h"
#include "lcmtypes/marie_event_t.h"
#include "tests/fails.h"

static int parse(const char *yaml, vision_msgmap_t *m, marie_errors_t *errs)
{
    marie_doc_t *d = marie_doc_parse("messages.yaml", yaml, strlen(yaml), errs);
    assert_non_null(d);
    int rc = vision_msgmap_parse(marie_doc_root(d), m, errs);
    int err = errno;
    marie_doc_destroy(d);
    errno = err;
    return rc;
}

static void test_ids_map_to_events_and_goals(void **state)
{
    vision_msgmap_t m;
    marie_errors_t errs = { 0 };
    const char *yaml =
        "- id: 3\n"
        "  message: dock ahead\n"
        "  kind: dock\n"
        "  severity: warn\n"
        "- id: 7\n"
        "  goal: {x: 2.5, y: -1, theta: 1.57, tolerance: 0.1, priority: 3, name: charger, id: 70}\n"
        "- id: 8\n"
        "  message: lab door\n"
        "  goal: {x: 1, y: 1}\n";
    assert_int_equal(parse(yaml, &m, &errs), 0);
    assert_int_equal(errs.n, 0);
    assert_int_equal(m.n, 3);
    const vision_msg_t *a = vision_msgmap_find(&m, 3);
    assert_non_null(a);
    assert_string_equal(a->text, "dock ahead");
    assert_string_equal(a->kind, "dock");
    assert_int_equal(a->severity, MARIE_EVENT_T_SEV_WARN);
    assert_false(a->has_goal);
    const vision_msg_t *b = vision_msgmap_find(&m, 7);
    assert_null(b->text);
    assert_true(b->has_goal);
    assert_true(b->x == 2.5 && b->y == -1 && b->theta == 1.57 && b->tolerance == 0.1);
    assert_int_equal(b->priority, 3);
    assert_int_equal(b->goal_id, 70);
    assert_string_equal(b->goal_name, "charger");
    const vision_msg_t *c = vision_msgmap_find(&m, 8);
    assert_string_equal(c->kind, "tag_message");
    assert_int_equal(c->severity, MARIE_EVENT_T_SEV_INFO);
    assert_int_equal(c->goal_id, 8);
    assert_true(c->tolerance == 0.2);
    assert_null(vision_msgmap_find(&m, 4));
    vision_msgmap_clear(&m);
    assert_int_equal(vision_msgmap_parse(NULL, &m, &errs), 0);
    assert_int_equal(m.n, 0);
}

static void expect_error(const char *yaml, const char *where, const char *what)
{
    vision_msgmap_t m;
    marie_errors_t errs = { 0 };
    assert_fails(parse(yaml, &m, &errs), EINVAL);
    assert_int_equal(m.n, 0);
    bool found = false;
    for (size_t i = 0; i < errs.n; i++)
        found |= strstr(errs.msgs[i], where) && strstr(errs.msgs[i], what);
    if (!found) {
        marie_errors_print(&errs, stderr);
        fail_msg("no error at '%s' saying '%s'", where, what);
    }
    marie_errors_clear(&errs);
}

static void test_mistakes_are_located(void **state)
{
    expect_error("{id: 3}", "messages.yaml:1:1", "expected a list");
    expect_error("- 3\n", "messages.yaml:1:3", "must be a map");
    expect_error("- message: hi\n", "messages.yaml:1:3", "id is required");
    expect_error("- id: -2\n  message: hi\n", "messages.yaml:1:7", "tag id >= 0");
    expect_error("- id: two\n  message: hi\n", "messages.yaml:1:7", "id");
    expect_error("- id: 2\n", "messages.yaml:1:3", "needs a message, a goal or both");
    expect_error("- id: 2\n  message: hi\n  severity: loud\n", "messages.yaml:3:13", "severity");
    expect_error("- id: 2\n  goal: {y: 1}\n", "messages.yaml:2:9", "x and y are required");
    expect_error("- id: 2\n  goal: {x: 1, y: 1, z: 4}\n", "messages.yaml:2:", "z");
    expect_error("- id: 2\n  goal: {x: .nan, y: 1}\n", "messages.yaml:2:13", "x:");
    expect_error("- id: 2\n  goal: [1, 2]\n", "messages.yaml:2:9", "expected a map");
    expect_error("- {id: 5, message: a}\n- {id: 5, message: b}\n", "messages.yaml:2:3", "mapped twice");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ids_map_to_events_and_goals),
        cmocka_unit_test(test_mistakes_are_located),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
