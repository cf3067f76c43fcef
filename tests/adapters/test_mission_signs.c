/* test_mission_signs: goals found by reading signs: parsing (mistakes located), the search
 * points followed until the sign is read, the goal moved before the sign, given up when the
 * search ends without it. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "adapters/mission/mission_request.h"
#include "adapters/mission/mission_signs.h"
#include "core/auth.h"
#include "core/time.h"

static int nevents;
static char last_kind[32], last_text[256];

static void on_ev(void *user, const char *kind, const mission_goal_t *g, const char *text)
{
    nevents++;
    snprintf(last_kind, sizeof last_kind, "%s", kind);
    snprintf(last_text, sizeof last_text, "%s", text);
}

static int load(mission_t *m, mission_signs_t *ss, const char *yaml, marie_errors_t *errs)
{
    marie_doc_t *doc = marie_doc_parse("signs.yaml", yaml, strlen(yaml), errs);
    assert_non_null(doc);
    mission_init(m);
    int n = mission_signs_parse(ss, m, marie_doc_root(doc), 0.3, errs);
    marie_doc_destroy(doc);
    return n;
}

static void test_search_then_read_then_reached(void **state)
{
    mission_t m;
    mission_signs_t ss;
    marie_errors_t errs = { 0 };
    assert_int_equal(load(&m, &ss, "- {message: room B, search: [[8, 15], [16, 15]], name: room-b}\n", &errs), 1);
    assert_int_equal(m.n, 1);
    assert_string_equal(m.goals[0].name, "room-b");
    assert_true(m.goals[0].x == 8 && m.goals[0].y == 15);
    double pose[3] = { 2, 15, 0 };
    mission_update(&m, 1000000, pose, on_ev, NULL);
    assert_int_equal(m.current, 0);
    /* At the first search point without the sign: on to the next, not reached. */
    pose[0] = 8.1;
    assert_int_equal(mission_signs_steer(&ss, &m, pose, on_ev, NULL), 1);
    mission_update(&m, 2000000, pose, on_ev, NULL);
    assert_int_equal(m.state[0], MISSION_ACTIVE);
    assert_true(m.goals[0].x == 16);
    /* Another sign changes nothing; sign B moves the goal 1 m before it, facing it. */
    assert_int_equal(mission_signs_read(&ss, &m, "room A", 5.35, 13.51, M_PI / 2, 3.0, on_ev, NULL), 0);
    assert_int_equal(mission_signs_read(&ss, &m, "room B", 12.25, 13.51, M_PI / 2, 3.5, on_ev, NULL), 1);
    assert_string_equal(last_kind, "sign_read");
    assert_non_null(strstr(last_text, "from 3.50 m"));
    assert_true(fabs(m.goals[0].x - 12.25) < 1e-9 && fabs(m.goals[0].y - 14.51) < 1e-9);
    assert_true(fabs(m.goals[0].theta + M_PI / 2) < 1e-9);
    /* Read once: a second sighting does not move it again. */
    assert_int_equal(mission_signs_read(&ss, &m, "room B", 12.3, 13.5, M_PI / 2, 2.0, on_ev, NULL), 0);
    pose[0] = 12.25;
    pose[1] = 14.45;
    assert_int_equal(mission_signs_steer(&ss, &m, pose, on_ev, NULL), 0);
    mission_update(&m, 3000000, pose, on_ev, NULL);
    assert_int_equal(m.state[0], MISSION_REACHED);
    assert_true(m.done);
}

static void test_search_ends_without_the_sign(void **state)
{
    mission_t m;
    mission_signs_t ss;
    marie_errors_t errs = { 0 };
    assert_int_equal(load(&m, &ss, "- {message: room Z, search: [[8, 15]]}\n", &errs), 1);
    double pose[3] = { 8, 15, 0 };
    mission_update(&m, 1000000, (double[3]){ 2, 15, 0 }, on_ev, NULL);
    assert_int_equal(mission_signs_steer(&ss, &m, pose, on_ev, NULL), 1);
    assert_int_equal(m.state[0], MISSION_MISSED);
    assert_string_equal(last_kind, "goal_missed");
    assert_non_null(strstr(last_text, "sign 'room Z' not read"));
}

