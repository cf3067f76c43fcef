/* test_arbiter: each behaviour's vote and the priority arbitration between them. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>

#include "adapters/behaviours/arbiter.h"
#include "adapters/behaviours/recovery.h"

static float open_scan[181];

static arb_inputs_t base_inputs(void)
{
    for (int k = 0; k < 181; k++)
        open_scan[k] = 10.0f;
    arb_inputs_t in;
    memset(&in, 0, sizeof(in));
    in.pose_age = in.path_age = in.estop_age = in.teleop_age = in.reloc_age = in.scan_age = -1;
    in.ranges = open_scan;
    in.nranges = 181;
    in.angle_min = -M_PI / 2;
    in.angle_increment = M_PI / 180;
    in.range_min = 0.02;
    in.range_max = 30;
    in.scan_age = 0.05;
    return in;
}

static const double straight[] = { 0, 0, 0, 2, 0, 0, 4, 0, 0 };

static void test_idle_without_inputs(void **state)
{
    arb_params_t p; arb_params_default(&p);
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    arb_vote_t v[ARB_COUNT];
    int w = arb_decide(&p, &s, &in, v);
    assert_int_equal(w, ARB_IDLE);
    assert_true(v[w].v == 0 && v[w].omega == 0);
    assert_false(v[ARB_FOLLOW].active);
    assert_string_equal(v[ARB_FOLLOW].reason, "no path");
}

static void test_follow_drives_along_path(void **state)
{
    arb_params_t p; arb_params_default(&p);
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    in.path = straight; in.npath = 3; in.path_age = 0.1; in.pose_age = 0.05;
    arb_vote_t v[ARB_COUNT];
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_FOLLOW);
    assert_true(v[ARB_FOLLOW].v > 0.3);
    assert_true(fabs(v[ARB_FOLLOW].omega) < 1e-9);
    /* Left of the path: steer right (clockwise, negative omega). */
    in.pose[1] = 0.3;
    arb_decide(&p, &s, &in, v);
    assert_true(v[ARB_FOLLOW].omega < -0.1);
    /* Facing away: turn in place. */
    in.pose[1] = 0; in.pose[2] = M_PI;
    arb_decide(&p, &s, &in, v);
    assert_true(v[ARB_FOLLOW].v == 0 && fabs(v[ARB_FOLLOW].omega) > 0.5);
}

static void test_follow_stops_at_end_and_on_stale_pose(void **state)
{
    arb_params_t p; arb_params_default(&p);
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    in.path = straight; in.npath = 3; in.path_age = 0.1; in.pose_age = 2.0;
    arb_vote_t v[ARB_COUNT];
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_IDLE);
    assert_non_null(strstr(v[ARB_FOLLOW].reason, "stale"));
    in.pose_age = 0.1;
    in.pose[0] = 3.95;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_IDLE);
    assert_string_equal(v[ARB_FOLLOW].reason, "path done");
    /* A path or pose with NaN in it is not followed (and never reaches the motors). */
    double bad[] = { 0, 0, 0, NAN, 1, 0 };
    arb_state_reset(&s);
    in.pose[0] = 0;
    in.path = bad; in.npath = 2;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_IDLE);
    in.path = straight; in.npath = 3;
    in.pose[2] = NAN;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_IDLE);
    in.pose[2] = 0;
    /* A failed plan is not followed. */
    arb_state_reset(&s);
    in.pose[0] = 0; in.path_status = 1;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_IDLE);
}

/* A speaker behind and to the left: the robot turns left on the spot until it faces them,
 * once; then the path it was given drives it, even when that turns it away again. */
