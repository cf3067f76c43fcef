/* test_kidnap: the kidnapped robot. marie-sim, marie-odometry, marie-localizer and (but in the
 * first case) marie-behaviours run over real LCM on the simulator's clock; the robot is carried
 * (SIM_TELEPORT) with no wheel turning. The localizer must notice (heartbeat degraded, `lost`
 * event) and find the robot again at its true pose, turning it by itself when nothing else moves
 * it (test_relocalize: a wrong start, a look-alike place). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "lcmtypes/marie_types.h"
#include "tests/nav/navrig.h"

static int relocalized(const rig_t *r)
{
    return r->running_again_at && r->pose_utime > r->running_again_at - 1000000 && rig_error(r) < 0.5;
}

/* Turning on the spot (the test turns it): no false alarm in 20 s; carried behind wall A of the
 * test world, it is lost within 20 s and found at its true pose within 90 s. */
static void kidnapped_robot_is_found_again(void **state)
{
    rig_t *r = rig_open("test_kidnap_turning");
    rig_start_sim(r, "test", 3.0, 2.0, 0.0, NULL);
    rig_start_localizer(r, "sim/worlds/test.yaml", 3.0, 2.0, 0.0);
    rig_run(r, 20, true, 0, 0.4, NULL);
    printf("before: %lld poses, error %.2f m, state %d, lost %lld\n", (long long)r->npose, rig_error(r), r->loc_state,
           (long long)r->lost);
    assert_true(r->npose > 50);
    assert_true(rig_error(r) < 0.2);
    assert_int_equal(r->lost, 0);
    assert_int_equal(r->loc_state, MARIE_LIFECYCLE_COMMAND_T_STATE_RUNNING);
    rig_teleport(r, 8.5, 6.0, 2.5);
    int64_t kidnap_at = r->sim_us;
    rig_run(r, 5, true, 0, 0.4, NULL);
    assert_true(hypot(r->truth[0] - 8.5, r->truth[1] - 6.0) < 0.3);     /* the simulator did carry it */
    rig_run(r, 120, true, 0, 0.4, relocalized);
    double t_lost = r->degraded_at ? (r->degraded_at - kidnap_at) / 1e6 : -1;
    double t_back = r->running_again_at ? (r->running_again_at - kidnap_at) / 1e6 : -1;
    printf("kidnapped at %.1f s: lost after %.1f s, relocalized after %.1f s, error %.2f m, lost %lld, found %lld\n",
           kidnap_at / 1e6, t_lost, t_back, rig_error(r), (long long)r->lost, (long long)r->found);
    assert_true(r->lost >= 1);                           /* detected ... */
    assert_true(t_lost > 0 && t_lost < 20);             /* ... soon, and said so in the heartbeat */
    assert_true(t_back > 0 && t_back < 90);             /* found again within a bounded time */
    assert_true(r->found >= 1);
    assert_true(rig_error(r) < 0.5);                   /* at the true pose */
    assert_int_equal(r->loc_state, MARIE_LIFECYCLE_COMMAND_T_STATE_RUNNING);
}

/* Standing still, carried behind wall A: nobody drives the robot, yet it is found again, because
 * the lost localizer turns it (its search through marie-behaviours). */
static void a_lost_robot_turns_and_finds_itself(void **state)
{
    rig_t *r = rig_open("test_kidnap_still");
    rig_start_sim(r, "test", 3.0, 2.0, 0.0, NULL);
    rig_start_localizer(r, "sim/worlds/test.yaml", 3.0, 2.0, 0.0);
    rig_start(r, "behaviours", "input_mode=subscribe", NULL);
    rig_run(r, 5, false, 0, 0, NULL);
    assert_true(rig_error(r) < 0.2);
    rig_teleport(r, 8.5, 6.0, 2.5);
    int64_t kidnap_at = r->sim_us;
    rig_run(r, 3, false, 0, 0, NULL);
    double turned0 = r->turned;
    rig_run(r, 90, false, 0, 0, relocalized);
    printf("standing: lost %lld after %.1f s, turned %.1f rad, found %lld after %.1f s, error %.2f m\n",
           (long long)r->lost, r->degraded_at ? (r->degraded_at - kidnap_at) / 1e6 : -1, r->turned - turned0,
           (long long)r->found, r->running_again_at ? (r->running_again_at - kidnap_at) / 1e6 : -1, rig_error(r));
    assert_true(r->lost >= 1);
    assert_true(r->turned - turned0 > 3.0);              /* it turned by itself to see */
    assert_true(relocalized(r));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(kidnapped_robot_is_found_again, rig_teardown),
        cmocka_unit_test_teardown(a_lost_robot_turns_and_finds_itself, rig_teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
