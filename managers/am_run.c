/* marie-am's hands: spawns components (their output goes to am_output.c), and carries out what
 * the supervision state machine (supervise.c) decides: signals, timers, respawns. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/component.h"
#include "core/log.h"
#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_types.h"
#include "managers/am.h"
#include "managers/progcheck.h"
#include "managers/spawn.h"

comp_t *am_comp_find(am_t *am, const char *name)
{
    for (size_t i = 0; i < am_ncomps(am); i++)
        if (strcmp(am_comp_at(am, i)->cfg->name, name) == 0)
            return am_comp_at(am, i);
    return NULL;
}

bool am_comp_matches(const comp_t *c, const char *target)
{
    return strcmp(target, "*") == 0 || strcmp(c->cfg->name, target) == 0 ||
           (c->cfg->group && strcmp(c->cfg->group, target) == 0);
}

/* After any event: a changed state is shown soon. */
static void note_state(comp_t *c, marie_sv_state_t before)
{
    if (c->sv.st != before) {
        marie_debug("%s: %s -> %s", c->cfg->name, marie_sv_state_name(before), marie_sv_state_name(c->sv.st));
        am_status_changed(c->am);
    }
}

bool am_comp_timer_pending(const comp_t *c) { return c->timer != NULL; }

void am_comp_cancel_timer(comp_t *c)
{
    if (c->timer) {
        marie_loop_remove_timer(c->am->env.loop, c->timer);
        c->timer = NULL;
    }
}

void am_comp_carry(comp_t *to, comp_t *from)
{
    const marie_component_cfg_t *cfg = to->cfg;
    am_comp_unboost(from);      /* its timer knows it by its old place */
    *to = *from;
    to->cfg = to->sv.cfg = cfg;
    am_output_moved(to);
    *from = (comp_t){.am = from->am};
    am_output_init(from);
}

/* ---------------------------------------------------------------- spawning */

static char *path_with_self(am_t *am)
{
    const char *p = getenv("PATH");
    size_t n = strlen(am->env.self_dir) + (p ? strlen(p) : 0) + 8;
    char *s = malloc(n);
    if (s)
        snprintf(s, n, "PATH=%s%s%s", am->env.self_dir, p ? ":" : "", p ? p : "");
    return s;
}

static bool env_dropped(const char *kv)
{
    static const char *const drop[] = {"NOTIFY_SOCKET=", "WATCHDOG_USEC=", "WATCHDOG_PID=",
                                       "LISTEN_FDS=", "LISTEN_PID=", "LISTEN_FDNAMES=", "PATH=",
                                       "MARIE_SYSTEM=", "MARIE_NAME=", "MARIE_PROFILE=", "MARIE_HOST=",
                                       "MARIE_STATE_DIR=", "MARIE_KEY=", "MARIE_SYSTEM_ORIGIN=", "MARIE_SYSTEM_ENTRY=", NULL};
    for (int i = 0; drop[i]; i++)
        if (strncmp(kv, drop[i], strlen(drop[i])) == 0)
            return true;
    return false;
}

/* The program to exec: a name without '/' is looked up in marie-am's own directory, then
 * in PATH (execvpe would search the manager's PATH only), a relative path from the system
 * file's folder, as marie up checked it. NULL: let execvpe report it. */
static char *resolve_exec(am_t *am, const marie_component_cfg_t *cfg)
{
    return marie_am_resolve_exec(am->env.self_dir, cfg->file, cfg->exec);
}

/* ---------------------------------------------------------------- the start at the manager's priority */

/* A manager at a real-time priority starts a component with a short heartbeat_timeout at that
 * priority less one (the manager's own wake-ups come first), and puts it back to the normal
 * policy at its first heartbeat or AM_BOOST_MAX_US after its start, whichever comes first.
 * Born at the normal policy, the new process waited for a CPU beside busy loops from its clone
 * to its main and its first heartbeat: 60-90 ms of a restart whose floor is the timeout and the
 * stop timeout (docs/managers.md, "Not responding"). Not for a component whose sched: asks for
 * a policy of its own, nor a shell's (its children are not its threads), nor one with a long
 * timeout (nothing to win, and it must not hold a CPU long). */
#define BOOST_MAX_TIMEOUT_S 4.0

/* The manager's SCHED_FIFO priority less one (at least 1), or 0 at another policy. */
static int below_manager(void)
{
    struct sched_param p;
    if ((sched_getscheduler(0) & ~SCHED_RESET_ON_FORK) != SCHED_FIFO || sched_getparam(0, &p) < 0)
        return 0;
    return p.sched_priority > 1 ? p.sched_priority - 1 : 1;
}

