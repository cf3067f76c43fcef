/* test_mission: goals are pursued by priority, reached within tolerance, skipped past their
 * deadlines, and a restored mission continues where it stopped. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "adapters/mission/mission.h"

typedef struct {
    char log[1024];
} events_t;

static void on_event(void *user, const char *kind, const mission_goal_t *g, const char *text)
{
    events_t *e = user;
    char buf[64];
    snprintf(buf, sizeof(buf), "%s:%d ", kind, g ? g->id : 0);
    strncat(e->log, buf, sizeof(e->log) - strlen(e->log) - 1);
}

static mission_t parse(const char *yaml)
{
    marie_errors_t errs = { 0 };
    marie_doc_t *doc = marie_doc_parse("goals.yaml", yaml, strlen(yaml), &errs);
    assert_non_null(doc);
    mission_t m;
    mission_init(&m);
    int n = mission_parse(&m, marie_doc_root(doc), 0.3, &errs);
    if (n < 0)
        marie_errors_print(&errs, stderr);
    assert_true(n > 0);
    marie_doc_destroy(doc);
    return m;
}

static const char *goals =
    "- {name: a, x: 1, y: 0}\n"
    "- {name: b, x: 2, y: 0, priority: 5}\n"
    "- {name: c, x: 3, y: 0, deadline: 10}\n"
    "- {name: d, x: 4, y: 0, tolerance: 0.1, theta: 1.5}\n";

static void test_priority_then_deadline_then_order(void **state)
{
    mission_t m = parse(goals);
    events_t e = { { 0 } };
    double far[3] = { 9, 9, 0 };
    mission_update(&m, 1000000, far, on_event, &e);
    assert_int_equal(m.current, 1);          /* b: priority 5 */
    assert_string_equal(e.log, "goal_started:2 ");
    double at_b[3] = { 2.1, 0.1, 0 };
    mission_update(&m, 2000000, at_b, on_event, &e);
    assert_int_equal(m.current, 2);          /* c: has a deadline, a does not */
    double at_c[3] = { 3, 0.25, 0 };
    mission_update(&m, 3000000, at_c, on_event, &e);
    assert_int_equal(m.current, 0);          /* then list order */
    double at_a[3] = { 1, 0, 0 };
    mission_update(&m, 4000000, at_a, on_event, &e);
    assert_int_equal(m.current, 3);
    double near_d[3] = { 4.15, 0, 0 };      /* outside d's own 0.1 m tolerance */
    mission_update(&m, 5000000, near_d, on_event, &e);
    assert_int_equal(m.current, 3);
    near_d[0] = 4.05;
    mission_update(&m, 6000000, near_d, on_event, &e);
    assert_true(m.done);
    assert_string_equal(e.log, "goal_started:2 goal_reached:2 goal_started:3 goal_reached:3 goal_started:1 "
                               "goal_reached:1 goal_started:4 goal_reached:4 mission_done:0 ");
    assert_int_equal(m.reached, 4);
}

static void test_deadlines_skip_goals(void **state)
{
    mission_t m = parse("- {x: 1, y: 0, deadline: 5, priority: 2}\n- {x: 2, y: 0, deadline: 8, priority: 1}\n- {x: 3, y: 0}\n");
    events_t e = { { 0 } };
    double far[3] = { 9, 9, 0 };
    mission_update(&m, 0, far, on_event, &e);
    assert_int_equal(m.current, 0);
    /* Goal 1 runs out of time at 5 s; goal 2 is then current; at 9 s it is missed as well. */
    mission_update(&m, 5500000, far, on_event, &e);
    assert_int_equal(m.current, 1);
    mission_update(&m, 9000000, far, on_event, &e);
    assert_int_equal(m.current, 2);
    assert_int_equal(m.missed, 2);
    /* No pose: nothing is reached, the mission waits. */
    mission_update(&m, 20000000, NULL, on_event, &e);
    assert_int_equal(m.current, 2);
    assert_false(m.done);
    assert_string_equal(e.log, "goal_started:1 goal_missed:1 goal_started:2 goal_missed:2 goal_started:3 ");
}

