/* test_supervise: marie-am's supervision rules, driven by made-up exits, heartbeats and clocks:
 * backoff growth and reset, giving up after max_failures in a window, heartbeat loss, the stop
 * timeout ending in SIGKILL, restart policies and dependencies. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <signal.h>
#include <string.h>

#include "core/component.h"
#include "managers/supervise.h"

#define S(x) ((int64_t)((x) * 1e6))
/* wait statuses as waitpid gives them */
#define EXIT_STATUS(code) (((code) & 0xff) << 8)
#define SIGNAL_STATUS(sig) ((sig) & 0x7f)

static marie_component_cfg_t cfg_make(marie_restart_kind_t policy)
{
    marie_component_cfg_t cfg = {0};
    cfg.name = "comp";
    cfg.restart.policy = policy;
    cfg.restart.backoff_min_s = 0.5;
    cfg.restart.backoff_max_s = 4;
    cfg.restart.stable_s = 10;
    cfg.restart.max_failures = 0;
    cfg.restart.window_s = 60;
    cfg.stop_timeout_s = 2;
    cfg.heartbeat_timeout_s = 0;
    return cfg;
}

/* Wanted, dependencies ready, spawned as `pid` at time t. */
static void run_at(marie_sv_t *sv, int pid, double t)
{
    marie_sv_action_t act;
    if (sv->st != MARIE_SV_BACKOFF && sv->st != MARIE_SV_RUNNING && sv->st != MARIE_SV_STARTING) {
        marie_sv_want(sv);
        marie_sv_ready(sv, &act);
        assert_true(act.what & MARIE_SV_SPAWN);
    }
    marie_sv_spawned(sv, pid, S(t));
}

/* The process fails at time t; returns the delay before the next spawn (0: at once). */
static double fail_delay(marie_sv_t *sv, double t)
{
    marie_sv_action_t act;
    marie_sv_exited(sv, EXIT_STATUS(1), S(t), &act);
    if (act.what & MARIE_SV_SPAWN)
        return 0;
    assert_int_equal(sv->st, MARIE_SV_BACKOFF);
    return act.timer_s;
}

static void test_backoff_doubles_up_to_max(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ON_FAILURE);
    marie_sv_t sv;
    marie_sv_init(&sv, &cfg, true);
    const double want[] = {0.5, 1, 2, 4, 4, 4};
    double t = 0;
    for (int i = 0; i < 6; i++) {
        run_at(&sv, 100 + i, t);
        t += 1;     /* a short run: not stable */
        double d = fail_delay(&sv, t);
        assert_float_equal(d, want[i], 1e-9);
        marie_sv_action_t act;
        marie_sv_timer(&sv, &act);
        assert_true(act.what & MARIE_SV_SPAWN);
        t += d;
    }
    assert_int_equal(sv.restarts, 6);
    assert_int_equal(sv.last_exit, 1);
}

static void test_stable_run_resets_backoff(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ON_FAILURE);
    marie_sv_t sv;
    marie_sv_init(&sv, &cfg, true);
    run_at(&sv, 10, 0);
    assert_float_equal(fail_delay(&sv, 1), 0.5, 1e-9);
    run_at(&sv, 11, 1.5);
    assert_float_equal(fail_delay(&sv, 2), 1, 1e-9);
    run_at(&sv, 12, 3);
    /* ran 10 s (stable_after): respawn at once, and the backoff starts over */
    marie_sv_action_t act;
    marie_sv_exited(&sv, EXIT_STATUS(1), S(13), &act);
    assert_true(act.what & MARIE_SV_SPAWN);
    assert_true(act.timer_s == 0);
    assert_string_equal(act.event_kind, "respawn");
    run_at(&sv, 13, 13);
    assert_float_equal(fail_delay(&sv, 14), 0.5, 1e-9);
}