static int boost_priority(const comp_t *c)
{
    const marie_component_cfg_t *cfg = c->cfg;
    bool short_timeout = cfg->heartbeat_timeout_s > 0 && cfg->heartbeat_timeout_s < BOOST_MAX_TIMEOUT_S;
    return !cfg->shell && cfg->sched.policy == MARIE_SCHED_OTHER && short_timeout ? below_manager() : 0;
}

/* One pass over the threads of process pid: each not yet at policy is set to it (prio); back
 * to SCHED_OTHER at the manager's niceness or 0, as SCHED_RESET_ON_FORK makes it. Returns how
 * many it changed. */
static int tasks_pass(pid_t pid, int policy, int prio, int nice)
{
    char path[64];
    snprintf(path, sizeof path, "/proc/%d/task", (int)pid);
    DIR *d = pid > 0 ? opendir(path) : NULL;
    struct sched_param p = {.sched_priority = prio};
    int changed = 0;
    for (struct dirent *e; d && (e = readdir(d));) {
        pid_t tid = (pid_t)atoi(e->d_name);
        if (tid <= 0 || (sched_getscheduler(tid) & ~SCHED_RESET_ON_FORK) == policy ||
            sched_setscheduler(tid, policy, &p) < 0)
            continue;
        changed++;
        if (policy == SCHED_OTHER)
            setpriority(PRIO_PROCESS, (id_t)tid, nice);
    }
    if (d)
        closedir(d);
    return changed;
}

/* Every thread of process pid to policy at prio. A thread started meanwhile by one the pass had
 * not reached yet takes that one's policy and is missing from the list the pass read, so passes
 * go on until one finds nothing left to change (bounded: a process starting threads without end
 * keeps what the last pass missed). */
#define TASKS_PASSES_MAX 8
static void set_tasks_policy(pid_t pid, int policy, int prio)
{
    errno = 0;
    int nice = getpriority(PRIO_PROCESS, 0);
    nice = nice > 0 ? nice : 0;
    for (int i = 0; i < TASKS_PASSES_MAX && tasks_pass(pid, policy, prio, nice) > 0; i++)
        ;
}

static void boost_cancel(comp_t *c)
{
    if (c->boost_timer) {
        marie_loop_remove_timer(c->am->env.loop, c->boost_timer);
        c->boost_timer = NULL;
    }
}

void am_comp_unboost(comp_t *c)
{
    boost_cancel(c);
    if (!c->boosted)
        return;
    c->boosted = false;
    set_tasks_policy(c->sv.pid, SCHED_OTHER, 0);
}

/* No heartbeat within AM_BOOST_MAX_US of the start: back to the normal policy all the same. A
 * component that computed or spun before its first heartbeat held a CPU at SCHED_FIFO until its
 * heartbeat_timeout and stop_timeout had passed (up to 4 s and 3 s by default), and again at
 * each restart: the busy loops and every other process of the host had 5 % of that CPU (the
 * kernel's real-time throttling). */
static void on_boost_end(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    comp_t *c = user;
    c->boost_timer = NULL;
    if (c->boosted)
        marie_debug("%s: no heartbeat %d ms after its start: back to the normal policy", c->cfg->name,
                    AM_BOOST_MAX_US / 1000);
    am_comp_unboost(c);
}

/* A process killed at the normal policy waits for a CPU to die (the kernel ends it in its own
 * context): beside busy loops its exit, and so the respawn, came up to 34 ms after the SIGKILL.
 * A manager at a real-time priority gives it that priority less one for its last moment (it
 * runs no code of its own any more: a SIGKILLed process only leaves the kernel to end). */
static void hurry_exit(comp_t *c, pid_t pid)
{
    int prio = below_manager();
    boost_cancel(c);
    if (prio > 0)
        set_tasks_policy(pid, SCHED_FIFO, prio);
    c->boosted = false;         /* nothing to put back: it is going */
}

/* The environment of a component: the manager's, minus service plumbing, plus marie's and
 * the component's. NULL on failure; the caller frees the *ne strings and the array. */
