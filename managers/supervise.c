/* The supervision rules of marie-am: restart policy, backoff, give-up window, heartbeat loss
 * and the stop timeout, decided from events without any system call. */
#include "managers/supervise.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/wait.h>

#include "core/component.h"
#include "core/log.h"
#include "lcmtypes/marie_event_t.h"

static const char *const state_names[] = {
    "stopped", "waiting", "starting", "running", "stopping", "backoff", "failed", "exited",
};

const char *marie_sv_state_name(marie_sv_state_t st)
{
    return (unsigned)st < sizeof state_names / sizeof state_names[0] ? state_names[st] : "?";
}

static void act_clear(marie_sv_action_t *act)
{
    memset(act, 0, sizeof *act);
}

static void act_event(marie_sv_action_t *act, int sev, const char *kind, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void act_event(marie_sv_action_t *act, int sev, const char *kind, const char *fmt, ...)
{
    MARIE_VFORMAT(act->event_text, fmt);
    act->event_sev = sev;
    act->event_kind = kind;
}

/* Heartbeat states that count as up, for dependencies and restarts alike (degraded is
 * running with a quiet device). */
static bool hb_up(int state)
{
    return state == MARIE_STATE_RUNNING || state == MARIE_STATE_PAUSED || state == MARIE_STATE_DEGRADED;
}

void marie_sv_init(marie_sv_t *sv, const marie_component_cfg_t *cfg, bool local)
{
    memset(sv, 0, sizeof *sv);
    sv->cfg = cfg;
    sv->local = local;
    sv->hb_state = -1;
    sv->next_backoff_s = cfg->restart.backoff_min_s;
}

/* Stop signal, SIGKILL after stop_timeout; without a process, settle at once. */
static void sv_stop(marie_sv_t *sv, bool restart_after, marie_sv_action_t *act)
{
    sv->stop_pending = false;
    if (sv->pid <= 0) {
        act->cancel_timer = true;
        if (restart_after) {
            sv->st = MARIE_SV_WAITING;
            act->what |= MARIE_SV_START_WAITING;
        } else if (sv->st != MARIE_SV_FAILED && sv->st != MARIE_SV_EXITED) {
            sv->st = MARIE_SV_STOPPED;
        }
        return;
    }
    sv->restart_after_stop = restart_after;
    if (sv->st == MARIE_SV_STOPPING)
        return;
    sv->st = MARIE_SV_STOPPING;
    act->what |= MARIE_SV_TERM;
    act->cancel_timer = true;
    act->timer_s = sv->cfg->stop_timeout_s > 0 ? sv->cfg->stop_timeout_s : 0.001;
}

void marie_sv_want(marie_sv_t *sv)
{
    sv->wanted = true;
    sv->stop_pending = false;
    if (!sv->local)
        return;
    if (sv->st == MARIE_SV_STOPPED || sv->st == MARIE_SV_FAILED || sv->st == MARIE_SV_EXITED) {
        sv->nfail_times = 0;
        sv->next_backoff_s = sv->cfg->restart.backoff_min_s;
        sv->st = MARIE_SV_WAITING;
    } else if (sv->st == MARIE_SV_STOPPING) {
        sv->restart_after_stop = true;
    }
}

void marie_sv_stop(marie_sv_t *sv, marie_sv_action_t *act)
{
    act_clear(act);
    sv->wanted = false;
    sv_stop(sv, false, act);
}

void marie_sv_restart(marie_sv_t *sv, marie_sv_action_t *act)
{
    act_clear(act);
    if (sv->pid > 0) {
        sv->wanted = true;
        sv_stop(sv, true, act);
    } else {
        marie_sv_want(sv);
    }
}

void marie_sv_stop_later(marie_sv_t *sv, int64_t now, marie_sv_action_t *act)
{
    act_clear(act);
    sv->wanted = false;
    if (sv->pid > 0 && sv->st != MARIE_SV_STOPPING) {
        sv->stop_pending = true;
        sv->stop_pending_since = now;
    } else if (sv->pid <= 0) {
        sv_stop(sv, false, act);
    }
}

void marie_sv_progress_stop(marie_sv_t *sv, bool dependents_alive, int64_t now, marie_sv_action_t *act)
{
    act_clear(act);
    if (!sv->stop_pending)
        return;
    double cap = sv->cfg->stop_timeout_s + 2.0;
    if (!dependents_alive || now - sv->stop_pending_since > (int64_t)(cap * 1e6))
        sv_stop(sv, false, act);
}

void marie_sv_set_local(marie_sv_t *sv, bool local, bool up, marie_sv_action_t *act)
{
    act_clear(act);
    bool was_local = sv->local;
    if (was_local && local)
        return;     /* the instance running here goes on: its heartbeats are still its own */
    sv->local = local;
    sv->hb_us = 0;
    sv->hb_state = -1;
    sv->peer_running = false;
    if (was_local && !local) {
        sv->wanted = false;
        sv_stop(sv, false, act);
    } else if (!was_local && local) {
        sv->st = MARIE_SV_STOPPED;
        if (up)
            marie_sv_want(sv);
    }
}

void marie_sv_ready(marie_sv_t *sv, marie_sv_action_t *act)
{
    act_clear(act);
    if (sv->local && sv->wanted && sv->st == MARIE_SV_WAITING)
        act->what |= MARIE_SV_SPAWN;
}

void marie_sv_spawned(marie_sv_t *sv, int pid, int64_t now)
{
    if (pid <= 0) {
        sv->last_exit = 127;
        sv->st = MARIE_SV_FAILED;
        return;
    }
    sv->pid = pid;
    sv->started_us = now;
    sv->hb_us = 0;
    sv->hb_state = -1;
    sv->restart_after_stop = false;
    sv->count_failure = false;
    /* without heartbeats, a live process is all we can know */
    sv->st = sv->cfg->heartbeat_timeout_s > 0 ? MARIE_SV_STARTING : MARIE_SV_RUNNING;
}

static void marie_sv_describe_exit(int status, char *buf, size_t len)
{
    if (WIFEXITED(status))
        snprintf(buf, len, "exit status %d", WEXITSTATUS(status));
    else if (WIFSIGNALED(status))
        snprintf(buf, len, "killed by signal %d (%s)", WTERMSIG(status), strsignal(WTERMSIG(status)));
    else
        snprintf(buf, len, "status 0x%x", status);
}

static int failures_in_window(const marie_sv_t *sv, int64_t now)
{
    int n = 0;
    for (int i = 0; i < sv->nfail_times; i++)
        if (now - sv->fail_times[i] <= (int64_t)(sv->cfg->restart.window_s * 1e6))
            n++;
    return n;
}

static void record_failure(marie_sv_t *sv, int64_t now)
{
    if (sv->nfail_times == MARIE_SV_MAX_FAIL_TIMES) {
        memmove(sv->fail_times, sv->fail_times + 1, (MARIE_SV_MAX_FAIL_TIMES - 1) * sizeof sv->fail_times[0]);
        sv->nfail_times--;
    }
    sv->fail_times[sv->nfail_times++] = now;
}

/* The delay before the next spawn: none after a stable run or an asked-for restart, else the
 * current backoff, which doubles up to backoff_max. */
static double next_delay(marie_sv_t *sv, bool asked, double run_s)
{
    const marie_restart_cfg_t *rc = &sv->cfg->restart;
    if (asked || run_s >= rc->stable_s) {
        sv->next_backoff_s = rc->backoff_min_s;
        return 0;
    }
    double delay = sv->next_backoff_s;
    double nb = sv->next_backoff_s * 2;
    if (nb < rc->backoff_min_s)
        nb = rc->backoff_min_s;
    if (nb > rc->backoff_max_s)
        nb = rc->backoff_max_s;
    sv->next_backoff_s = nb;
    return delay;
}

void marie_sv_exited(marie_sv_t *sv, int status, int64_t now, marie_sv_action_t *act)
{
    const marie_restart_cfg_t *rc = &sv->cfg->restart;
    const char *name = sv->cfg->name;
    int old = sv->pid;
    char why[96];
    act_clear(act);
    marie_sv_describe_exit(status, why, sizeof why);
    sv->pid = 0;
    sv->hb_state = -1;
    act->cancel_timer = true;
    sv->last_exit = WIFEXITED(status) ? WEXITSTATUS(status) : WIFSIGNALED(status) ? -WTERMSIG(status) : -1;
    double run_s = (double)(now - sv->started_us) * 1e-6;
    bool failure = sv->count_failure || !(WIFEXITED(status) && WEXITSTATUS(status) == 0);

    if (sv->st == MARIE_SV_STOPPING && !sv->restart_after_stop) {
        act->log_only = true;
        act_event(act, MARIE_EVENT_T_SEV_INFO, "stopped", "%s: stopped (%s)", name, why);
        sv->st = MARIE_SV_STOPPED;
        act->what |= MARIE_SV_PROGRESS_STOPS;
        return;
    }
    if (!sv->wanted || !sv->local) {
        sv->st = MARIE_SV_STOPPED;
        return;
    }
    bool asked = sv->st == MARIE_SV_STOPPING && sv->restart_after_stop && !sv->count_failure;
    bool respawn = asked || rc->policy == MARIE_RESTART_ALWAYS ||
                   (rc->policy == MARIE_RESTART_ON_FAILURE && failure);
    if (!respawn) {
        act_event(act, failure ? MARIE_EVENT_T_SEV_ERROR : MARIE_EVENT_T_SEV_INFO, failure ? "failed" : "exited",
                  "%s (pid %d) %s after %.1f s; policy does not restart it", name, old, why, run_s);
        sv->st = failure ? MARIE_SV_FAILED : MARIE_SV_EXITED;
        return;
    }
    if (failure && !asked) {
        record_failure(sv, now);
        int nf = failures_in_window(sv, now);
        if (rc->max_failures > 0 && nf >= rc->max_failures) {
            act_event(act, MARIE_EVENT_T_SEV_ERROR, "gave_up",
                      "%s: %d failures within %.0f s, last %s: not restarting it", name, nf, rc->window_s, why);
            sv->st = MARIE_SV_FAILED;
            return;
        }
    }
    double delay = next_delay(sv, asked, run_s);
    sv->restarts++;
    if (!asked)
        act_event(act, MARIE_EVENT_T_SEV_WARN, "respawn", "%s (pid %d) %s after %.1f s; restart %d in %.2f s",
                  name, old, why, run_s, sv->restarts, delay);
    if (delay <= 0) {
        act->what |= MARIE_SV_SPAWN;
    } else {
        sv->st = MARIE_SV_BACKOFF;
        act->timer_s = delay;
    }
}

void marie_sv_heartbeat(marie_sv_t *sv, int state, const char *reason, int64_t now, marie_sv_action_t *act)
{
    act_clear(act);
    sv->hb_us = now;
    int prev = sv->hb_state;
    sv->hb_state = state;
    if (!sv->local) {
        if (prev != state)
            act->what |= MARIE_SV_START_WAITING;
        return;
    }
    if (sv->pid <= 0)
        return;
    if (sv->st == MARIE_SV_STARTING && hb_up(state)) {
        sv->st = MARIE_SV_RUNNING;
        act->what |= MARIE_SV_START_WAITING;
    } else if (sv->st == MARIE_SV_RUNNING && state == MARIE_STATE_FAILED && prev != MARIE_STATE_FAILED &&
               sv->cfg->restart.policy != MARIE_RESTART_NEVER) {
        act_event(act, MARIE_EVENT_T_SEV_WARN, "component_failed", "%s reports failed (%s): restarting it",
                  sv->cfg->name, reason ? reason : "");
        sv->count_failure = true;
        sv_stop(sv, true, act);
    } else if (prev != state) {
        act->what |= MARIE_SV_STATUS;
    }
}

bool marie_sv_peer_status(marie_sv_t *sv, bool running, int64_t now)
{
    bool changed = running != sv->peer_running;
    sv->peer_running = running;
    sv->peer_us = now;
    return changed;
}

void marie_sv_timer(marie_sv_t *sv, marie_sv_action_t *act)
{
    act_clear(act);
    if (sv->st == MARIE_SV_BACKOFF) {
        if (sv->wanted && sv->local)
            act->what |= MARIE_SV_SPAWN;
    } else if (sv->pid > 0) {
        act->log_only = true;
        act_event(act, MARIE_EVENT_T_SEV_WARN, "killed", "%s: still alive %.1f s after the stop signal: SIGKILL",
                  sv->cfg->name, sv->cfg->stop_timeout_s);
        act->what |= MARIE_SV_KILL;
    }
}

void marie_sv_breach(marie_sv_t *sv, bool stop, marie_sv_action_t *act)
{
    act_clear(act);
    if (stop)
        sv->wanted = false;
    if (sv->pid <= 0 || sv->st == MARIE_SV_STOPPING)
        return;
    sv->count_failure = true;
    sv_stop(sv, !stop, act);
}

int64_t marie_sv_heartbeat_deadline(const marie_sv_t *sv)
{
    if (!sv->local || sv->pid <= 0 || sv->cfg->heartbeat_timeout_s <= 0 ||
        (sv->st != MARIE_SV_STARTING && sv->st != MARIE_SV_RUNNING))
        return INT64_MAX;
    int64_t ref = sv->hb_us > sv->started_us ? sv->hb_us : sv->started_us;
    return ref + (int64_t)(sv->cfg->heartbeat_timeout_s * 1e6);
}

void marie_sv_check_heartbeat(marie_sv_t *sv, int64_t now, marie_sv_action_t *act)
{
    act_clear(act);
    int64_t deadline = marie_sv_heartbeat_deadline(sv);
    if (deadline == INT64_MAX)
        return;
    int64_t ref = sv->hb_us > sv->started_us ? sv->hb_us : sv->started_us;
    if (now > deadline) {
        act_event(act, MARIE_EVENT_T_SEV_WARN, "not_responding", "%s (pid %d): no heartbeat for %.2f s: restarting it",
                  sv->cfg->name, sv->pid, (double)(now - ref) * 1e-6);
        sv->count_failure = true;
        sv_stop(sv, true, act);
    }
}

bool marie_sv_up(const marie_sv_t *sv, int64_t now)
{
    if (sv->local)
        return sv->pid > 0 && sv->st == MARIE_SV_RUNNING;
    double fresh = sv->cfg->heartbeat_timeout_s > 2 ? sv->cfg->heartbeat_timeout_s : 2;
    if (sv->hb_us && now - sv->hb_us < (int64_t)(fresh * 1e6) && hb_up(sv->hb_state))
        return true;
    return sv->peer_running && now - sv->peer_us < 2000000;
}

bool marie_sv_alive(const marie_sv_t *sv, int64_t now)
{
    if (sv->local)
        return sv->pid > 0;
    return sv->hb_us && now - sv->hb_us < 1500000 && sv->hb_state != MARIE_STATE_EXITED;
}