static void test_face_speaker_turns_once_then_follow(void **state)
{
    arb_params_t p; arb_params_default(&p);
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    in.path = straight; in.npath = 3; in.path_age = 0.1; in.pose_age = 0.05;
    in.face_id = 1; in.face_heading = 2.0; in.face_age = 0.1;
    arb_vote_t v[ARB_COUNT];
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_FACE);
    assert_true(v[ARB_FACE].v == 0 && v[ARB_FACE].omega > 0.5);
    assert_true(v[ARB_FACE].omega <= p.omega_max);
    /* Closed loop at 5 Hz: faced within the tolerance in a few seconds, then never again. */
    int cycles = 0;
    while (arb_decide(&p, &s, &in, v) == ARB_FACE && cycles < 50) {
        in.pose[2] += v[ARB_FACE].omega * 0.2;
        cycles++;
    }
    assert_true(cycles > 3 && cycles < 25);
    assert_true(fabs(remainder(in.pose[2] - 2.0, 2 * M_PI)) < p.face_tolerance + 0.3 * 0.2);
    assert_string_equal(v[ARB_FACE].reason, "speaker faced");
    in.pose[2] = 0;     /* the path turned it back: follow keeps winning */
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_FOLLOW);
    /* A new utterance is a new request: faced again; the shorter way round (right). */
    in.face_id = 2; in.face_heading = -1.5;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_FACE);
    assert_true(v[ARB_FACE].omega < 0);
    /* Too old, or no pose: nothing to turn to. */
    in.face_id = 3; in.face_age = 10;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_FOLLOW);
    in.face_age = 0.1; in.pose_age = -1;
    assert_false(arb_decide(&p, &s, &in, v) == ARB_FACE);
    /* Below teleop and e-stop. */
    in.pose_age = 0.05; in.teleop_age = 0.1; in.teleop_v = 0.2;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_TELEOP);
    in.estop_age = 0.1; in.estop_pressed = true;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_ESTOP);
}

static void test_estop_beats_everything(void **state)
{
    arb_params_t p; arb_params_default(&p);
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    in.path = straight; in.npath = 3; in.path_age = 0.1; in.pose_age = 0.05;
    in.teleop_age = 0.1; in.teleop_v = 0.4;
    in.estop_age = 0.1; in.estop_pressed = true;
    arb_vote_t v[ARB_COUNT];
    int w = arb_decide(&p, &s, &in, v);
    assert_int_equal(w, ARB_ESTOP);
    assert_true(v[w].v == 0 && v[w].omega == 0);
    assert_true(v[ARB_TELEOP].active && v[ARB_FOLLOW].active);
    in.estop_pressed = false;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_TELEOP);
    /* With e-stop required, silence from the e-stop input stops the robot. */
    p.estop_required = true;
    in.estop_age = 5.0;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_ESTOP);
    in.estop_age = -1;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_ESTOP);
}

static void test_teleop_only_while_recent(void **state)
{
    arb_params_t p; arb_params_default(&p);
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    in.path = straight; in.npath = 3; in.path_age = 0.1; in.pose_age = 0.05;
    in.teleop_age = 0.2; in.teleop_v = 9.0; in.teleop_omega = -0.3;
    arb_vote_t v[ARB_COUNT];
    int w = arb_decide(&p, &s, &in, v);
    assert_int_equal(w, ARB_TELEOP);
    assert_true(v[w].v == p.v_max);      /* clamped */
    assert_true(v[w].omega == -0.3);
    in.teleop_age = 0.8;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_FOLLOW);
}

/* The lost localizer's search moves the robot while its commands are recent: above following
 * a path, below the operator; its turn on the spot is not vetoed by a wall ahead, its drive is. */
static void test_relocalize_search_between_teleop_and_follow(void **state)
{
    arb_params_t p; arb_params_default(&p);
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    in.path = straight; in.npath = 3; in.path_age = 0.1; in.pose_age = 0.05;
    in.reloc_age = 0.1; in.reloc_v = 0; in.reloc_omega = 0.5;
    arb_vote_t v[ARB_COUNT];
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_RELOC);
    assert_true(v[ARB_RELOC].v == 0 && v[ARB_RELOC].omega == 0.5);
    in.teleop_age = 0.1; in.teleop_v = 0.2;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_TELEOP);
    in.teleop_age = -1;
    for (int k = 80; k < 100; k++)
        open_scan[k] = 0.3f;            /* a wall just ahead */
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_RELOC);
    in.reloc_v = 0.25; in.reloc_omega = 0;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_AVOID);
    in.reloc_age = 0.8;                 /* the search stopped: nothing moves the robot for it */
    for (int k = 80; k < 100; k++)
        open_scan[k] = 10.0f;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_FOLLOW);
    assert_string_equal(v[ARB_RELOC].reason, "localized");
}