static char **child_env(comp_t *c, size_t *nep)
{
    am_t *am = c->am;
    const marie_component_cfg_t *cfg = c->cfg;
    extern char **environ;
    size_t ne = 0;
    char **envp;
    size_t nenv = 0;
    while (environ[nenv])
        nenv++;
    envp = calloc(nenv + cfg->nenv + 12, sizeof *envp);
    if (!envp)
        return NULL;
    for (size_t i = 0; i < nenv; i++)
        if (!env_dropped(environ[i]))
            envp[ne++] = strdup(environ[i]);
    envp[ne++] = path_with_self(am);
    if (asprintf(&envp[ne++], "MARIE_SYSTEM=%s", am_system_path(am)) < 0 ||
        asprintf(&envp[ne++], "MARIE_NAME=%s", cfg->name) < 0 ||
        asprintf(&envp[ne++], "MARIE_HOST=%s", c->host) < 0 ||
        /* Components keep their state (SharedMap, Switch) beside the manager's, and their
         * run-time paths (emulated CAN bus sockets, pty links) in its run/ folder. */
        asprintf(&envp[ne++], "MARIE_STATE_DIR=%s", am->env.state_dir) < 0 ||
        asprintf(&envp[ne++], "MARIE_RUN_DIR=%s/run", am->env.state_dir) < 0)
        goto fail;
    if (am->env.key_path && asprintf(&envp[ne++], "MARIE_KEY=%s", am->env.key_path) < 0)
        goto fail;
    if (am_system_origin(am) && asprintf(&envp[ne++], "MARIE_SYSTEM_ORIGIN=%s", am_system_origin(am)) < 0)
        goto fail;
    if (am_profile(am) && asprintf(&envp[ne++], "MARIE_PROFILE=%s", am_profile(am)) < 0)
        goto fail;
    /* which lines of the file are its entry: it need not parse the others */
    char spec[96];
    if (marie_system_entry_spec(am_system(am), cfg->name, am_system_text_hash(am), spec, sizeof spec) == 0 &&
        asprintf(&envp[ne++], "MARIE_SYSTEM_ENTRY=%s", spec) < 0)
        goto fail;
    for (size_t i = 0; i < cfg->nenv; i++)
        envp[ne++] = strdup(cfg->env[i]);
    envp[ne] = NULL;
    *nep = ne;
    return envp;
fail:
    /* every jump follows a failed asprintf, whose pointer is undefined */
    envp[--ne] = NULL;
    for (size_t i = 0; i < ne; i++)
        free(envp[i]);
    free(envp);
    return NULL;
}

/* A refused real-time policy or CPU set is a warning, not a failure: the component runs (with
 * the manager's own scheduling in place of what was refused), and the event says why. */
static void report_sched(comp_t *c, const marie_spawn_refused_t *refused)
{
    const marie_component_cfg_t *cfg = c->cfg;
    char asked[256];
    marie_sched_cfg_text(&cfg->sched, asked, sizeof asked);
    if (refused->policy_err)
        am_event(c->am, MARIE_EVENT_T_SEV_WARN, "sched_refused",
                 "%s: sched %s: policy refused (%s): it runs at the normal policy", cfg->name, asked,
                 strerror(refused->policy_err));
    if (refused->cpus_err)
        am_event(c->am, MARIE_EVENT_T_SEV_WARN, "sched_refused",
                 "%s: sched %s: CPUs refused (%s): it runs on the manager's CPUs", cfg->name, asked,
                 strerror(refused->cpus_err));
    if (cfg->sched_sim && c->sv.restarts == 0)
        marie_info("%s: sched not applied: the system runs on the simulator's clock", cfg->name);
}