static void test_pending_goal_skipped_while_other_runs(void **state)
{
    mission_t m = parse("- {x: 1, y: 0, priority: 9}\n- {x: 2, y: 0, deadline: 3}\n");
    events_t e = { { 0 } };
    double far[3] = { 9, 9, 0 };
    mission_update(&m, 0, far, on_event, &e);
    mission_update(&m, 4000000, far, on_event, &e);
    assert_int_equal(m.state[1], MISSION_MISSED);
    assert_int_equal(m.current, 0);
}

static void test_restore_continues(void **state)
{
    mission_t m = parse(goals);
    int32_t ids[4] = { 1, 2, 3, 4 };
    int8_t st[4] = { MISSION_PENDING, MISSION_REACHED, MISSION_ACTIVE, MISSION_PENDING };
    assert_int_equal(mission_restore(&m, 500, 2, ids, st, 4), 0);
    assert_int_equal(m.reached, 1);
    events_t e = { { 0 } };
    double at_c[3] = { 3, 0, 0 };
    mission_update(&m, 1000000, at_c, on_event, &e);
    assert_int_equal(m.start_utime, 500);
    assert_string_equal(e.log, "goal_reached:3 goal_started:1 ");
    /* Another mission's state (other ids, other count) is refused and changes nothing. */
    int32_t other[4] = { 1, 2, 3, 5 };
    assert_int_equal(mission_restore(&m, 0, 0, other, st, 4), -1);
    assert_int_equal(mission_restore(&m, 0, 0, ids, st, 3), -1);
    int8_t bad[4] = { 0, 0, 9, 0 };
    assert_int_equal(mission_restore(&m, 0, 0, ids, bad, 4), -1);
    assert_int_equal(m.start_utime, 500);
    /* A finished mission restored is declared done again without new events for goals. */
    int8_t all[4] = { MISSION_REACHED, MISSION_REACHED, MISSION_MISSED, MISSION_REACHED };
    assert_int_equal(mission_restore(&m, 500, -1, ids, all, 4), 0);
    e.log[0] = 0;
    mission_update(&m, 2000000, at_c, on_event, &e);
    assert_true(m.done);
    assert_string_equal(e.log, "mission_done:0 ");
}

static void test_give_up_unreachable(void **state)
{
    mission_t m = parse("- {x: 1, y: 0}\n- {x: 2, y: 0}\n");
    events_t e = { { 0 } };
    double far[3] = { 9, 9, 0 };
    mission_update(&m, 0, far, on_event, &e);
    mission_give_up(&m, "no path", on_event, &e);
    mission_update(&m, 1000000, far, on_event, &e);
    assert_int_equal(m.state[0], MISSION_MISSED);
    assert_int_equal(m.current, 1);
    assert_string_equal(e.log, "goal_started:1 goal_missed:1 goal_started:2 ");
    mission_give_up(&m, "no path", on_event, &e);
    mission_give_up(&m, "no path", on_event, &e);   /* nothing current: no-op */
    assert_int_equal(m.missed, 2);
}

static void test_bad_goal_lists(void **state)
{
    const char *bad[] = { "x: 1\n", "- {x: 1}\n", "- {x: 1, y: 2, speed: 3}\n", "- {x: a, y: 2}\n",
                          "- {x: 1, y: 2, deadline: -1}\n", "- {x: 1, y: 2, id: 3}\n- {x: 2, y: 2, id: 3}\n",
                          "- 5\n", "- {x: 1, y: 2, tolerance: 0}\n" };
    for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
        marie_errors_t errs = { 0 };
        marie_doc_t *doc = marie_doc_parse("goals.yaml", bad[i], strlen(bad[i]), &errs);
        assert_non_null(doc);
        mission_t m;
        mission_init(&m);
        assert_int_equal(mission_parse(&m, marie_doc_root(doc), 0.3, &errs), -1);
        assert_true(errs.n >= 1);
        assert_non_null(strstr(errs.msgs[0], "goals.yaml:"));
        marie_errors_clear(&errs);
        marie_doc_destroy(doc);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_priority_then_deadline_then_order),
        cmocka_unit_test(test_deadlines_skip_goals),
        cmocka_unit_test(test_pending_goal_skipped_while_other_runs),
        cmocka_unit_test(test_restore_continues),
        cmocka_unit_test(test_give_up_unreachable),
        cmocka_unit_test(test_bad_goal_lists),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