static void test_avoid_blocks_and_turns_to_open_side(void **state)
{
    arb_params_t p; arb_params_default(&p);
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    in.path = straight; in.npath = 3; in.path_age = 0.1; in.pose_age = 0.05;
    /* A box 0.25 m ahead; the right side is walled at 0.5 m, the left open. */
    for (int k = 80; k <= 100; k++)
        open_scan[k] = 0.25f;
    for (int k = 0; k < 60; k++)
        open_scan[k] = 0.5f;
    arb_vote_t v[ARB_COUNT];
    int w = arb_decide(&p, &s, &in, v);
    assert_int_equal(w, ARB_AVOID);
    assert_true(v[w].v == 0);
    assert_true(v[w].omega > 0);
    /* Farther away: slows down instead of stopping. */
    for (int k = 80; k <= 100; k++)
        open_scan[k] = 0.5f;
    w = arb_decide(&p, &s, &in, v);
    assert_int_equal(w, ARB_AVOID);
    assert_true(v[w].v > 0 && v[w].v < p.v_max * 0.5);
    /* A wall beside the robot (outside its swept width) does not trigger. */
    in = base_inputs();
    in.path = straight; in.npath = 3; in.path_age = 0.1; in.pose_age = 0.05;
    for (int k = 0; k < 30; k++)
        open_scan[k] = 0.45f;   /* -90..-60 deg at 0.45 m: y <= -0.39 */
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_FOLLOW);
    /* A stale scan cannot vouch for anything. */
    in.scan_age = 3;
    arb_decide(&p, &s, &in, v);
    assert_false(v[ARB_AVOID].active);
}

static void test_closed_loop_follows_l_path(void **state)
{
    /* Unicycle driven at 5 Hz by the arbitration along an L: reaches the end, stays near the path. */
    const double L[] = { 0, 0, 0, 3, 0, 0, 3, 3, 0, 1, 3, 0 };
    arb_params_t p; arb_params_default(&p);
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    in.path = L; in.npath = 4; in.path_age = 0.1; in.pose_age = 0.05;
    in.pose[2] = 0.5;
    double maxdev = 0;
    int cycles = 0;
    arb_vote_t v[ARB_COUNT];
    for (; cycles < 300; cycles++) {
        int w = arb_decide(&p, &s, &in, v);
        if (w == ARB_IDLE)
            break;
        assert_int_equal(w, ARB_FOLLOW);
        for (int k = 0; k < 10; k++) {     /* 0.2 s in 20 ms steps */
            in.pose[0] += v[w].v * 0.02 * cos(in.pose[2]);
            in.pose[1] += v[w].v * 0.02 * sin(in.pose[2]);
            in.pose[2] += v[w].omega * 0.02;
        }
        double x = in.pose[0], y = in.pose[1];
        double d = fmin(fmin(fabs(y) + (x > 3 ? x - 3 : x < 0 ? -x : 0), fabs(x - 3) + (y < 0 ? -y : y > 3 ? y - 3 : 0)),
                        fabs(y - 3) + (x > 3 ? x - 3 : x < 1 ? 1 - x : 0));
        if (d > maxdev)
            maxdev = d;
    }
    printf("L path: %d cycles, max deviation %.2f m, end (%.2f, %.2f)\n", cycles, maxdev, in.pose[0], in.pose[1]);
    assert_true(cycles < 300);
    assert_true(hypot(in.pose[0] - 1, in.pose[1] - 3) < p.goal_tolerance);
    assert_true(maxdev < 0.35);
}

static void test_new_path_restarts_progress(void **state)
{
    arb_params_t p; arb_params_default(&p);
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    in.path = straight; in.npath = 3; in.path_age = 0.1; in.pose_age = 0.05;
    in.pose[0] = 3.0;
    arb_vote_t v[ARB_COUNT];
    arb_decide(&p, &s, &in, v);
    assert_int_equal(s.progress, 1);
    const double back[] = { 3, 0, 0, 0, 0, 0 };
    in.path = back; in.npath = 2; in.path_goal = 2;
    arb_decide(&p, &s, &in, v);
    assert_int_equal(s.progress, 0);
    assert_true(v[ARB_FOLLOW].active && v[ARB_FOLLOW].v == 0);   /* turns around first */
}

/* The laser of a robot at (x, y, th) in a corridor between walls y = lo and y = hi. */
static void corridor_scan(arb_inputs_t *in, double lo, double hi)
{
    for (int k = 0; k < 181; k++) {
        double phi = in->pose[2] + in->angle_min + k * in->angle_increment, r = 30;
        if (sin(phi) < -1e-9)
            r = fmin(r, (lo - in->pose[1]) / sin(phi));
        if (sin(phi) > 1e-9)
            r = fmin(r, (hi - in->pose[1]) / sin(phi));
        open_scan[k] = (float)r;
    }
}