static void test_gives_up_after_max_failures_in_window(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ALWAYS);
    cfg.restart.max_failures = 3;
    cfg.restart.window_s = 10;
    marie_sv_t sv;
    marie_sv_init(&sv, &cfg, true);
    marie_sv_action_t act;
    run_at(&sv, 20, 0);
    assert_true(fail_delay(&sv, 1) > 0);
    run_at(&sv, 21, 2);
    assert_true(fail_delay(&sv, 3) > 0);
    run_at(&sv, 22, 4);
    marie_sv_exited(&sv, EXIT_STATUS(3), S(5), &act);
    assert_int_equal(sv.st, MARIE_SV_FAILED);
    assert_string_equal(act.event_kind, "gave_up");
    assert_false(act.what & MARIE_SV_SPAWN);
    assert_true(act.timer_s == 0);
    assert_int_equal(sv.last_exit, 3);
    /* a later start order begins with a clean slate */
    marie_sv_want(&sv);
    assert_int_equal(sv.st, MARIE_SV_WAITING);
    assert_int_equal(sv.nfail_times, 0);
    assert_float_equal(sv.next_backoff_s, 0.5, 1e-9);
}

static void test_failures_spread_beyond_window_never_give_up(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ON_FAILURE);
    cfg.restart.max_failures = 2;
    cfg.restart.window_s = 10;
    marie_sv_t sv;
    marie_sv_init(&sv, &cfg, true);
    for (int i = 0; i < 100; i++) {
        run_at(&sv, 30 + i, 20.0 * i);
        /* fails after 12 s, each time: one failure per window */
        double d = fail_delay(&sv, 20.0 * i + 12);
        assert_int_not_equal(sv.st, MARIE_SV_FAILED);
        if (d > 0) {
            marie_sv_action_t act;
            marie_sv_timer(&sv, &act);
            assert_true(act.what & MARIE_SV_SPAWN);
        }
    }
    assert_int_equal(sv.restarts, 100);
    assert_true(sv.nfail_times <= MARIE_SV_MAX_FAIL_TIMES);
}

static void test_heartbeat_loss_restarts(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ON_FAILURE);
    cfg.heartbeat_timeout_s = 1;
    marie_sv_t sv;
    marie_sv_init(&sv, &cfg, true);
    marie_sv_action_t act;
    run_at(&sv, 40, 0);
    assert_int_equal(sv.st, MARIE_SV_STARTING);
    /* running heartbeat: up, and the ones waiting for it may start */
    marie_sv_heartbeat(&sv, MARIE_STATE_RUNNING, "", S(0.5), &act);
    assert_int_equal(sv.st, MARIE_SV_RUNNING);
    assert_true(act.what & MARIE_SV_START_WAITING);
    assert_true(marie_sv_up(&sv, S(0.6)));
    marie_sv_check_heartbeat(&sv, S(1.4), &act);
    assert_int_equal(act.what, 0);
    assert_int_equal(sv.st, MARIE_SV_RUNNING);
    /* silent for more than heartbeat_timeout: stop signal, SIGKILL later */
    marie_sv_check_heartbeat(&sv, S(1.6), &act);
    assert_string_equal(act.event_kind, "not_responding");
    assert_true(act.what & MARIE_SV_TERM);
    assert_float_equal(act.timer_s, 2, 1e-9);
    assert_int_equal(sv.st, MARIE_SV_STOPPING);
    /* it ends on the stop signal: a failure, restarted with backoff */
    marie_sv_exited(&sv, SIGNAL_STATUS(SIGTERM), S(1.7), &act);
    assert_int_equal(sv.st, MARIE_SV_BACKOFF);
    assert_string_equal(act.event_kind, "respawn");
    assert_int_equal(sv.nfail_times, 1);
    assert_int_equal(sv.last_exit, -SIGTERM);
}

static void test_no_heartbeat_ever_counts_from_spawn(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ON_FAILURE);
    cfg.heartbeat_timeout_s = 1;
    marie_sv_t sv;
    marie_sv_init(&sv, &cfg, true);
    marie_sv_action_t act;
    run_at(&sv, 41, 5);
    marie_sv_check_heartbeat(&sv, S(5.9), &act);
    assert_int_equal(act.what, 0);
    marie_sv_check_heartbeat(&sv, S(6.1), &act);
    assert_true(act.what & MARIE_SV_TERM);
    /* without heartbeat_timeout nothing is ever declared hung */
    cfg.heartbeat_timeout_s = 0;
    marie_sv_init(&sv, &cfg, true);
    run_at(&sv, 42, 0);
    assert_int_equal(sv.st, MARIE_SV_RUNNING);
    marie_sv_check_heartbeat(&sv, S(1000), &act);
    assert_int_equal(act.what, 0);
}

