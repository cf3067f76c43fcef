/* test_relocalize: a robot that is not where the localizer thinks, standing still. marie-sim,
 * marie-odometry, marie-localizer and marie-behaviours run over real LCM on the simulator's clock;
 * the robot starts with a wrong pose, or is carried (SIM_TELEPORT) into a look-alike place. The
 * localizer must notice (heartbeat degraded, `lost` event) and find the robot at its true pose,
 * turning and driving it by itself, or say that it cannot rather than take a look-alike place. */
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

static int found_or_asked(const rig_t *r)
{
    return (r->found_at && r->pose_utime > r->found_at) || r->asked_at;
}

/* Started 7 m off in free space of the office, standing: the scans at start contradict the map,
 * the robot is lost (not `running` 7 m off), turns, and is found where it stands. */
static void a_wrong_start_is_found_standing(void **state)
{
    rig_t *r = rig_open("test_relocalize_wrong_start");
    rig_start_sim(r, "office", 10.0, 15.0, 0.3, NULL);
    rig_start_localizer(r, "sim/worlds/office.yaml", 17.0, 15.0, 0.3);
    rig_start(r, "behaviours", "input_mode=subscribe", NULL);
    rig_run(r, 90, false, 0, 0, relocalized);
    printf("wrong start: lost %lld after %.1f s, found %lld after %.1f s, error %.2f m, state %d\n", (long long)r->lost,
           r->degraded_at / 1e6, (long long)r->found, r->running_again_at / 1e6, rig_error(r), r->loc_state);
    assert_true(r->lost >= 1);
    assert_true(r->degraded_at > 0 && r->degraded_at < 30000000);
    assert_true(relocalized(r));
}

/* Carried into the office's cross corridor, whose other half is its mirror image: the robot must
 * not be found at a look-alike place. It either tells the places apart by driving on, or stops
 * and asks for a pose; a pose it publishes after `relocalized` is the true one. */
static void a_look_alike_place_is_not_taken(void **state)
{
    rig_t *r = rig_open("test_relocalize_look_alike");
    rig_start_sim(r, "office", 2.0, 15.0, 0.0, "speed=6");
    rig_start_localizer(r, "sim/worlds/office.yaml", 2.0, 15.0, 0.0);
    rig_start(r, "behaviours", "input_mode=subscribe", NULL);
    rig_run(r, 4, false, 0, 0, NULL);
    rig_teleport(r, 20.0, 3.0, 1.3);
    rig_run(r, 260, false, 0, 0, found_or_asked);
    rig_run(r, 2, false, 0, 0, NULL);
    printf("look-alike: lost %lld, found %lld (%.2f, %.2f) truth (%.2f, %.2f), asked %lld: %s\n", (long long)r->lost,
           (long long)r->found, r->found_pose[0], r->found_pose[1], r->truth[0], r->truth[1], (long long)r->asked, r->loc_reason);
    assert_true(r->lost >= 1);
    assert_true(r->found_at || r->asked_at);
    if (r->found_at)
        assert_true(hypot(r->found_pose[0] - r->truth[0], r->found_pose[1] - r->truth[1]) < 0.5);
    else
        assert_non_null(strstr(r->loc_reason, "send a pose on INITIALPOSE"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(a_wrong_start_is_found_standing, rig_teardown),
        cmocka_unit_test_teardown(a_look_alike_place_is_not_taken, rig_teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