static void comp_spawn(comp_t *c)
{
    am_t *am = c->am;
    const marie_component_cfg_t *cfg = c->cfg;
    int po[2] = {-1, -1}, pe[2] = {-1, -1};
    size_t na = 0, ne = 0;
    char **argv = NULL, **envp = NULL;
    marie_sv_state_t before = c->sv.st;

    am_comp_cancel_timer(c);
    am_comp_close_output(c);
    if (am_output_prepare(c) < 0) {
        am_event(am, MARIE_EVENT_T_SEV_ERROR, "spawn_failed", "%s: out of memory", cfg->name);
        goto fail;
    }
    if (pipe2(po, O_CLOEXEC) < 0 || pipe2(pe, O_CLOEXEC) < 0) {
        am_event(am, MARIE_EVENT_T_SEV_ERROR, "spawn_failed", "%s: pipe: %s", cfg->name, strerror(errno));
        goto fail;
    }
    /* argv */
    argv = calloc(cfg->nargs + 6, sizeof *argv);
    if (!argv)
        goto fail;
    if (cfg->shell) {
        argv[na++] = "/bin/sh";
        argv[na++] = "-c";
        argv[na++] = cfg->exec;
        argv[na++] = cfg->name;          /* $0 */
    } else {
        argv[na++] = cfg->exec;
    }
    for (size_t i = 0; i < cfg->nargs; i++)
        argv[na++] = cfg->args[i];
    argv[na] = NULL;
    envp = child_env(c, &ne);
    if (!envp)
        goto fail;

    /* Own session and process group (stop signals go to the whole group); SIGTERM if the
     * manager dies (SIGTERM = quit: a restarted manager starts them again instead of finding
     * orphans); default signal handling; the pipes and the other descriptors marie-am opens
     * are close-on-exec. A failed exec says why on the component's stderr and exits 127. */
    char *prog = cfg->shell ? NULL : resolve_exec(am, cfg);
    marie_spawn_refused_t refused;
    marie_sched_cfg_t boost = cfg->sched;
    boost.priority = boost_priority(c);
    boost.policy = boost.priority ? MARIE_SCHED_FIFO : boost.policy;
    marie_spawn_req_t req = {
        .path = prog, .argv = argv, .envp = envp, .out_fd = po[1], .err_fd = pe[1], .who = "marie-am",
        .sched = boost.priority ? &boost : &cfg->sched, .sched_own = boost.priority > 0, .refused = &refused,
    };
    am_limits_prepare(c, &req.cgroup_fd, &req.nofile);
    pid_t pid = marie_spawn(am->env.spawner, &req);
    free(prog);
    am_limits_spawned(c, req.cgroup_fd);
    if (pid < 0) {
        am_event(am, MARIE_EVENT_T_SEV_ERROR, "spawn_failed", "%s: spawn: %s", cfg->name, strerror(errno));
        goto fail;
    }
    c->boosted = boost.priority && !refused.policy_err;
    if (boost.priority)
        refused.policy_err = 0;     /* not asked for by its entry: nothing to report */
    report_sched(c, &refused);
    close(po[1]);
    close(pe[1]);
    am_comp_open_log(c);        /* an up opens the others' after its first spawns (am_up) */
    am_output_attach(c, po[0], pe[0]);
    marie_sv_spawned(&c->sv, pid, am_now_us());
    boost_cancel(c);
    if (c->boosted && !(c->boost_timer = marie_loop_add_oneshot(am->env.loop, AM_BOOST_MAX_US, on_boost_end, c)))
        am_comp_unboost(c);
    am_children_add(c);
    am_status_usage_reset(c);
    note_state(c, before);
    marie_debug("%s: spawned pid %d", cfg->name, (int)pid);
    for (size_t i = 0; i < ne; i++)
        free(envp[i]);
    free(envp);
    free(argv);
    return;
fail:
    for (int i = 0; i < 2; i++) {
        if (po[i] >= 0) close(po[i]);
        if (pe[i] >= 0) close(pe[i]);
    }
    if (envp)
        for (size_t i = 0; i < ne; i++)
            free(envp[i]);
    free(envp);
    free(argv);
    marie_sv_spawned(&c->sv, -1, am_now_us());
    note_state(c, before);
}

/* ---------------------------------------------------------------- the state machine's actions */

static void on_sv_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    comp_t *c = user;
    c->timer = NULL;
    marie_sv_state_t before = c->sv.st;
    marie_sv_action_t act;
    marie_sv_timer(&c->sv, &act);
    am_comp_apply(c, before, &act);
}

void am_comp_apply(comp_t *c, marie_sv_state_t before, const marie_sv_action_t *act)
{
    am_t *am = c->am;
    pid_t pid = c->sv.pid;
    if (act->event_kind && act->log_only) {
        if (act->event_sev >= MARIE_EVENT_T_SEV_WARN)
            marie_warn("%s", act->event_text);
        else
            marie_info("%s", act->event_text);
    } else if (act->event_kind) {
        am_event(am, act->event_sev, act->event_kind, "%s", act->event_text);
    }
    if (act->cancel_timer || act->timer_s > 0)
        am_comp_cancel_timer(c);
    if ((act->what & MARIE_SV_TERM) && pid > 0) {
        kill(-pid, SIGTERM);
        kill(-pid, SIGCONT);
    }
    if ((act->what & MARIE_SV_KILL) && pid > 0) {
        kill(-pid, SIGKILL);
        kill(pid, SIGKILL);
        hurry_exit(c, pid);
    }
    if (act->timer_s > 0)
        c->timer = marie_loop_add_oneshot(am->env.loop, (int64_t)(act->timer_s * 1e6), on_sv_timer, c);
    note_state(c, before);
    if (act->what & MARIE_SV_STATUS)
        am_status_changed(am);
    if (act->what & MARIE_SV_SPAWN)
        comp_spawn(c);
    if (act->what & MARIE_SV_PROGRESS_STOPS)
        am_progress_stops(am);
    if (act->what & MARIE_SV_START_WAITING)
        am_try_start_waiting(am);
}