static void test_mistakes_are_located(void **state)
{
    static const struct { const char *yaml, *want; } cases[] = {
        { "- {message: room B}\n", "signs.yaml:1:3: search: expected a list" },
        { "- {message: room B, search: [[1, x]]}\n", "signs.yaml:1:" },
        { "- {message: room B, search: [[1, 2, 3]]}\n", "search point 1: expected [x, y]" },
        { "- {search: [[1, 2]]}\n", "expected a map with message and search" },
        { "- {message: B, search: [[1, 2]], colour: red}\n", "colour" },
        { "- {message: B, search: [[1, 2]], approach: -1}\n", "approach: expected 0 < m < 10" },
        { "- {message: B, search: [[1, 2]], id: 4}\n- {message: C, search: [[1, 2]], id: 4}\n", "id 4 used twice" },
        { "{message: B}\n", "signs: expected a list" },
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        mission_t m;
        mission_signs_t ss;
        marie_errors_t errs = { 0 };
        assert_int_equal(load(&m, &ss, cases[i].yaml, &errs), -1);
        bool found = false;
        for (size_t k = 0; k < errs.n; k++)
            found |= strstr(errs.msgs[k], cases[i].want) != NULL;
        if (!found)
            fail_msg("case %zu: wanted '%s', got '%s'", i, cases[i].want, errs.n ? errs.msgs[0] : "(nothing)");
        marie_errors_clear(&errs);
    }
}

/* A person's request goes ahead of the list; the interrupted goal waits, then resumes. */
static void test_request_goes_first(void **state)
{
    mission_t m;
    mission_init(&m);
    m.goals[0] = (mission_goal_t){ .id = 1, .name = "a", .x = 10, .y = 0, .tolerance = 0.3, .priority = 5 };
    m.n = 1;
    double pose[3] = { 0, 0, 0 };
    mission_update(&m, 0, pose, NULL, NULL);
    assert_int_equal(m.current, 0);
    mission_goal_t r = { .id = 800001, .name = "lab", .x = 3, .y = 4, .tolerance = 0.3 };
    assert_int_equal(mission_request_insert(&m, &r), 0);
    mission_update(&m, 1000000, pose, NULL, NULL);
    assert_int_equal(m.current, 1);
    assert_true(m.goals[1].priority > 5);
    pose[0] = 3;
    pose[1] = 4;
    mission_update(&m, 2000000, pose, NULL, NULL);
    assert_int_equal(m.state[1], MISSION_REACHED);
    assert_int_equal(m.current, 0);            /* back to the list */
    /* After the mission is done a request starts it again. */
    pose[0] = 10;
    pose[1] = 0;
    mission_update(&m, 3000000, pose, NULL, NULL);
    mission_update(&m, 3100000, pose, NULL, NULL);
    assert_true(m.done);
    r.id = 800002;
    assert_int_equal(mission_request_insert(&m, &r), 0);
    mission_update(&m, 4000000, pose, NULL, NULL);
    assert_false(m.done);
    assert_int_equal(m.current, 2);
}

/* Goal requests are signed and checked as orders are: altered, unsigned, replayed refused. */
static void test_goal_request_signature(void **state)
{
    uint8_t key[MARIE_AUTH_KEY_LEN] = { 7 }, other[MARIE_AUTH_KEY_LEN] = { 8 };
    marie_auth_t *a = marie_auth_from_key(key), *b = marie_auth_from_key(other);
    marie_replay_t *rp = marie_replay_create(NULL);
    marie_goal_request_t r = { .utime = marie_wall_us(), .sender = "me@host/face", .seq = marie_wall_us() + 1,
                               .goal = { .id = 5, .name = "lab", .pose = { 1, 2, 0 } } };
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    assert_int_equal(marie_auth_sign_goal_request(a, &r, mac), 0);
    assert_int_equal(marie_auth_check_goal_request(b, NULL, &r), MARIE_AUTH_FORGED);
    r.goal.pose.x = 9;
    assert_int_equal(marie_auth_check_goal_request(a, NULL, &r), MARIE_AUTH_FORGED);
    r.goal.pose.x = 1;
    assert_int_equal(marie_auth_check_goal_request(a, rp, &r), MARIE_AUTH_OK);
    assert_int_equal(marie_auth_check_goal_request(a, rp, &r), MARIE_AUTH_REPLAYED);
    assert_int_equal(marie_auth_check_goal_request(NULL, rp, &r), MARIE_AUTH_NOKEY);
    r.mac_len = 0;
    assert_int_equal(marie_auth_check_goal_request(a, rp, &r), MARIE_AUTH_UNSIGNED);
    marie_replay_destroy(rp);
    marie_auth_destroy(a);
    marie_auth_destroy(b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_search_then_read_then_reached),
        cmocka_unit_test(test_search_ends_without_the_sign),
        cmocka_unit_test(test_mistakes_are_located),
        cmocka_unit_test(test_request_goes_first),
        cmocka_unit_test(test_goal_request_signature),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