static void test_failed_heartbeat_restarts_unless_never(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ON_FAILURE);
    cfg.heartbeat_timeout_s = 1;
    marie_sv_t sv;
    marie_sv_init(&sv, &cfg, true);
    marie_sv_action_t act;
    run_at(&sv, 50, 0);
    marie_sv_heartbeat(&sv, MARIE_STATE_RUNNING, "", S(0.1), &act);
    marie_sv_heartbeat(&sv, MARIE_STATE_FAILED, "device gone", S(0.2), &act);
    assert_string_equal(act.event_kind, "component_failed");
    assert_non_null(strstr(act.event_text, "device gone"));
    assert_true(act.what & MARIE_SV_TERM);
    assert_true(sv.count_failure);

    cfg.restart.policy = MARIE_RESTART_NEVER;
    marie_sv_init(&sv, &cfg, true);
    run_at(&sv, 51, 0);
    marie_sv_heartbeat(&sv, MARIE_STATE_RUNNING, "", S(0.1), &act);
    marie_sv_heartbeat(&sv, MARIE_STATE_FAILED, "x", S(0.2), &act);
    assert_false(act.what & MARIE_SV_TERM);
    assert_true(act.what & MARIE_SV_STATUS);
    assert_int_equal(sv.st, MARIE_SV_RUNNING);
}

static void test_stop_timeout_ends_in_sigkill(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ALWAYS);
    cfg.stop_timeout_s = 3;
    marie_sv_t sv;
    marie_sv_init(&sv, &cfg, true);
    marie_sv_action_t act;
    run_at(&sv, 60, 0);
    marie_sv_stop(&sv, &act);
    assert_true(act.what & MARIE_SV_TERM);
    assert_false(act.what & MARIE_SV_KILL);
    assert_float_equal(act.timer_s, 3, 1e-9);
    assert_int_equal(sv.st, MARIE_SV_STOPPING);
    /* a second stop order does not send the signal again nor restart the clock */
    marie_sv_stop(&sv, &act);
    assert_int_equal(act.what, 0);
    assert_true(act.timer_s == 0);
    /* the timer: still alive, so SIGKILL */
    marie_sv_timer(&sv, &act);
    assert_true(act.what & MARIE_SV_KILL);
    assert_int_equal(sv.pid, 60);
    /* the exit: stopped for good, even with policy always */
    marie_sv_exited(&sv, SIGNAL_STATUS(SIGKILL), S(4), &act);
    assert_int_equal(sv.st, MARIE_SV_STOPPED);
    assert_false(act.what & MARIE_SV_SPAWN);
    assert_true(act.what & MARIE_SV_PROGRESS_STOPS);
    assert_true(act.timer_s == 0);
}

static void test_stop_without_process_settles_at_once(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ON_FAILURE);
    marie_sv_t sv;
    marie_sv_init(&sv, &cfg, true);
    marie_sv_action_t act;
    run_at(&sv, 70, 0);
    assert_true(fail_delay(&sv, 1) > 0);
    assert_int_equal(sv.st, MARIE_SV_BACKOFF);
    /* stopped while waiting to respawn: the backoff timer goes, no signal */
    marie_sv_stop(&sv, &act);
    assert_int_equal(sv.st, MARIE_SV_STOPPED);
    assert_true(act.cancel_timer);
    assert_false(act.what & (MARIE_SV_TERM | MARIE_SV_KILL | MARIE_SV_SPAWN));
    /* a timer that fired anyway does nothing */
    marie_sv_timer(&sv, &act);
    assert_int_equal(act.what, 0);
}