static void test_turn_in_a_doorway_is_not_vetoed(void **state)
{
    /* Seen in marie-demo --chaos 3: the robot in a doorway (jambs 0.45 m either side) gets
     * a new path that leaves the way it came. Follow turns round towards it; half way the
     * jamb is ahead, avoid turns back to the open side, follow turns again: the robot spun
     * on the spot for a minute. Turning in place is safe: it must come round and drive off. */
    arb_params_t p; arb_params_default(&p);
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    const double back[] = { 0.5, 0, 0, -6, 0, 0 };
    in.path = back; in.npath = 2; in.path_age = 0.1; in.pose_age = 0.05;
    in.pose[0] = 0.5; in.pose[1] = 0; in.pose[2] = 0.2;
    double lo = -0.45, hi = 0.45, closest = 10;
    arb_vote_t v[ARB_COUNT];
    int cycles = 0;
    double cmd_v = 0, cmd_w = 0;    /* the drives act on the previous cycle's command */
    for (; cycles < 150 && in.pose[0] > -2; cycles++) {    /* 30 s at 5 Hz */
        corridor_scan(&in, lo, hi);
        int w = arb_decide(&p, &s, &in, v);
        for (int k = 0; k < 10; k++) {
            in.pose[0] += cmd_v * 0.02 * cos(in.pose[2]);
            in.pose[1] += cmd_v * 0.02 * sin(in.pose[2]);
            in.pose[2] += cmd_w * 0.02;
        }
        cmd_v = v[w].v;
        cmd_w = v[w].omega;
        closest = fmin(closest, fmin(in.pose[1] - lo, hi - in.pose[1]));
    }
    printf("doorway: %d cycles to x = %.2f, closest to a jamb %.2f m\n", cycles, in.pose[0], closest);
    assert_true(in.pose[0] <= -2);
    assert_true(closest > 0.25);
}

/* The progress watch: a robot held in place on a path for stuck_s gets a recovery (replan
 * asked once, then back off, face the detour point, drive), which ends at the detour point; a
 * robot making way never does, nor one under e-stop. */
/* The recovery's tests: default parameters, fresh state, a fresh pose and a two-point path. */
typedef struct {
    arb_params_t ap;
    rec_params_t rp;
    rec_state_t rs;
    arb_state_t st;
    arb_inputs_t in;
} rec_case_t;

static void rec_case(rec_case_t *k, const double path[6], int32_t goal)
{
    arb_params_default(&k->ap);
    rec_params_default(&k->rp);
    rec_state_reset(&k->rs);
    arb_state_reset(&k->st);
    k->in = base_inputs();
    k->in.path = path;
    k->in.npath = 2;
    k->in.path_age = 0.1;
    k->in.pose_age = 0.05;
    k->in.path_goal = goal;
}

static void test_recovery_when_no_progress(void **state)
{
    static rec_case_t rc;
    const double path[6] = { 0, 0, 0, 10, 0, 0 };
    rec_case(&rc, path, 3);
    arb_vote_t votes[ARB_COUNT];
    double v, w;
    bool replan;
    int replans = 0, stage = REC_NONE;
    /* Making way: 0.1 m/s for 30 s. */
    for (int k = 0; k < 150; k++) {
        rc.in.pose[0] = 0.02 * k;
        int win = arb_decide(&rc.ap, &rc.st, &rc.in, votes);
        stage = rec_step(&rc.rp, &rc.rs, k * 0.2, &rc.ap, &rc.in, win, votes, &v, &w, &replan);
        assert_int_equal(stage, REC_NONE);
    }
    /* Held at x = 3 (something ahead): a recovery after stuck_s. */
    int first = -1, seen[REC_DETOUR + 1] = { 0 };
    for (int k = 150; k < 300; k++) {
        rc.in.pose[0] = 3.0;
        int win = arb_decide(&rc.ap, &rc.st, &rc.in, votes);
        stage = rec_step(&rc.rp, &rc.rs, k * 0.2, &rc.ap, &rc.in, win, votes, &v, &w, &replan);
        replans += replan;
        seen[stage]++;
        if (stage != REC_NONE && first < 0)
            first = k;
        if (stage == REC_BACKOFF)
            assert_true(v < 0 && w == 0);
        if (stage == REC_ROTATE)
            assert_true(v == 0 && w != 0);
    }
    /* stuck_s after the last 0.3 m of progress, which came at most 3 s before the hold. */
    assert_true(first >= 150 + (int)(rc.rp.stuck_s / 0.2) - 16 && first <= 150 + (int)(rc.rp.stuck_s / 0.2) + 1);
    assert_true(replans >= 1);
    assert_true(seen[REC_REPLAN] && seen[REC_BACKOFF] && seen[REC_ROTATE] && seen[REC_DETOUR]);
    assert_true(rc.rs.recoveries >= 1);
    /* The e-stop wins over a recovery. */
    rc.in.estop_pressed = true;
    rc.in.estop_age = 0.05;
    int win = arb_decide(&rc.ap, &rc.st, &rc.in, votes);
    assert_int_equal(win, ARB_ESTOP);
    assert_int_equal(rec_step(&rc.rp, &rc.rs, 61, &rc.ap, &rc.in, win, votes, &v, &w, &replan), REC_NONE);
}