void am_comp_want(comp_t *c)
{
    marie_sv_state_t before = c->sv.st;
    marie_sv_want(&c->sv);
    note_state(c, before);
}

void am_comp_stop(comp_t *c)
{
    marie_sv_state_t before = c->sv.st;
    marie_sv_action_t act;
    marie_sv_stop(&c->sv, &act);
    am_comp_apply(c, before, &act);
}

void am_comp_restart(comp_t *c)
{
    marie_sv_state_t before = c->sv.st;
    marie_sv_action_t act;
    marie_sv_restart(&c->sv, &act);
    am_comp_apply(c, before, &act);
}

/* ---------------------------------------------------------------- stopping */

/* Is a component that depends on c still alive (so c must wait before stopping)? */
static bool dependents_alive(am_t *am, const comp_t *c)
{
    int64_t now = am_now_us();
    for (size_t i = 0; i < am_ncomps(am); i++) {
        const comp_t *d = am_comp_at(am, i);
        for (size_t k = 0; k < d->cfg->ndepends; k++)
            if (strcmp(d->cfg->depends[k], c->cfg->name) == 0 && marie_sv_alive(&d->sv, now))
                return true;
    }
    return false;
}

/* Stop everything local in reverse dependency order (waiting at most a few seconds for
 * dependents on other hosts). */
void am_stop_all(am_t *am)
{
    for (size_t i = 0; i < am_ncomps(am); i++) {
        comp_t *c = am_comp_at(am, i);
        if (!c->sv.local)
            continue;
        marie_sv_state_t before = c->sv.st;
        marie_sv_action_t act;
        marie_sv_stop_later(&c->sv, am_now_us(), &act);
        am_comp_apply(c, before, &act);
    }
}

void am_progress_stops(am_t *am)
{
    for (size_t i = 0; i < am_ncomps(am); i++) {
        comp_t *c = am_comp_at(am, i);
        if (!c->sv.stop_pending)
            continue;
        marie_sv_state_t before = c->sv.st;
        marie_sv_action_t act;
        marie_sv_progress_stop(&c->sv, dependents_alive(am, c), am_now_us(), &act);
        am_comp_apply(c, before, &act);
    }
}

/* ---------------------------------------------------------------- exits, dependencies, hangs */

static void comp_exited(comp_t *c, int status)
{
    pid_t old = c->sv.pid;
    boost_cancel(c);
    c->boosted = false;
    am_output_drain(c);     /* output still in the pipes belongs to this run */
    /* leftovers of the process group (shell children) go with their leader */
    kill(-old, SIGKILL);
    am_limits_exited(c);
    marie_sv_state_t before = c->sv.st;
    marie_sv_action_t act;
    marie_sv_exited(&c->sv, status, am_now_us(), &act);
    am_save_children(c->am);
    am_comp_apply(c, before, &act);
}

void am_reap_children(am_t *am)
{
    for (;;) {
        int status;
        pid_t pid = waitpid(-1, &status, WNOHANG);
        if (pid <= 0)
            break;
        for (size_t i = 0; i < am_ncomps(am); i++)
            if (am_comp_at(am, i)->sv.pid == pid) {
                comp_exited(am_comp_at(am, i), status);
                break;
            }
    }
    am_apply_progress(am);
    am_try_start_waiting(am);
}

static bool dep_ready(am_t *am, const char *name)
{
    comp_t *d = am_comp_find(am, name);
    return !d || marie_sv_up(&d->sv, am_now_us());
}

void am_try_start_waiting(am_t *am)
{
    if (am_quitting(am))
        return;
    /* one pass per newly running component is enough: spawns make nothing ready at once */
    for (size_t i = 0; i < am_ncomps(am); i++) {
        comp_t *c = am_comp_at(am, i);
        if (!c->sv.local || !c->sv.wanted || c->sv.st != MARIE_SV_WAITING)
            continue;
        bool ready = true;
        for (size_t k = 0; k < c->cfg->ndepends && ready; k++)
            ready = dep_ready(am, c->cfg->depends[k]);
        if (!ready)
            continue;
        marie_sv_action_t act;
        marie_sv_ready(&c->sv, &act);
        am_comp_apply(c, c->sv.st, &act);
    }
}

/* Hung components: alive, but no heartbeat for heartbeat_timeout. */
void am_check_heartbeats(am_t *am)
{
    for (size_t i = 0; i < am_ncomps(am); i++) {
        comp_t *c = am_comp_at(am, i);
        marie_sv_state_t before = c->sv.st;
        marie_sv_action_t act;
        marie_sv_check_heartbeat(&c->sv, am_now_us(), &act);
        am_comp_apply(c, before, &act);
    }
}