static void test_restart_order_is_not_a_failure(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_NEVER);
    marie_sv_t sv;
    marie_sv_init(&sv, &cfg, true);
    marie_sv_action_t act;
    run_at(&sv, 80, 0);
    marie_sv_restart(&sv, &act);
    assert_true(act.what & MARIE_SV_TERM);
    marie_sv_exited(&sv, SIGNAL_STATUS(SIGTERM), S(1), &act);
    assert_true(act.what & MARIE_SV_SPAWN);
    assert_null(act.event_kind);
    assert_int_equal(sv.nfail_times, 0);
    assert_int_equal(sv.restarts, 1);
}

static void test_policies_on_exit(void **state)
{
    marie_sv_action_t act;
    marie_sv_t sv;
    /* on_failure: a clean exit stays exited */
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ON_FAILURE);
    marie_sv_init(&sv, &cfg, true);
    run_at(&sv, 90, 0);
    marie_sv_exited(&sv, EXIT_STATUS(0), S(1), &act);
    assert_int_equal(sv.st, MARIE_SV_EXITED);
    assert_string_equal(act.event_kind, "exited");
    assert_false(act.what & MARIE_SV_SPAWN);
    /* never: a failure stays failed */
    cfg = cfg_make(MARIE_RESTART_NEVER);
    marie_sv_init(&sv, &cfg, true);
    run_at(&sv, 91, 0);
    marie_sv_exited(&sv, EXIT_STATUS(2), S(1), &act);
    assert_int_equal(sv.st, MARIE_SV_FAILED);
    assert_string_equal(act.event_kind, "failed");
    /* always: a clean exit comes back */
    cfg = cfg_make(MARIE_RESTART_ALWAYS);
    marie_sv_init(&sv, &cfg, true);
    run_at(&sv, 92, 0);
    marie_sv_exited(&sv, EXIT_STATUS(0), S(1), &act);
    assert_int_equal(sv.st, MARIE_SV_BACKOFF);
    /* a failed spawn is a failed component */
    marie_sv_init(&sv, &cfg, true);
    marie_sv_want(&sv);
    marie_sv_spawned(&sv, -1, S(0));
    assert_int_equal(sv.st, MARIE_SV_FAILED);
    assert_int_equal(sv.last_exit, 127);
}

static void test_dependencies(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ON_FAILURE);
    cfg.heartbeat_timeout_s = 1;
    marie_sv_t local, remote;
    marie_sv_action_t act;
    /* local: up once its heartbeat says running */
    marie_sv_init(&local, &cfg, true);
    assert_false(marie_sv_up(&local, S(0)));
    run_at(&local, 100, 0);
    assert_false(marie_sv_up(&local, S(0.1)));
    assert_true(marie_sv_alive(&local, S(0.1)));
    marie_sv_heartbeat(&local, MARIE_STATE_DEGRADED, "", S(0.2), &act);
    assert_true(marie_sv_up(&local, S(0.3)));
    /* remote: up while its heartbeats are fresh (at least 2 s) */
    marie_sv_init(&remote, &cfg, false);
    assert_false(marie_sv_up(&remote, S(1)));
    marie_sv_heartbeat(&remote, MARIE_STATE_RUNNING, "", S(1), &act);
    assert_true(act.what & MARIE_SV_START_WAITING);
    assert_true(marie_sv_up(&remote, S(2.9)));
    assert_false(marie_sv_up(&remote, S(3.1)));
    assert_true(marie_sv_alive(&remote, S(2.4)));
    assert_false(marie_sv_alive(&remote, S(2.6)));
    /* or while its manager's status says it runs */
    assert_true(marie_sv_peer_status(&remote, true, S(10)));
    assert_true(marie_sv_up(&remote, S(11)));
    assert_false(marie_sv_peer_status(&remote, true, S(11)));
    assert_false(marie_sv_up(&remote, S(13.5)));
    /* a remote component is never spawned here */
    marie_sv_want(&remote);
    marie_sv_ready(&remote, &act);
    assert_false(act.what & MARIE_SV_SPAWN);
}