/* The laser sees only ahead: a robot that faced a wall 0.3 m away, turned its back to it and got
 * stuck there does not back off into it (the back-off is skipped, the recovery goes on to
 * rotate); the same robot with nothing seen behind it backs off the whole backoff_s. */
static int backoff_cycles(bool wall_seen)
{
    static rec_case_t rc;
    static float wall[181];
    const double path[6] = { 3, 0, M_PI, -5, 0, M_PI };      /* west, away from the wall at x = 3.3 */
    rec_case(&rc, path, 4);
    arb_inputs_t *in = &rc.in;
    in->pose[0] = 3.0;
    arb_vote_t votes[ARB_COUNT];
    double v, w;
    bool replan;
    int backing = 0, rotating = 0;
    for (int c = 0; c < 150; c++) {          /* 30 s at 5 Hz, held in place */
        in->pose[2] = c < 5 ? 0 : M_PI;      /* the first second facing east, then west */
        in->ranges = open_scan;
        if (c < 5 && wall_seen) {
            for (int j = 0; j < 181; j++) {
                double a = in->angle_min + j * in->angle_increment;
                wall[j] = fabs(a) < 1.2 ? (float)(0.3 / cos(a)) : 10.0f;
            }
            in->ranges = wall;
        }
        in->scan_age = 0.05 + 1e-3 * (c % 2);      /* a new scan every cycle */
        int win = arb_decide(&rc.ap, &rc.st, in, votes);
        int stage = rec_step(&rc.rp, &rc.rs, 100 + c * 0.2, &rc.ap, in, win, votes, &v, &w, &replan);
        backing += stage == REC_BACKOFF && v < 0;
        rotating += stage == REC_ROTATE;
    }
    printf("%s: %d cycles backing off, %d rotating, %lld back-offs cut\n", wall_seen ? "wall behind" : "open behind",
           backing, rotating, (long long)rc.rs.backoffs_cut);
    assert_true(rotating > 0);
    return backing;
}

static void test_backoff_stops_at_what_was_seen_behind(void **state)
{
    assert_int_equal(backoff_cycles(true), 0);
    rec_params_t rp;
    rec_params_default(&rp);
    assert_true(backoff_cycles(false) >= (int)(rp.backoff_s / 0.2) - 1);
}

/* A corner's wall beside the robot, just inside the corridor it sweeps, while the path steers
 * towards that side: avoid turns away from it (turning with the path turned into it, and the
 * two took turns in a maze corner until a recovery). Dead ahead, the path's way still wins. */
static void test_avoid_turns_away_from_a_wall_at_its_side(void **state)
{
    arb_params_t p; arb_params_default(&p);
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    static const double left[] = { 0, 0.3, 0, 3, 0.3, 0 };     /* 0.3 m to the robot's left */
    in.path = left; in.npath = 2; in.path_age = 0.1; in.pose_age = 0.05;
    int k = (int)lround((atan2(0.25, 0.2) - in.angle_min) / in.angle_increment);
    open_scan[k] = (float)hypot(0.2, 0.25);        /* 0.2 m ahead, 0.25 m to the left */
    arb_vote_t v[ARB_COUNT];
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_AVOID);
    assert_true(v[ARB_FOLLOW].omega > 0.2);
    assert_true(v[ARB_AVOID].aside);
    assert_true(v[ARB_AVOID].omega < 0);
    /* The same return straight ahead: the path's side. */
    open_scan[k] = 10.0f;
    open_scan[90] = 0.2f;
    assert_int_equal(arb_decide(&p, &s, &in, v), ARB_AVOID);
    assert_false(v[ARB_AVOID].aside);
    assert_true(v[ARB_AVOID].omega > 0);
}