static void test_down_waits_for_dependents(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ON_FAILURE);
    cfg.stop_timeout_s = 1;
    marie_sv_t sv;
    marie_sv_action_t act;
    marie_sv_init(&sv, &cfg, true);
    run_at(&sv, 110, 0);
    marie_sv_stop_later(&sv, S(10), &act);
    assert_int_equal(act.what, 0);
    assert_true(sv.stop_pending);
    marie_sv_progress_stop(&sv, true, S(12.9), &act);
    assert_int_equal(act.what, 0);
    /* dependents still alive after stop_timeout + 2 s: stop anyway */
    marie_sv_progress_stop(&sv, true, S(13.1), &act);
    assert_true(act.what & MARIE_SV_TERM);
    assert_false(sv.stop_pending);
    /* or at once when they are gone */
    marie_sv_init(&sv, &cfg, true);
    run_at(&sv, 111, 0);
    marie_sv_stop_later(&sv, S(10), &act);
    marie_sv_progress_stop(&sv, false, S(10.1), &act);
    assert_true(act.what & MARIE_SV_TERM);
}

static void test_move_away_stops_it(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ALWAYS);
    marie_sv_t sv;
    marie_sv_action_t act;
    marie_sv_init(&sv, &cfg, true);
    run_at(&sv, 120, 0);
    marie_sv_set_local(&sv, false, true, &act);
    assert_true(act.what & MARIE_SV_TERM);
    assert_false(sv.wanted);
    /* and moved back while the system is up: wanted again */
    marie_sv_exited(&sv, SIGNAL_STATUS(SIGTERM), S(1), &act);
    marie_sv_set_local(&sv, true, true, &act);
    assert_int_equal(sv.st, MARIE_SV_WAITING);
    assert_true(sv.wanted);
}

/* A move to the host where it already runs (the leader's placement after a partition heals):
 * the instance that runs there goes on, and its liveness is still its own heartbeats. */
static void test_move_to_where_it_runs_keeps_it(void **state)
{
    marie_component_cfg_t cfg = cfg_make(MARIE_RESTART_ON_FAILURE);
    cfg.heartbeat_timeout_s = 2;
    marie_sv_t sv;
    marie_sv_action_t act;
    marie_sv_init(&sv, &cfg, true);
    run_at(&sv, 130, 0);
    for (int t = 1; t <= 135; t++)
        marie_sv_heartbeat(&sv, MARIE_STATE_RUNNING, "", S(t), &act);
    marie_sv_set_local(&sv, true, true, &act);
    assert_int_equal(act.what & (MARIE_SV_TERM | MARIE_SV_SPAWN), 0);
    marie_sv_check_heartbeat(&sv, S(135.05), &act);
    if (act.event_kind)
        fail_msg("the kept copy was restarted: %s", act.event_text);
    assert_int_equal(sv.st, MARIE_SV_RUNNING);
    assert_int_equal(sv.pid, 130);
    assert_true(marie_sv_up(&sv, S(135.1)));
    /* still watched: silent for heartbeat_timeout after its last beat, it is restarted */
    marie_sv_check_heartbeat(&sv, S(137.5), &act);
    assert_string_equal(act.event_kind, "not_responding");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_backoff_doubles_up_to_max),
        cmocka_unit_test(test_stable_run_resets_backoff),
        cmocka_unit_test(test_gives_up_after_max_failures_in_window),
        cmocka_unit_test(test_failures_spread_beyond_window_never_give_up),
        cmocka_unit_test(test_heartbeat_loss_restarts),
        cmocka_unit_test(test_no_heartbeat_ever_counts_from_spawn),
        cmocka_unit_test(test_failed_heartbeat_restarts_unless_never),
        cmocka_unit_test(test_stop_timeout_ends_in_sigkill),
        cmocka_unit_test(test_stop_without_process_settles_at_once),
        cmocka_unit_test(test_restart_order_is_not_a_failure),
        cmocka_unit_test(test_policies_on_exit),
        cmocka_unit_test(test_dependencies),
        cmocka_unit_test(test_down_waits_for_dependents),
        cmocka_unit_test(test_move_away_stops_it),
        cmocka_unit_test(test_move_to_where_it_runs_keeps_it),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