/* Drives a unicycle along an L-shaped path at the behaviours' 5 Hz with follow_path alone;
 * returns the closest the robot's centre came to the corner's inner wall point, which the path
 * (planned on the inflated map) passes at 0.24 m. Reaches the end or fails. */
static double closest_to_inner_corner(const double *L, int n, double corner_angle)
{
    const double wall[2] = { 2 - 0.24, 0.24 };     /* 0.24 m from both legs */
    arb_params_t p; arb_params_default(&p);
    p.corner_angle = corner_angle;
    arb_state_t s; arb_state_reset(&s);
    arb_inputs_t in = base_inputs();
    in.path = L; in.npath = n; in.path_age = 0.1; in.pose_age = 0.05;
    double closest = INFINITY;
    bool done = false;
    for (int k = 0; k < 300 && !done; k++) {
        arb_vote_t v[ARB_COUNT];
        arb_follow(&p, &s, &in, &v[ARB_FOLLOW]);
        done = !v[ARB_FOLLOW].active;
        for (int j = 0; j < 20; j++) {          /* 0.2 s in 10 ms steps */
            in.pose[0] += v[ARB_FOLLOW].v * cos(in.pose[2]) * 0.01;
            in.pose[1] += v[ARB_FOLLOW].v * sin(in.pose[2]) * 0.01;
            in.pose[2] += v[ARB_FOLLOW].omega * 0.01;
            closest = fmin(closest, hypot(in.pose[0] - wall[0], in.pose[1] - wall[1]));
        }
    }
    assert_true(done);
    assert_true(s.done);
    return closest;
}

/* In a 0.8 m maze corridor the path keeps a 0.18 m robot 0.06 m off the wall only at the corner
 * itself. Pure pursuit (0.5 m ahead) cut it: the wall came inside avoid's corridor (0.21 m: the
 * radius and half the clearance), avoid blocked the robot at the corner and the two stalled
 * there. The robot now drives to the corner, then turns. */
static void test_follow_does_not_cut_a_sharp_corner(void **state)
{
    static const double L[] = { 0, 0, 0, 2, 0, M_PI / 2, 2, 2, M_PI / 2 };
    double cut = closest_to_inner_corner(L, 3, 0), kept = closest_to_inner_corner(L, 3, 0.5);
    print_message("closest to the inner corner: %.3f m cutting, %.3f m driving to the corner\n", cut, kept);
    assert_true(cut < 0.21);
    assert_true(kept > 0.22);
    /* A sampled planner's corner: a 5 cm arc of four legs, none turning 0.5 rad. */
    static const double R[] = { 0, 0, 0, 1.95, 0, 0, 1.9691, 0.0038, 0, 1.9854, 0.0146, 0, 1.9962, 0.0309, 0,
                                2.0, 0.05, 0, 2.0, 2.0, 0 };
    cut = closest_to_inner_corner(R, 7, 0);
    kept = closest_to_inner_corner(R, 7, 0.5);
    print_message("... a corner of close vertices: %.3f m cutting, %.3f m driving to it\n", cut, kept);
    assert_true(cut < 0.21);
    assert_true(kept > 0.22);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_idle_without_inputs),
        cmocka_unit_test(test_recovery_when_no_progress),
        cmocka_unit_test(test_backoff_stops_at_what_was_seen_behind),
        cmocka_unit_test(test_follow_drives_along_path),
        cmocka_unit_test(test_follow_does_not_cut_a_sharp_corner),
        cmocka_unit_test(test_follow_stops_at_end_and_on_stale_pose),
        cmocka_unit_test(test_face_speaker_turns_once_then_follow),
        cmocka_unit_test(test_estop_beats_everything),
        cmocka_unit_test(test_teleop_only_while_recent),
        cmocka_unit_test(test_relocalize_search_between_teleop_and_follow),
        cmocka_unit_test(test_avoid_blocks_and_turns_to_open_side),
        cmocka_unit_test(test_avoid_turns_away_from_a_wall_at_its_side),
        cmocka_unit_test(test_closed_loop_follows_l_path),
        cmocka_unit_test(test_new_path_restarts_progress),
        cmocka_unit_test(test_turn_in_a_doorway_is_not_vetoed),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
