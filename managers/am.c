/* marie-am: the application manager of one host: starts, watches and restarts the
 * components the system file assigns to it, and obeys authenticated orders. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <stdarg.h>
#include <sys/prctl.h>
#include <sys/signalfd.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <lcm/lcm.h>
#include <sodium.h>
#include <systemd/sd-daemon.h>

#include "core/component.h"
#include "core/config.h"
#include "core/file.h"
#include "core/log.h"
#include "core/loop.h"
#include "core/time.h"
#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_heartbeat_t.h"
#include "lcmtypes/marie_lifecycle_command_t.h"
#include "managers/am_proto.h"
#include "managers/progcheck.h"
#include "core/auth.h"
#include "managers/logcap.h"
#include "core/procstat.h"
#include "core/typeinfo.h"

/* The manager's view of a component. */
typedef enum {
    CS_STOPPED = 0,   /* not wanted */
    CS_WAITING,       /* wanted, its dependencies are not all running yet */
    CS_STARTING,      /* spawned, no running heartbeat yet */
    CS_RUNNING,
    CS_STOPPING,      /* stop signal sent, SIGKILL when stop_timeout passes */
    CS_BACKOFF,       /* exited, respawn after a delay */
    CS_FAILED,        /* gave up, or failed with policy never */
    CS_EXITED,        /* exited cleanly and the policy does not restart it */
} cstate_t;

static const char *const cstate_names[] = {
    "stopped", "waiting", "starting", "running", "stopping", "backoff", "failed", "exited",
};

#define MAX_FAIL_TIMES 64

typedef struct am am_t;

typedef struct {
    am_t *am;
    struct comp *c;
    int fd;
    int stream;
    marie_linebuf_t lb;
} outpipe_t;

typedef struct comp {
    am_t *am;
    const marie_component_cfg_t *cfg;
    char host[128];             /* effective host (a move changes it) */
    bool local;
    bool wanted;
    cstate_t st;
    pid_t pid;
    int64_t started_us;         /* monotonic */
    int64_t start_ticks;        /* /proc start time, with pid names the process */
    int restarts;
    int last_exit;
    int64_t fail_times[MAX_FAIL_TIMES];
    int nfail_times;
    double next_backoff_s;
    marie_timer_t *timer;       /* backoff or kill timer */
    bool restart_after_stop;
    bool count_failure;         /* the coming exit is a failure (hang, failed state) */
    bool stop_pending;          /* down: wait for dependents first */
    int64_t stop_pending_since;
    /* heartbeat (any host) */
    int64_t hb_mono;
    int hb_state;
    int hb_pid;
    /* the component's manager status (remote hosts) */
    int64_t st_mono;
    bool st_running;
    /* usage */
    marie_cpu_sample_t cpu_prev;
    float cpu;
    int64_t rss;
    /* output */
    outpipe_t out[2];
    marie_ratelimit_t rl;
    int64_t drops_pending, drops_total, log_seq;
    marie_logfile_t *logf;
} comp_t;

struct am {
    char host[128];
    char *state_dir;
    char *key_path;
    char *url;
    char self_dir[PATH_MAX];
    marie_loop_t *loop;
    lcm_t *lcm;
    int sigfd;
    marie_auth_t *auth;
    marie_replay_t *replay;
    int64_t order_lifetime_us, max_skew_us;    /* the replay table's window */
    marie_ratelimit_t refusal_rl;              /* answers and events for refused orders */
    int64_t refusals_unannounced;
    /* the loaded system */
    marie_system_t *sys;
    char sys_hash[65];
    char *sys_path;             /* path given to components as MARIE_SYSTEM */
    char *profile;
    bool up;
    comp_t *comps;
    size_t ncomps;
    /* settings */
    double status_hz;
    double log_rate, log_burst;
    int64_t log_max_bytes;
    int log_keep;
    /* state */
    int64_t start_mono;
    int64_t status_seq, event_seq, orders_refused, lc_seq, bad_input;
    marie_cpu_sample_t self_cpu;
    float self_cpu_pct;
    int64_t self_rss;
    bool status_pending;
    bool quitting;
    int64_t quit_deadline;
    uint64_t watchdog_us;
    marie_timer_t *status_timer;
    bool opt_status_hz, opt_log_rate, opt_log_max, opt_log_keep;   /* given on the command line */
    /* automatic placement (the system's balance: section; NULL without one) */
    balance_cfg_t bal_cfg;
    balance_t *bal;
    char bal_sender[160];       /* "balance@HOST": its orders' sender */
    char bal_last[256];         /* its last decision, in the status */
    int64_t adopt_until;        /* a returning manager learns the placement before it starts */
};

static int64_t now_us(void) { return marie_mono_us(); }

/* ---------------------------------------------------------------- events */

static void am_event(am_t *am, int sev, const char *kind, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void am_event(am_t *am, int sev, const char *kind, const char *fmt, ...)
{
    char text[512], source[160];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    snprintf(source, sizeof source, "marie-am@%s", am->host);
    marie_event_t ev = {
        .utime = marie_wall_us(), .source = source, .seq = ++am->event_seq,
        .severity = (int8_t)sev, .kind = (char *)kind, .text = text,
    };
    marie_event_t_publish(am->lcm, MARIE_CH_EVENT, &ev);
    if (sev >= MARIE_EVENT_T_SEV_WARN)
        marie_warn("%s: %s", kind, text);
    else
        marie_info("%s: %s", kind, text);
}

static void status_changed(am_t *am);
static void apply_move(am_t *am, struct comp *c, const char *host);
static void save_up_state(am_t *am);
static void am_up(am_t *am);

/* ---------------------------------------------------------------- lookup */

static comp_t *comp_find(am_t *am, const char *name)
{
    for (size_t i = 0; i < am->ncomps; i++)
        if (strcmp(am->comps[i].cfg->name, name) == 0)
            return &am->comps[i];
    return NULL;
}

static bool comp_matches(const comp_t *c, const char *target)
{
    return strcmp(target, "*") == 0 || strcmp(c->cfg->name, target) == 0 ||
           (c->cfg->group && strcmp(c->cfg->group, target) == 0);
}

static void comp_set_state(comp_t *c, cstate_t st)
{
    if (c->st != st) {
        marie_debug("%s: %s -> %s", c->cfg->name, cstate_names[c->st], cstate_names[st]);
        c->st = st;
        status_changed(c->am);
    }
}

static void comp_cancel_timer(comp_t *c)
{
    if (c->timer) {
        marie_loop_remove_timer(c->am->loop, c->timer);
        c->timer = NULL;
    }
}

/* ---------------------------------------------------------------- output capture */

static void log_line_cb(const char *line, size_t len, void *user)
{
    outpipe_t *op = user;
    comp_t *c = op->c;
    am_t *am = op->am;
    int64_t wall = marie_wall_us();
    if (!marie_ratelimit_take(&c->rl, now_us())) {
        c->drops_pending++;
        c->drops_total++;
        return;
    }
    char text[MARIE_LINE_MAX + 1];
    memcpy(text, line, len);
    text[len] = 0;
    marie_log_line_t m = {
        .utime = wall, .host = am->host, .component = c->cfg->name, .pid = c->pid,
        .stream = (int8_t)op->stream, .seq = ++c->log_seq, .dropped = c->drops_pending,
        .request_seq = 0, .text = text,
    };
    marie_log_line_t_publish(am->lcm, MARIE_CH_LOG, &m);
    if (c->logf) {
        char hdr[96];
        time_t secs = (time_t)(wall / 1000000);
        struct tm tm;
        gmtime_r(&secs, &tm);
        int hl = 0;
        if (c->drops_pending) {
            char note[96];
            int nl = snprintf(note, sizeof note, "-- %lld lines dropped (rate limit)\n", (long long)c->drops_pending);
            marie_logfile_write(c->logf, note, (size_t)nl);
        }
        hl = snprintf(hdr, sizeof hdr, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ %s ", tm.tm_year + 1900,
                      tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec,
                      (int)(wall / 1000 % 1000), op->stream == MARIE_LOG_LINE_T_STDERR ? "err" : "out");
        char buf[sizeof hdr + MARIE_LINE_MAX + 2];
        memcpy(buf, hdr, (size_t)hl);
        memcpy(buf + hl, line, len);
        buf[hl + len] = '\n';
        marie_logfile_write(c->logf, buf, (size_t)hl + len + 1);
    }
    c->drops_pending = 0;
}

static void outpipe_close(outpipe_t *op)
{
    if (op->fd < 0)
        return;
    marie_linebuf_flush(&op->lb, log_line_cb, op);
    marie_loop_remove_fd(op->am->loop, op->fd);
    close(op->fd);
    op->fd = -1;
}

/* Read what is there; returns 0 at end of file. */
static int outpipe_drain(outpipe_t *op)
{
    char buf[4096];
    for (int rounds = 0; rounds < 16; rounds++) {
        ssize_t n = read(op->fd, buf, sizeof buf);
        if (n > 0) {
            marie_linebuf_feed(&op->lb, buf, (size_t)n, log_line_cb, op);
            continue;
        }
        if (n == 0)
            return 0;
        if (errno == EINTR)
            continue;
        return errno == EAGAIN ? 1 : 0;
    }
    return 1;
}

static void on_outpipe(marie_loop_t *loop, int fd, short revents, void *user)
{
    outpipe_t *op = user;
    if (outpipe_drain(op) == 0)
        outpipe_close(op);
}

/* ---------------------------------------------------------------- spawning */

static void comp_spawn(comp_t *c);
static void try_start_waiting(am_t *am);
static void save_children(am_t *am);

static char *path_with_self(am_t *am)
{
    const char *p = getenv("PATH");
    size_t n = strlen(am->self_dir) + (p ? strlen(p) : 0) + 8;
    char *s = malloc(n);
    if (s)
        snprintf(s, n, "PATH=%s%s%s", am->self_dir, p ? ":" : "", p ? p : "");
    return s;
}

static bool env_dropped(const char *kv)
{
    static const char *const drop[] = {"NOTIFY_SOCKET=", "WATCHDOG_USEC=", "WATCHDOG_PID=",
                                       "LISTEN_FDS=", "LISTEN_PID=", "LISTEN_FDNAMES=", "PATH=",
                                       "MARIE_SYSTEM=", "MARIE_NAME=", "MARIE_PROFILE=", "MARIE_HOST=",
                                       "MARIE_STATE_DIR=", "MARIE_KEY=", NULL};
    for (int i = 0; drop[i]; i++)
        if (strncmp(kv, drop[i], strlen(drop[i])) == 0)
            return true;
    return false;
}

/* The program to exec: a name without '/' is looked up in marie-am's own directory, then
 * in PATH (execvpe would search the manager's PATH only). NULL: let execvpe report it. */
static char *resolve_exec(am_t *am, const char *name)
{
    return marie_am_resolve_exec(am->self_dir, name);
}

static void child_exec(comp_t *c, int outfd, int errfd, pid_t parent, const char *prog, char **argv, char **envp)
{
    /* Own session and process group: stop signals go to the whole group. */
    setsid();
    /* If the manager dies, its components quit (SIGTERM = quit); a restarted manager
     * starts them again instead of finding orphans. */
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != parent)
        _exit(127);
    sigset_t none;
    sigemptyset(&none);
    sigprocmask(SIG_SETMASK, &none, NULL);
    for (int s = 1; s < NSIG; s++)
        if (s != SIGKILL && s != SIGSTOP)
            signal(s, SIG_DFL);
    int nul = open("/dev/null", O_RDONLY);
    if (nul >= 0 && nul != 0) {
        dup2(nul, 0);
        close(nul);
    }
    dup2(outfd, 1);
    dup2(errfd, 2);
    /* pipes and every other descriptor of the manager are close-on-exec */
    if (prog)
        execve(prog, argv, envp);
    else
        execvpe(argv[0], argv, envp);
    dprintf(2, "marie-am: exec %s: %s\n", argv[0], strerror(errno));
    _exit(127);
}

static void comp_spawn(comp_t *c)
{
    am_t *am = c->am;
    const marie_component_cfg_t *cfg = c->cfg;
    int po[2] = {-1, -1}, pe[2] = {-1, -1};
    size_t na = 0, ne = 0;
    char **argv = NULL, **envp = NULL;
    extern char **environ;

    comp_cancel_timer(c);
    for (int i = 0; i < 2; i++)
        outpipe_close(&c->out[i]);
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
    /* env: the manager's, minus service plumbing, plus marie's and the component's */
    size_t nenv = 0;
    while (environ[nenv])
        nenv++;
    envp = calloc(nenv + cfg->nenv + 10, sizeof *envp);
    if (!envp)
        goto fail;
    for (size_t i = 0; i < nenv; i++)
        if (!env_dropped(environ[i]))
            envp[ne++] = strdup(environ[i]);
    envp[ne++] = path_with_self(am);
    if (asprintf(&envp[ne++], "MARIE_SYSTEM=%s", am->sys_path) < 0 ||
        asprintf(&envp[ne++], "MARIE_NAME=%s", cfg->name) < 0 ||
        asprintf(&envp[ne++], "MARIE_HOST=%s", c->host) < 0 ||
        /* Components keep their state (SharedMap, Switch) beside the manager's, and their
         * run-time paths (emulated CAN bus sockets, pty links) in its run/ folder. */
        asprintf(&envp[ne++], "MARIE_STATE_DIR=%s", am->state_dir) < 0 ||
        asprintf(&envp[ne++], "MARIE_RUN_DIR=%s/run", am->state_dir) < 0)
        goto fail;
    if (am->key_path && asprintf(&envp[ne++], "MARIE_KEY=%s", am->key_path) < 0)
        goto fail;
    if (am->profile && asprintf(&envp[ne++], "MARIE_PROFILE=%s", am->profile) < 0)
        goto fail;
    for (size_t i = 0; i < cfg->nenv; i++)
        envp[ne++] = strdup(cfg->env[i]);
    envp[ne] = NULL;

    char *prog = cfg->shell ? NULL : resolve_exec(am, cfg->exec);
    pid_t parent = getpid();
    pid_t pid = fork();
    if (pid < 0) {
        am_event(am, MARIE_EVENT_T_SEV_ERROR, "spawn_failed", "%s: fork: %s", cfg->name, strerror(errno));
        free(prog);
        goto fail;
    }
    if (pid == 0)
        child_exec(c, po[1], pe[1], parent, prog, argv, envp);
    free(prog);
    close(po[1]);
    close(pe[1]);
    int rd[2] = {po[0], pe[0]};
    for (int i = 0; i < 2; i++) {
        outpipe_t *op = &c->out[i];
        op->am = am;
        op->c = c;
        op->fd = rd[i];
        op->stream = i == 0 ? MARIE_LOG_LINE_T_STDOUT : MARIE_LOG_LINE_T_STDERR;
        op->lb.len = 0;
        fcntl(op->fd, F_SETFL, fcntl(op->fd, F_GETFL) | O_NONBLOCK);
        marie_loop_add_fd(am->loop, op->fd, POLLIN, on_outpipe, op);
    }
    c->pid = pid;
    c->started_us = now_us();
    c->start_ticks = 0;
    marie_proc_starttime(pid, &c->start_ticks);
    save_children(am);
    c->hb_mono = 0;
    c->hb_state = -1;
    c->cpu_prev.at_us = 0;
    c->cpu = 0;
    c->rss = 0;
    c->restart_after_stop = false;
    c->count_failure = false;
    /* without heartbeats, a live process is all we can know */
    comp_set_state(c, cfg->heartbeat_timeout_s > 0 ? CS_STARTING : CS_RUNNING);
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
    c->last_exit = 127;
    comp_set_state(c, CS_FAILED);
}

/* ---------------------------------------------------------------- leftovers */

/* The live children, so that a manager restarted after a crash can end the ones that
 * outlived it (a component that ignores SIGTERM survives PR_SET_PDEATHSIG). */
static void save_children(am_t *am)
{
    char path[PATH_MAX], tmp[PATH_MAX + 8];
    snprintf(path, sizeof path, "%s/children", am->state_dir);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    FILE *f = fopen(tmp, "w");
    if (!f)
        return;
    for (size_t i = 0; i < am->ncomps; i++) {
        comp_t *c = &am->comps[i];
        if (c->pid > 0 && c->local)
            fprintf(f, "%d %lld %s\n", (int)c->pid, (long long)c->start_ticks, c->cfg->name);
    }
    if (fclose(f) == 0)
        rename(tmp, path);
}

static void kill_leftovers(am_t *am)
{
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/children", am->state_dir);
    FILE *f = fopen(path, "r");
    if (!f)
        return;
    int pid;
    long long ticks;
    char name[128];
    while (fscanf(f, "%d %lld %127s", &pid, &ticks, name) == 3) {
        int64_t now_ticks;
        /* the same pid and start time: still that process, not a reused pid */
        if (pid > 1 && marie_proc_starttime(pid, &now_ticks) == 0 && now_ticks == ticks) {
            marie_warn("%s (pid %d) outlived the previous marie-am: SIGKILL to its process group", name, pid);
            kill(-pid, SIGKILL);
            kill(pid, SIGKILL);
        }
    }
    fclose(f);
    unlink(path);
}

/* ---------------------------------------------------------------- stopping */

static void on_kill_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    comp_t *c = user;
    c->timer = NULL;
    if (c->pid > 0) {
        marie_warn("%s: still alive %.1f s after the stop signal: SIGKILL", c->cfg->name, c->cfg->stop_timeout_s);
        kill(-c->pid, SIGKILL);
        kill(c->pid, SIGKILL);
    }
}

/* Stop signal to the process group, SIGKILL after stop_timeout. */
static void comp_stop(comp_t *c, bool restart_after)
{
    c->stop_pending = false;
    if (c->pid <= 0) {
        comp_cancel_timer(c);
        if (restart_after) {
            comp_set_state(c, CS_WAITING);
            try_start_waiting(c->am);
        } else if (c->st != CS_FAILED && c->st != CS_EXITED) {
            comp_set_state(c, CS_STOPPED);
        }
        return;
    }
    c->restart_after_stop = restart_after;
    if (c->st == CS_STOPPING)
        return;
    comp_set_state(c, CS_STOPPING);
    kill(-c->pid, SIGTERM);
    kill(-c->pid, SIGCONT);
    comp_cancel_timer(c);
    double t = c->cfg->stop_timeout_s > 0 ? c->cfg->stop_timeout_s : 0.001;
    c->timer = marie_loop_add_oneshot(c->am->loop, (int64_t)(t * 1e6), on_kill_timer, c);
}

/* Is a component that depends on c still alive (so c must wait before stopping)? */
static bool dependents_alive(am_t *am, const comp_t *c)
{
    int64_t now = now_us();
    for (size_t i = 0; i < am->ncomps; i++) {
        const comp_t *d = &am->comps[i];
        for (size_t k = 0; k < d->cfg->ndepends; k++) {
            if (strcmp(d->cfg->depends[k], c->cfg->name) != 0)
                continue;
            if (d->local) {
                if (d->pid > 0)
                    return true;
            } else if (d->hb_mono && now - d->hb_mono < 1500000 && d->hb_state != MARIE_STATE_EXITED) {
                return true;
            }
        }
    }
    return false;
}

/* Stop everything local in reverse dependency order (waiting at most a few seconds for
 * dependents on other hosts). */
static void stop_all(am_t *am)
{
    for (size_t i = 0; i < am->ncomps; i++) {
        comp_t *c = &am->comps[i];
        if (!c->local)
            continue;
        c->wanted = false;
        if (c->pid > 0 && c->st != CS_STOPPING) {
            c->stop_pending = true;
            c->stop_pending_since = now_us();
        } else if (c->pid <= 0) {
            comp_stop(c, false);
        }
    }
}

static void progress_stops(am_t *am)
{
    int64_t now = now_us();
    for (size_t i = 0; i < am->ncomps; i++) {
        comp_t *c = &am->comps[i];
        if (!c->stop_pending)
            continue;
        double cap = c->cfg->stop_timeout_s + 2.0;
        if (!dependents_alive(am, c) || now - c->stop_pending_since > (int64_t)(cap * 1e6))
            comp_stop(c, false);
    }
}

/* ---------------------------------------------------------------- exits and respawn */

static void on_backoff_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    comp_t *c = user;
    c->timer = NULL;
    if (c->st == CS_BACKOFF && c->wanted && c->local)
        comp_spawn(c);
}

static int failures_in_window(comp_t *c, int64_t now)
{
    int n = 0;
    for (int i = 0; i < c->nfail_times; i++)
        if (now - c->fail_times[i] <= (int64_t)(c->cfg->restart.window_s * 1e6))
            n++;
    return n;
}

static void record_failure(comp_t *c, int64_t now)
{
    if (c->nfail_times == MAX_FAIL_TIMES) {
        memmove(c->fail_times, c->fail_times + 1, (MAX_FAIL_TIMES - 1) * sizeof c->fail_times[0]);
        c->nfail_times--;
    }
    c->fail_times[c->nfail_times++] = now;
}

static void describe_exit(int status, char *buf, size_t len)
{
    if (WIFEXITED(status))
        snprintf(buf, len, "exit status %d", WEXITSTATUS(status));
    else if (WIFSIGNALED(status))
        snprintf(buf, len, "killed by signal %d (%s)", WTERMSIG(status), strsignal(WTERMSIG(status)));
    else
        snprintf(buf, len, "status 0x%x", status);
}

static void comp_exited(comp_t *c, int status)
{
    am_t *am = c->am;
    const marie_restart_cfg_t *rc = &c->cfg->restart;
    int64_t now = now_us();
    pid_t old = c->pid;
    char why[96];
    describe_exit(status, why, sizeof why);

    /* output still in the pipes belongs to this run */
    for (int i = 0; i < 2; i++)
        if (c->out[i].fd >= 0 && outpipe_drain(&c->out[i]) == 0)
            outpipe_close(&c->out[i]);
    /* leftovers of the process group (shell children) go with their leader */
    kill(-old, SIGKILL);
    c->pid = 0;
    save_children(am);
    c->hb_state = -1;
    comp_cancel_timer(c);
    c->last_exit = WIFEXITED(status) ? WEXITSTATUS(status) : WIFSIGNALED(status) ? -WTERMSIG(status) : -1;
    double run_s = (double)(now - c->started_us) * 1e-6;
    bool failure = c->count_failure || !(WIFEXITED(status) && WEXITSTATUS(status) == 0);

    if (c->st == CS_STOPPING && !c->restart_after_stop) {
        marie_info("%s: stopped (%s)", c->cfg->name, why);
        comp_set_state(c, CS_STOPPED);
        progress_stops(am);
        return;
    }
    if (!c->wanted || !c->local) {
        comp_set_state(c, CS_STOPPED);
        return;
    }
    bool asked = c->st == CS_STOPPING && c->restart_after_stop && !c->count_failure;
    bool respawn = asked || rc->policy == MARIE_RESTART_ALWAYS ||
                   (rc->policy == MARIE_RESTART_ON_FAILURE && failure);
    if (!respawn) {
        am_event(am, failure ? MARIE_EVENT_T_SEV_ERROR : MARIE_EVENT_T_SEV_INFO, failure ? "failed" : "exited",
                 "%s (pid %d) %s after %.1f s; policy does not restart it", c->cfg->name, (int)old, why, run_s);
        comp_set_state(c, failure ? CS_FAILED : CS_EXITED);
        return;
    }
    if (failure && !asked) {
        record_failure(c, now);
        int nf = failures_in_window(c, now);
        if (rc->max_failures > 0 && nf >= rc->max_failures) {
            am_event(am, MARIE_EVENT_T_SEV_ERROR, "gave_up",
                     "%s: %d failures within %.0f s, last %s: not restarting it", c->cfg->name, nf,
                     rc->window_s, why);
            comp_set_state(c, CS_FAILED);
            return;
        }
    }
    double delay = 0;
    if (asked || run_s >= rc->stable_s) {
        c->next_backoff_s = rc->backoff_min_s;      /* a stable run resets the backoff */
    } else {
        delay = c->next_backoff_s;
        double nb = c->next_backoff_s * 2;
        if (nb < rc->backoff_min_s)
            nb = rc->backoff_min_s;
        if (nb > rc->backoff_max_s)
            nb = rc->backoff_max_s;
        c->next_backoff_s = nb;
    }
    c->restarts++;
    if (!asked)
        am_event(am, MARIE_EVENT_T_SEV_WARN, "respawn", "%s (pid %d) %s after %.1f s; restart %d in %.2f s",
                 c->cfg->name, (int)old, why, run_s, c->restarts, delay);
    if (delay <= 0) {
        comp_spawn(c);
    } else {
        comp_set_state(c, CS_BACKOFF);
        c->timer = marie_loop_add_oneshot(am->loop, (int64_t)(delay * 1e6), on_backoff_timer, c);
    }
}

static void reap_children(am_t *am)
{
    for (;;) {
        int status;
        pid_t pid = waitpid(-1, &status, WNOHANG);
        if (pid <= 0)
            break;
        for (size_t i = 0; i < am->ncomps; i++)
            if (am->comps[i].pid == pid) {
                comp_exited(&am->comps[i], status);
                break;
            }
    }
    try_start_waiting(am);
}

static void on_signalfd(marie_loop_t *loop, int fd, short revents, void *user)
{
    am_t *am = user;
    struct signalfd_siginfo si[8];
    ssize_t n = read(fd, si, sizeof si);
    if (n <= 0)
        return;
    bool chld = false;
    for (size_t i = 0; i < (size_t)n / sizeof si[0]; i++) {
        if (si[i].ssi_signo == SIGCHLD) {
            chld = true;
        } else if (!am->quitting) {
            marie_info("signal %d: stopping components, then exiting", (int)si[i].ssi_signo);
            sd_notify(0, "STOPPING=1");
            am->quitting = true;
            double longest = 0;
            for (size_t k = 0; k < am->ncomps; k++)
                if (am->comps[k].cfg->stop_timeout_s > longest)
                    longest = am->comps[k].cfg->stop_timeout_s;
            am->quit_deadline = now_us() + (int64_t)((longest + 3.0) * 1e6);
            stop_all(am);
            progress_stops(am);
        }
    }
    if (chld)
        reap_children(am);
}

/* ---------------------------------------------------------------- dependencies */

static bool dep_ready(am_t *am, const char *name)
{
    comp_t *d = comp_find(am, name);
    if (!d)
        return true;
    int64_t now = now_us();
    if (d->local && d->cfg->heartbeat_timeout_s <= 0)
        return d->pid > 0 && d->st == CS_RUNNING;
    if (d->local)
        return d->pid > 0 && (d->st == CS_RUNNING);
    double fresh = d->cfg->heartbeat_timeout_s > 2 ? d->cfg->heartbeat_timeout_s : 2;
    if (d->hb_mono && now - d->hb_mono < (int64_t)(fresh * 1e6) &&
        (d->hb_state == MARIE_STATE_RUNNING || d->hb_state == MARIE_STATE_PAUSED ||
         d->hb_state == MARIE_STATE_DEGRADED))
        return true;
    return d->st_running && now - d->st_mono < 2000000;
}

static void try_start_waiting(am_t *am)
{
    if (am->quitting)
        return;
    /* one pass per newly running component is enough: spawns make nothing ready at once */
    for (size_t i = 0; i < am->ncomps; i++) {
        comp_t *c = &am->comps[i];
        if (!c->local || !c->wanted || c->st != CS_WAITING)
            continue;
        bool ready = true;
        for (size_t k = 0; k < c->cfg->ndepends && ready; k++)
            ready = dep_ready(am, c->cfg->depends[k]);
        if (ready)
            comp_spawn(c);
    }
}

static void comp_want(comp_t *c)
{
    c->wanted = true;
    c->stop_pending = false;
    if (!c->local)
        return;
    if (c->st == CS_STOPPED || c->st == CS_FAILED || c->st == CS_EXITED) {
        c->nfail_times = 0;
        c->next_backoff_s = c->cfg->restart.backoff_min_s;
        comp_set_state(c, CS_WAITING);
    } else if (c->st == CS_STOPPING) {
        c->restart_after_stop = true;
    }
}

/* ---------------------------------------------------------------- heartbeats */

static void on_heartbeat(const lcm_recv_buf_t *rbuf, const char *channel, const marie_heartbeat_t *hb, void *user)
{
    am_t *am = user;
    comp_t *c = comp_find(am, hb->component);
    if (!c || strcmp(hb->host, c->host) != 0)
        return;
    if (c->local && c->pid > 0 && hb->pid != c->pid && !c->cfg->shell) {
        /* an old process's last words, or a stranger with our name */
        marie_warn_ratelimited(5, "%s: heartbeat from pid %d, but the component runs as pid %d",
                               c->cfg->name, (int)hb->pid, (int)c->pid);
        return;
    }
    c->hb_mono = now_us();
    int prev = c->hb_state;
    c->hb_state = hb->state;
    if (!c->local) {
        if (prev != hb->state)
            try_start_waiting(am);
        return;
    }
    if (c->pid <= 0)
        return;
    /* Degraded is running with a quiet device: up, for dependencies and restarts alike. */
    if (c->st == CS_STARTING && (hb->state == MARIE_STATE_RUNNING || hb->state == MARIE_STATE_PAUSED ||
                                 hb->state == MARIE_STATE_DEGRADED)) {
        comp_set_state(c, CS_RUNNING);
        try_start_waiting(am);
    } else if (c->st == CS_RUNNING && hb->state == MARIE_STATE_FAILED && prev != MARIE_STATE_FAILED &&
               c->cfg->restart.policy != MARIE_RESTART_NEVER) {
        am_event(am, MARIE_EVENT_T_SEV_WARN, "component_failed", "%s reports failed (%s): restarting it",
                 c->cfg->name, hb->reason);
        c->count_failure = true;
        comp_stop(c, true);
    } else if (prev != hb->state) {
        status_changed(am);
    }
}

/* Every status (our own too) feeds the placement decisions; a returning manager adopts the
 * placement it hears. */
static void balance_on_status(am_t *am, const marie_am_status_t *st)
{
    int64_t now = now_us();
    balance_heard(am->bal, st->host, st->balance_term, strcmp(st->balance_leader, st->host) == 0, st->ncpu, now);
    for (int i = 0; i < st->ncomponents; i++) {
        const marie_am_component_status_t *cs = &st->components[i];
        bool running = strcmp(cs->state, "running") == 0 || strcmp(cs->state, "degraded") == 0 ||
                       strcmp(cs->state, "starting") == 0;
        balance_sample(am->bal, st->host, cs->name, cs->cpu, running, now);
        comp_t *c = comp_find(am, cs->name);
        if (am->adopt_until && running && c && c->local && strcmp(st->host, am->host) != 0) {
            am_event(am, MARIE_EVENT_T_SEV_INFO, "balance", "%s runs on %s now: not starting it here",
                     c->cfg->name, st->host);
            apply_move(am, c, st->host);
            save_up_state(am);
        }
    }
}

static void balance_decide(am_t *am)
{
    balance_move_t m;
    if (!am->bal || am->adopt_until || !am->up || !balance_step(am->bal, now_us(), &m))
        return;
    snprintf(am->bal_last, sizeof am->bal_last, "%s", m.reason);
    if (!am->auth) {
        am_event(am, MARIE_EVENT_T_SEV_WARN, "balance", "%s: not done, no key to sign the move", m.reason);
        return;
    }
    am_event(am, m.why == BALANCE_OVERLOAD ? MARIE_EVENT_T_SEV_INFO : MARIE_EVENT_T_SEV_WARN, "balance",
             "%s (term %lld)", m.reason, (long long)balance_term(am->bal));
    /* Decided: the next step must not decide it again before the order comes back. */
    balance_placed(am->bal, m.component, m.to, now_us());
    char *targets[] = {m.component};
    marie_am_order_t o = {.host = "*", .op = MARIE_AM_ORDER_T_OP_MOVE, .ntargets = 1, .targets = targets, .arg = m.to};
    if (marie_am_send_order_as(am->lcm, am->auth, &o, am->bal_sender, NULL) < 0)
        marie_warn("balance: cannot send the move of %s", m.component);
    status_changed(am);
}

static void on_peer_status(const lcm_recv_buf_t *rbuf, const char *channel, const marie_am_status_t *st, void *user)
{
    am_t *am = user;
    if (am->bal)
        balance_on_status(am, st);
    if (strcmp(st->host, am->host) == 0)
        return;
    bool changed = false;
    for (int i = 0; i < st->ncomponents; i++) {
        comp_t *c = comp_find(am, st->components[i].name);
        if (!c || strcmp(c->host, st->host) != 0)
            continue;
        bool running = strcmp(st->components[i].state, "running") == 0 ||
                       strcmp(st->components[i].state, "degraded") == 0;
        changed |= running != c->st_running;
        c->st_running = running;
        c->st_mono = now_us();
    }
    if (changed)
        try_start_waiting(am);
}

/* Hung components: alive, but no heartbeat for heartbeat_timeout. */
static void check_heartbeats(am_t *am)
{
    int64_t now = now_us();
    for (size_t i = 0; i < am->ncomps; i++) {
        comp_t *c = &am->comps[i];
        if (!c->local || c->pid <= 0 || c->cfg->heartbeat_timeout_s <= 0)
            continue;
        if (c->st != CS_STARTING && c->st != CS_RUNNING)
            continue;
        int64_t ref = c->hb_mono > c->started_us ? c->hb_mono : c->started_us;
        if (now - ref > (int64_t)(c->cfg->heartbeat_timeout_s * 1e6)) {
            am_event(am, MARIE_EVENT_T_SEV_WARN, "not_responding",
                     "%s (pid %d): no heartbeat for %.2f s: restarting it", c->cfg->name, (int)c->pid,
                     (double)(now - ref) * 1e-6);
            c->count_failure = true;
            comp_stop(c, true);
        }
    }
}

/* ---------------------------------------------------------------- status */

static void on_status_soon(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user);
static void on_status_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user);

static void status_changed(am_t *am)
{
    if (am->status_pending || !am->loop)
        return;
    am->status_pending = true;
    marie_loop_add_oneshot(am->loop, 20000, on_status_soon, am);
}

static void publish_status(am_t *am, bool sample)
{
    int64_t now = now_us();
    marie_am_status_t st = {0};
    marie_am_component_status_t *cs = calloc(am->ncomps ? am->ncomps : 1, sizeof *cs);
    char **states = calloc(am->ncomps ? am->ncomps : 1, sizeof *states);
    if (!cs || !states)
        goto out;
    int n = 0;
    for (size_t i = 0; i < am->ncomps; i++) {
        comp_t *c = &am->comps[i];
        if (!c->local)
            continue;
        if (sample && c->pid > 0) {
            int64_t cpu_us, rss;
            if (marie_proc_usage(c->pid, &cpu_us, &rss) == 0) {
                c->cpu = marie_cpu_percent(&c->cpu_prev, cpu_us, now);
                c->rss = rss;
            }
        }
        marie_am_component_status_t *s = &cs[n++];
        const char *name = cstate_names[c->st];
        if (c->st == CS_RUNNING && c->hb_state == MARIE_STATE_PAUSED)
            name = "paused";
        else if (c->st == CS_RUNNING && c->hb_state == MARIE_STATE_READY)
            name = "ready";
        else if (c->st == CS_RUNNING && c->hb_state == MARIE_STATE_DEGRADED)
            name = "degraded";
        s->name = c->cfg->name;
        s->group = c->cfg->group ? c->cfg->group : "";
        s->state = (char *)name;
        s->comp_state = (int8_t)(c->pid > 0 ? c->hb_state : -1);
        s->pid = c->pid;
        s->uptime_us = c->pid > 0 ? now - c->started_us : 0;
        s->restarts = c->restarts;
        s->last_exit = c->last_exit;
        s->cpu = c->pid > 0 ? c->cpu : 0;
        s->rss = c->pid > 0 ? c->rss : 0;
        s->heartbeat_age_us = c->pid > 0 && c->hb_mono ? now - c->hb_mono : -1;
        s->config_hash = (char *)c->cfg->hash;
        s->log_drops = c->drops_total;
    }
    if (sample) {
        int64_t cpu_us, rss;
        if (marie_proc_usage(getpid(), &cpu_us, &rss) == 0) {
            am->self_cpu_pct = marie_cpu_percent(&am->self_cpu, cpu_us, now);
            am->self_rss = rss;
        }
    }
    st.am_cpu = am->self_cpu_pct;      /* between samples: the last one */
    st.am_rss = am->self_rss;
    float load[3] = {0};
    marie_host_load(load);
    st.utime = marie_wall_us();
    st.host = am->host;
    st.pid = getpid();
    st.seq = ++am->status_seq;
    st.uptime_us = now - am->start_mono;
    st.system = am->sys && am->sys->name ? am->sys->name : "";
    st.system_hash = am->sys ? am->sys_hash : "";
    st.profile = am->profile ? am->profile : "";
    st.load1 = load[0];
    st.load5 = load[1];
    st.load15 = load[2];
    st.ncpu = (int32_t)sysconf(_SC_NPROCESSORS_ONLN);
    st.orders_refused = am->orders_refused;
    st.nhosts = am->sys ? (int32_t)am->sys->nhosts : 0;
    st.hosts = am->sys ? am->sys->hosts : NULL;
    st.ncomponents = n;
    st.components = cs;
    st.balance_leader = "";
    st.balance_last = am->bal_last;
    if (am->bal) {
        st.balance_leader = (char *)(balance_leads(am->bal) ? am->host : balance_leader(am->bal, now));
        st.balance_term = balance_term(am->bal);
    }
    marie_am_status_t_publish(am->lcm, MARIE_CH_AM_STATUS, &st);
out:
    free(states);
    free(cs);
}

static void on_status_soon(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    am_t *am = user;
    am->status_pending = false;
    publish_status(am, false);
}

static void on_status_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    publish_status(user, true);
    balance_decide(user);
}

static void on_tick(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    am_t *am = user;
    if (am->adopt_until && now_us() >= am->adopt_until) {
        am->adopt_until = 0;
        am_up(am);
    }
    check_heartbeats(am);
    progress_stops(am);
    try_start_waiting(am);
    if (am->quitting) {
        bool alive = false;
        for (size_t i = 0; i < am->ncomps; i++)
            alive |= am->comps[i].pid > 0;
        if (!alive || now_us() > am->quit_deadline)
            marie_loop_quit(am->loop);
    }
}

static void on_watchdog(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    sd_notify(0, "WATCHDOG=1");
}

/* ---------------------------------------------------------------- the system */

static void comps_free(am_t *am)
{
    for (size_t i = 0; i < am->ncomps; i++) {
        comp_t *c = &am->comps[i];
        comp_cancel_timer(c);
        for (int k = 0; k < 2; k++)
            outpipe_close(&c->out[k]);
        marie_logfile_close(c->logf);
    }
    free(am->comps);
    am->comps = NULL;
    am->ncomps = 0;
}

static void write_file(const char *path, const char *text, size_t len, mode_t mode)
{
    char tmp[PATH_MAX];
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, mode);
    if (fd < 0)
        return;
    ssize_t w = write(fd, text, len);
    close(fd);
    if (w == (ssize_t)len)
        rename(tmp, path);
}

static char *read_file(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    char *buf = NULL;
    size_t cap = 0, n = 0;
    for (;;) {
        if (n + 4096 > cap) {
            char *nb = realloc(buf, cap = cap * 2 + 8192);
            if (!nb) { free(buf); fclose(f); return NULL; }
            buf = nb;
        }
        size_t r = fread(buf + n, 1, cap - n - 1, f);
        if (r == 0)
            break;
        n += r;
    }
    fclose(f);
    buf[n] = 0;
    *len = n;
    return buf;
}

static void sha256_hex(const void *data, size_t len, const char *extra, char out[65])
{
    crypto_hash_sha256_state s;
    uint8_t h[32];
    crypto_hash_sha256_init(&s);
    crypto_hash_sha256_update(&s, data, len);
    if (extra)
        crypto_hash_sha256_update(&s, (const uint8_t *)extra, strlen(extra) + 1);
    crypto_hash_sha256_final(&s, h);
    sodium_bin2hex(out, 65, h, sizeof h);
}

/* Remembered across restarts of the manager: which system is up, and the moves. */
static void save_up_state(am_t *am)
{
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/up", am->state_dir);
    if (!am->up || !am->sys) {
        unlink(path);
        return;
    }
    char *text = NULL;
    size_t len = 0;
    FILE *m = open_memstream(&text, &len);
    if (!m)
        return;
    fprintf(m, "system %s\nprofile %s\n", am->sys_path, am->profile ? am->profile : "");
    for (size_t i = 0; i < am->ncomps; i++)
        if (strcmp(am->comps[i].host, marie_am_component_host(am->sys, am->comps[i].cfg, am->host)) != 0)
            fprintf(m, "move %s %s\n", am->comps[i].cfg->name, am->comps[i].host);
    fclose(m);
    write_file(path, text, len, 0644);
    free(text);
}

static bool host_known(am_t *am, const char *h)
{
    for (size_t i = 0; i < am->sys->nhosts; i++)
        if (strcmp(am->sys->hosts[i], h) == 0)
            return true;
    return false;
}

/* The programs of this host's components exist and accept their entries (descriptions
 * cached in STATE_DIR/describe). */
static int check_programs(am_t *am, const marie_system_t *sys, marie_errors_t *errs)
{
    char *cache = NULL;
    if (asprintf(&cache, "%s/describe", am->state_dir) < 0)
        cache = NULL;
    marie_progcheck_t *p = marie_progcheck_create(am->self_dir, cache);
    free(cache);
    int rc = p ? marie_progcheck_system(p, sys, am->host, am->host, errs) : -1;
    marie_progcheck_destroy(p);
    return rc;
}

/* Load a system (not yet started). Errors go to errs. */
static int am_load_system(am_t *am, const char *path, const char *profile, marie_errors_t *errs)
{
    size_t len = 0;
    char *text = read_file(path, &len);
    if (!text) {
        marie_errors_add(errs, path, 0, 0, "%s", strerror(errno));
        return -1;
    }
    marie_system_t *sys = marie_system_load(path, profile && *profile ? profile : NULL, errs);
    marie_am_settings_t set;
    if (sys && (marie_am_check_system(sys, &set, errs) < 0 || check_programs(am, sys, errs) < 0)) {
        marie_system_destroy(sys);
        sys = NULL;
    }
    if (!sys) {
        free(text);
        return -1;
    }
    if (!am->opt_status_hz && set.status_hz != am->status_hz) {
        am->status_hz = set.status_hz;
        if (am->status_timer) {
            marie_loop_remove_timer(am->loop, am->status_timer);
            am->status_timer = marie_loop_add_timer(am->loop, (int64_t)(1e6 / am->status_hz), on_status_timer, am);
        }
    }
    if (!am->opt_log_rate) {
        am->log_rate = set.log_rate;
        am->log_burst = set.log_rate * 2;
    }
    if (!am->opt_log_max)
        am->log_max_bytes = set.log_max_bytes;
    if (!am->opt_log_keep)
        am->log_keep = set.log_keep;
    comps_free(am);
    balance_destroy(am->bal);
    am->bal = NULL;
    marie_system_destroy(am->sys);
    am->sys = sys;
    am->bal_cfg = set.balance;
    if (set.balance.enabled && !(am->bal = balance_create(am->host, sys, &am->bal_cfg)))
        marie_error("automatic placement off: %s", strerror(errno));
    sha256_hex(text, len, profile ? profile : "", am->sys_hash);
    free(text);
    free(am->sys_path);
    am->sys_path = realpath(path, NULL);
    if (!am->sys_path)
        am->sys_path = strdup(path);
    free(am->profile);
    am->profile = profile && *profile ? strdup(profile) : NULL;
    am->comps = calloc(sys->ncomponents ? sys->ncomponents : 1, sizeof *am->comps);
    am->ncomps = sys->ncomponents;
    char logdir[PATH_MAX];
    snprintf(logdir, sizeof logdir, "%s/logs", am->state_dir);
    mkdir(logdir, 0755);
    snprintf(logdir, sizeof logdir, "%s/run", am->state_dir);
    mkdir(logdir, 0755);
    for (size_t i = 0; i < sys->ncomponents; i++) {
        comp_t *c = &am->comps[i];
        c->am = am;
        c->cfg = &sys->components[i];
        snprintf(c->host, sizeof c->host, "%s", marie_am_component_host(sys, c->cfg, am->host));
        c->local = strcmp(c->host, am->host) == 0;
        c->hb_state = -1;
        c->next_backoff_s = c->cfg->restart.backoff_min_s;
        for (int k = 0; k < 2; k++)
            c->out[k].fd = -1;
        marie_ratelimit_init(&c->rl, am->log_rate, am->log_burst);
    }
    status_changed(am);
    return 0;
}

static void comp_open_log(comp_t *c)
{
    if (c->logf || !c->local)
        return;
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/logs/%s.log", c->am->state_dir, c->cfg->name);
    c->logf = marie_logfile_open(path, c->am->log_max_bytes, c->am->log_keep);
    if (!c->logf)
        marie_warn("%s: cannot open log file %s: %s", c->cfg->name, path, strerror(errno));
}

/* The effective configuration of every component this host runs, for comparing runs
 * (sim against robot): logged, and kept in the state directory. */
static void record_hashes(am_t *am)
{
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/config-hashes", am->state_dir);
    FILE *f = fopen(path, "w");
    for (size_t i = 0; i < am->ncomps; i++) {
        const comp_t *c = &am->comps[i];
        if (!c->local)
            continue;
        marie_info("%s: configuration %s", c->cfg->name, c->cfg->hash);
        if (f)
            fprintf(f, "%s %s %s\n", c->cfg->name, c->cfg->hash, am->profile ? am->profile : "-");
    }
    if (f)
        fclose(f);
}

static void am_up(am_t *am)
{
    am->up = true;
    record_hashes(am);
    for (size_t i = 0; i < am->ncomps; i++) {
        comp_t *c = &am->comps[i];
        if (c->local) {
            comp_open_log(c);
            comp_want(c);
        }
    }
    save_up_state(am);
    try_start_waiting(am);
}

static void apply_move(am_t *am, comp_t *c, const char *host)
{
    if (am->bal)
        balance_placed(am->bal, c->cfg->name, host, now_us());
    bool was_local = c->local;
    snprintf(c->host, sizeof c->host, "%s", host);
    c->local = strcmp(host, am->host) == 0;
    c->hb_mono = 0;
    c->hb_state = -1;
    c->st_running = false;
    if (was_local && !c->local) {
        c->wanted = false;
        comp_stop(c, false);
    } else if (!was_local && c->local) {
        c->st = CS_STOPPED;
        comp_open_log(c);
        if (am->up)
            comp_want(c);
    }
}

static void restore_up_state(am_t *am)
{
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/up", am->state_dir);
    FILE *f = fopen(path, "r");
    if (!f)
        return;
    char line[PATH_MAX + 64], sys[PATH_MAX] = "", profile[128] = "";
    char moves[64][2][128];
    int nmoves = 0;
    while (fgets(line, sizeof line, f)) {
        line[strcspn(line, "\n")] = 0;
        if (strncmp(line, "system ", 7) == 0)
            snprintf(sys, sizeof sys, "%.*s", (int)sizeof sys - 1, line + 7);
        else if (strncmp(line, "profile ", 8) == 0)
            snprintf(profile, sizeof profile, "%.*s", (int)sizeof profile - 1, line + 8);
        else if (nmoves < 64 && sscanf(line, "move %127s %127s", moves[nmoves][0], moves[nmoves][1]) == 2)
            nmoves++;
    }
    fclose(f);
    if (!sys[0])
        return;
    marie_errors_t errs = {0};
    if (am_load_system(am, sys, profile, &errs) < 0) {
        marie_error("cannot restore the system that was up (%s):", sys);
        marie_errors_print(&errs, stderr);
        marie_errors_clear(&errs);
        return;
    }
    for (int i = 0; i < nmoves; i++) {
        comp_t *c = comp_find(am, moves[i][0]);
        if (c && host_known(am, moves[i][1]))
            apply_move(am, c, moves[i][1]);
    }
    marie_info("restoring system %s (profile %s)", sys, profile[0] ? profile : "none");
    if (!am->bal) {
        am_up(am);
        return;
    }
    /* Moves made while this manager was away (a failover) come back through the other
     * managers' statuses: listen first, then start what is still placed here. */
    am->adopt_until = now_us() + (int64_t)((am->bal_cfg.host_lost_s + 0.5) * 1e6);
    marie_info("learning the current placement for %.1f s before starting anything", am->bal_cfg.host_lost_s + 0.5);
}

/* ---------------------------------------------------------------- orders */

typedef struct {
    am_t *am;
    const char *component;
    int64_t req;
} tail_ctx_t;

static void tail_line_cb(const char *line, size_t len, void *user)
{
    tail_ctx_t *t = user;
    char text[MARIE_LINE_MAX + 128];
    snprintf(text, sizeof text, "%.*s", (int)len, line);
    marie_log_line_t m = {
        .utime = marie_wall_us(), .host = t->am->host, .component = (char *)t->component,
        .stream = MARIE_LOG_LINE_T_STDOUT, .request_seq = t->req, .text = text,
    };
    marie_log_line_t_publish(t->am->lcm, MARIE_CH_LOG, &m);
}

static void reply(am_t *am, const marie_am_order_t *o, bool ok, int affected, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
static void reply(am_t *am, const marie_am_order_t *o, bool ok, int affected, const char *fmt, ...)
{
    char reason[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(reason, sizeof reason, fmt, ap);
    va_end(ap);
    marie_am_reply_t r = {
        .utime = marie_wall_us(), .host = am->host, .sender = o->sender, .seq = o->seq, .ok = ok,
        .reason = reason, .affected = affected,
        .nhosts = am->sys ? (int32_t)am->sys->nhosts : 0, .hosts = am->sys ? am->sys->hosts : NULL,
    };
    marie_am_reply_t_publish(am->lcm, MARIE_CH_AM_REPLY, &r);
}

static void send_lifecycle(am_t *am, comp_t *c, int cmd, int64_t req)
{
    char sender[160];
    snprintf(sender, sizeof sender, "marie-am@%s", am->host);
    int64_t seq = marie_wall_us();
    if (seq <= am->lc_seq)
        seq = am->lc_seq + 1;
    am->lc_seq = seq;
    marie_lifecycle_command_t m = {
        .utime = marie_wall_us(), .request_id = req, .sender = sender, .target = c->cfg->name,
        .command = (int8_t)cmd, .seq = seq,
    };
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    if (am->auth)
        marie_auth_sign_command(am->auth, &m, mac);
    marie_lifecycle_command_t_publish(am->lcm, MARIE_CH_LIFECYCLE, &m);
}

static void order_up(am_t *am, const marie_am_order_t *o)
{
    char hash[65];
    const char *profile = o->arg;
    sha256_hex(o->system_text, strlen(o->system_text), profile, hash);
    if (am->sys && strcmp(hash, am->sys_hash) == 0) {
        am_up(am);
        reply(am, o, true, 0, "ok");
        return;
    }
    for (size_t i = 0; i < am->ncomps; i++)
        if (am->comps[i].pid > 0) {
            reply(am, o, false, 0, "another system (%s) is running here: marie down first",
                  am->sys && am->sys->name ? am->sys->name : "?");
            return;
        }
    /* Use the sender's file where this host sees the same text (relative paths in it keep
     * working); otherwise keep a copy in the state directory. */
    char path[PATH_MAX];
    size_t len = 0;
    char *local = o->system_path[0] ? read_file(o->system_path, &len) : NULL;
    if (local && len == strlen(o->system_text) && memcmp(local, o->system_text, len) == 0) {
        snprintf(path, sizeof path, "%s", o->system_path);
    } else {
        snprintf(path, sizeof path, "%s/system.yaml", am->state_dir);
        write_file(path, o->system_text, strlen(o->system_text), 0644);
    }
    free(local);
    marie_errors_t errs = {0};
    if (am_load_system(am, path, profile, &errs) < 0) {
        char *msg = NULL;
        size_t ml = 0;
        FILE *m = open_memstream(&msg, &ml);
        if (m) {
            marie_errors_print(&errs, m);
            fclose(m);
        }
        reply(am, o, false, 0, "system file refused:\n%s", msg ? msg : "");
        free(msg);
        marie_errors_clear(&errs);
        return;
    }
    am_up(am);
    int n = 0;
    for (size_t i = 0; i < am->ncomps; i++)
        n += am->comps[i].local;
    reply(am, o, true, n, "ok");
}

/* A refused order is counted always, but answered and announced within a rate limit, so a
 * flood of forgeries or replays cannot make the manager flood the bus; the answer says why
 * and nothing more (no hosts: the sender may not hold the key). */
static void refuse_order(am_t *am, const marie_am_order_t *o, marie_auth_result_t ar)
{
    am->orders_refused++;
    marie_warn_ratelimited(1, "refused %s order from '%s' (seq %lld): %s (%lld refused so far)",
                           marie_am_op_name(o->op), o->sender, (long long)o->seq, marie_auth_result_name(ar),
                           (long long)am->orders_refused);
    if (!marie_ratelimit_take(&am->refusal_rl, now_us())) {
        am->refusals_unannounced++;
        return;
    }
    char reason[200], text[200], source[160];
    int64_t now = marie_wall_us();
    if (ar == MARIE_AUTH_STALE || ar == MARIE_AUTH_FUTURE)
        snprintf(reason, sizeof reason, "refused: %s (utime %+.1f s, seq %+.1f s from this host's clock; "
                 "accepted: %+.1f..%+.1f s)", marie_auth_result_name(ar), (double)(o->utime - now) / 1e6,
                 (double)(o->seq - now) / 1e6, -(double)(am->order_lifetime_us + am->max_skew_us) / 1e6,
                 (double)am->max_skew_us / 1e6);
    else
        snprintf(reason, sizeof reason, "refused: %s", marie_auth_result_name(ar));
    snprintf(text, sizeof text, "%s (%lld refused, %lld not announced)", marie_auth_result_name(ar),
             (long long)am->orders_refused, (long long)am->refusals_unannounced);
    snprintf(source, sizeof source, "marie-am@%s", am->host);
    marie_event_t ev = {
        .utime = now, .source = source, .seq = ++am->event_seq,
        .severity = MARIE_EVENT_T_SEV_WARN, .kind = "order_refused", .text = text,
    };
    marie_event_t_publish(am->lcm, MARIE_CH_EVENT, &ev);
    marie_am_reply_t r = {
        .utime = now, .host = am->host, .sender = o->sender, .seq = o->seq, .ok = false, .reason = reason,
    };
    marie_am_reply_t_publish(am->lcm, MARIE_CH_AM_REPLY, &r);
    status_changed(am);
}

static void on_order(const lcm_recv_buf_t *rbuf, const char *channel, const marie_am_order_t *o, void *user)
{
    am_t *am = user;
    if (strcmp(o->host, "*") != 0 && strcmp(o->host, am->host) != 0)
        return;
    marie_auth_result_t ar = marie_auth_check_order(am->auth, am->replay, o);
    if (ar != MARIE_AUTH_OK) {
        refuse_order(am, o, ar);
        return;
    }
    marie_info("order %s from %s (seq %lld)", marie_am_op_name(o->op), o->sender, (long long)o->seq);
    if (o->op == MARIE_AM_ORDER_T_OP_PING) {
        reply(am, o, true, 0, "ok");
        return;
    }
    if (o->op == MARIE_AM_ORDER_T_OP_UP) {
        order_up(am, o);
        return;
    }
    if (!am->sys) {
        reply(am, o, false, 0, "no system loaded: marie up FILE first");
        return;
    }
    if (o->op == MARIE_AM_ORDER_T_OP_DOWN) {
        am->up = false;
        save_up_state(am);
        int n = 0;
        for (size_t i = 0; i < am->ncomps; i++)
            n += am->comps[i].local && am->comps[i].pid > 0;
        stop_all(am);
        progress_stops(am);
        reply(am, o, true, n, "ok");
        return;
    }
    /* every target must name a component or a group of the system */
    for (int t = 0; t < o->ntargets; t++) {
        bool known = false;
        for (size_t i = 0; i < am->ncomps && !known; i++)
            known = comp_matches(&am->comps[i], o->targets[t]);
        if (!known) {
            reply(am, o, false, 0, "no component or group named '%s'", o->targets[t]);
            return;
        }
    }
    if (o->op == MARIE_AM_ORDER_T_OP_MOVE) {
        if (o->ntargets != 1 || !host_known(am, o->arg)) {
            reply(am, o, false, 0, "move: unknown host '%s'", o->arg);
            return;
        }
        comp_t *c = comp_find(am, o->targets[0]);
        if (!c) {
            reply(am, o, false, 0, "move: '%s' is not a component", o->targets[0]);
            return;
        }
        bool affected = c->local || strcmp(o->arg, am->host) == 0;
        apply_move(am, c, o->arg);
        save_up_state(am);
        try_start_waiting(am);
        status_changed(am);
        reply(am, o, true, affected, "ok");
        return;
    }
    int n = 0;
    for (size_t i = 0; i < am->ncomps; i++) {
        comp_t *c = &am->comps[i];
        bool hit = false;
        for (int t = 0; t < o->ntargets; t++)
            hit |= comp_matches(c, o->targets[t]);
        if (!hit || !c->local)
            continue;
        n++;
        switch (o->op) {
        case MARIE_AM_ORDER_T_OP_START:
            comp_open_log(c);
            comp_want(c);
            break;
        case MARIE_AM_ORDER_T_OP_STOP:
            c->wanted = false;
            comp_stop(c, false);
            break;
        case MARIE_AM_ORDER_T_OP_RESTART:
            comp_open_log(c);
            if (c->pid > 0) {
                c->wanted = true;
                comp_stop(c, true);
            } else {
                comp_want(c);
            }
            break;
        case MARIE_AM_ORDER_T_OP_PAUSE:
            send_lifecycle(am, c, MARIE_CMD_PAUSE, o->seq);
            break;
        case MARIE_AM_ORDER_T_OP_RESUME:
            send_lifecycle(am, c, MARIE_CMD_RESUME, o->seq);
            break;
        case MARIE_AM_ORDER_T_OP_TAIL: {
            char path[PATH_MAX];
            snprintf(path, sizeof path, "%s/logs/%s.log", am->state_dir, c->cfg->name);
            tail_ctx_t tc = {am, c->cfg->name, o->seq};
            int lines = atoi(o->arg);
            marie_logfile_tail(path, lines > 0 ? lines : 20, tail_line_cb, &tc);
            break;
        }
        default:
            reply(am, o, false, 0, "unknown order %d", o->op);
            return;
        }
    }
    try_start_waiting(am);
    reply(am, o, true, n, "ok");
}

/* ---------------------------------------------------------------- main */

/* Raw subscriptions: a malformed message is counted and logged at most once a second,
 * never printed per message as the generated handlers would. */
static void bad_message(am_t *am, const char *channel, const lcm_recv_buf_t *rbuf)
{
    am->bad_input++;
    marie_warn_ratelimited(1, "undecodable message on %s (%u bytes); %lld bad so far", channel,
                           rbuf->data_size, (long long)am->bad_input);
}

static void on_raw_order(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_am_order_t o;
    if (marie_decode_checked(&marie_type_am_order_t, rbuf->data, rbuf->data_size, &o) < 0) {
        bad_message(user, channel, rbuf);
        return;
    }
    on_order(rbuf, channel, &o, user);
    marie_am_order_t_decode_cleanup(&o);
}

static void on_raw_heartbeat(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_heartbeat_t hb;
    if (marie_decode_checked(&marie_type_heartbeat_t, rbuf->data, rbuf->data_size, &hb) < 0) {
        bad_message(user, channel, rbuf);
        return;
    }
    on_heartbeat(rbuf, channel, &hb, user);
    marie_heartbeat_t_decode_cleanup(&hb);
}

static void on_raw_status(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_am_status_t st;
    if (marie_decode_checked(&marie_type_am_status_t, rbuf->data, rbuf->data_size, &st) < 0) {
        bad_message(user, channel, rbuf);
        return;
    }
    on_peer_status(rbuf, channel, &st, user);
    marie_am_status_t_decode_cleanup(&st);
}

static void on_lcm(marie_loop_t *loop, int fd, short revents, void *user)
{
    am_t *am = user;
    lcm_handle_timeout(am->lcm, 0);
}

static void usage(FILE *out)
{
    fprintf(out,
            "usage: marie-am [OPTIONS]\n"
            "  --host NAME        this host's name in the system file (default: hostname)\n"
            "  --state-dir DIR    logs, received system file, replay table (default: $MARIE_STATE_DIR,\n"
            "                     $STATE_DIRECTORY, /var/lib/marie as root, else $XDG_STATE_HOME/marie or\n"
            "                     ~/.local/state/marie)\n"
            "  --key FILE         order key (default: $MARIE_KEY, else /etc/marie/key)\n"
            "  --system FILE      bring this system up at start (also: the last system that was up)\n"
            "  --profile P        profile for --system\n"
            "  --url URL          LCM URL (default: $LCM_DEFAULT_URL or marie's)\n"
            "  --status-hz HZ     status rate (default 2)\n"
            "  --log-rate N       captured lines per second per component (default 200, burst 2x)\n"
            "  --log-max-bytes N  rotate a component's log file past this size (default 1048576)\n"
            "  --log-keep N       rotated files kept (default 3)\n"
            "  --order-lifetime S how long an order stays valid (default 10)\n"
            "  --max-skew S       how far the hosts' clocks may differ (default 5)\n");
}

/* --order-lifetime and --max-skew: seconds, 0 to a day. */
static int parse_window_s(const char *arg, int64_t *us)
{
    char *end;
    double s = strtod(arg, &end);
    if (end == arg || *end || !(s >= 0 && s <= 86400)) {
        fprintf(stderr, "marie-am: '%s' is not a number of seconds between 0 and 86400\n", arg);
        return -1;
    }
    *us = (int64_t)(s * 1e6);
    return 0;
}


int main(int argc, char **argv)
{
    static const struct option opts[] = {
        {"host", required_argument, 0, 'H'}, {"state-dir", required_argument, 0, 'd'},
        {"key", required_argument, 0, 'k'}, {"system", required_argument, 0, 's'},
        {"profile", required_argument, 0, 'p'}, {"url", required_argument, 0, 'u'},
        {"status-hz", required_argument, 0, 'z'}, {"log-rate", required_argument, 0, 'r'},
        {"log-max-bytes", required_argument, 0, 'm'}, {"log-keep", required_argument, 0, 'K'},
        {"order-lifetime", required_argument, 0, 'L'}, {"max-skew", required_argument, 0, 'S'},
        {"help", no_argument, 0, 'h'}, {0, 0, 0, 0},
    };
    am_t am_storage = {0}, *am = &am_storage;
    const char *system = NULL, *profile = NULL, *key = NULL;
    am->status_hz = 2;
    am->log_rate = 200;
    am->log_max_bytes = 1 << 20;
    am->log_keep = 3;
    am->order_lifetime_us = MARIE_AUTH_LIFETIME_US;
    am->max_skew_us = MARIE_AUTH_MAX_SKEW_US;
    am->sigfd = -1;
    int opt;
    while ((opt = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
        switch (opt) {
        case 'H': snprintf(am->host, sizeof am->host, "%s", optarg); break;
        case 'd': am->state_dir = strdup(optarg); break;
        case 'k': key = optarg; break;
        case 's': system = optarg; break;
        case 'p': profile = optarg; break;
        case 'u': am->url = strdup(optarg); break;
        case 'z': am->status_hz = atof(optarg); am->opt_status_hz = true; break;
        case 'r': am->log_rate = atof(optarg); am->opt_log_rate = true; break;
        case 'm': am->log_max_bytes = atoll(optarg); am->opt_log_max = true; break;
        case 'K': am->log_keep = atoi(optarg); am->opt_log_keep = true; break;
        case 'L': if (parse_window_s(optarg, &am->order_lifetime_us) < 0) return 2; break;
        case 'S': if (parse_window_s(optarg, &am->max_skew_us) < 0) return 2; break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    if (optind != argc || am->status_hz <= 0) {
        usage(stderr);
        return 2;
    }
    am->log_burst = am->log_rate * 2;
    if (!am->host[0])
        gethostname(am->host, sizeof am->host - 1);
    snprintf(am->bal_sender, sizeof am->bal_sender, "balance@%.128s", am->host);
    if (!am->state_dir)
        am->state_dir = marie_state_dir();
    if (!am->url)
        am->url = strdup(marie_default_url());
    char log_name[160];
    snprintf(log_name, sizeof log_name, "marie-am@%.128s", am->host);
    marie_log_set_name(log_name);
    {
        char self[PATH_MAX];
        ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
        if (n > 0) {
            self[n] = 0;
            char *slash = strrchr(self, '/');
            if (slash)
                *slash = 0;
            snprintf(am->self_dir, sizeof am->self_dir, "%s", self);
        }
    }
    if (sodium_init() < 0) {
        marie_error("libsodium failed to initialise");
        return 1;
    }
    if (!am->state_dir) {
        marie_error("no state directory (%s): give --state-dir or set MARIE_STATE_DIR", strerror(errno));
        return 1;
    }
    if (mkdir(am->state_dir, 0755) < 0 && errno != EEXIST) {
        marie_error("state directory %s: %s", am->state_dir, strerror(errno));
        return 1;
    }
    int rc = 1;
    /* Validate a given system before anything starts. */
    marie_errors_t errs = {0};
    am->start_mono = now_us();
    am->loop = marie_loop_create();
    if (!am->loop) {
        marie_error("loop: %s", strerror(errno));
        return 1;
    }
    if (system) {
        if (am_load_system(am, system, profile, &errs) < 0) {
            marie_errors_print(&errs, stderr);
            marie_errors_clear(&errs);
            rc = 2;
            goto out_loop;
        }
    }
    if (!key && am->sys && am->sys->key_file)
        key = am->sys->key_file;
    const char *key_path = marie_am_key_path(key);
    char err[512];
    am->auth = marie_auth_load(key_path, err, sizeof err);
    if (am->auth)
        am->key_path = strdup(key_path);  /* components verify their lifecycle orders with it */
    if (!am->auth) {
        /* A key that was asked for, or one that exists but is unusable, is a configuration
         * error; only the default file not being there yet (before `marie keygen`) is not. */
        if (key || errno != ENOENT) {
            marie_error("%s: refusing to run with a key that cannot be used%s", err,
                        key ? "" : " (from $MARIE_KEY or the default)");
            rc = 2;
            goto out_loop;
        }
        marie_warn("%s: every order will be refused", err);
    }
    char seqpath[PATH_MAX];
    snprintf(seqpath, sizeof seqpath, "%s/order-seq", am->state_dir);
    am->replay = marie_replay_create_window(seqpath, am->order_lifetime_us, am->max_skew_us);
    if (!am->replay) {
        marie_error("replay table %s: %s", seqpath, strerror(errno));
        goto out_loop;
    }
    marie_ratelimit_init(&am->refusal_rl, 5, 10);

    am->lcm = lcm_create(am->url);
    if (!am->lcm) {
        marie_error("lcm_create(%s) failed", am->url);
        goto out_loop;
    }
    lcm_subscribe(am->lcm, MARIE_CH_HEARTBEAT, on_raw_heartbeat, am);
    lcm_subscribe(am->lcm, MARIE_CH_AM_ORDER, on_raw_order, am);
    lcm_subscribe(am->lcm, MARIE_CH_AM_STATUS, on_raw_status, am);
    marie_loop_add_fd(am->loop, lcm_get_fileno(am->lcm), POLLIN, on_lcm, am);

    sigset_t mask;
    sigemptyset(&mask);
    sigaddset(&mask, SIGCHLD);
    sigaddset(&mask, SIGTERM);
    sigaddset(&mask, SIGINT);
    sigaddset(&mask, SIGHUP);
    sigprocmask(SIG_BLOCK, &mask, NULL);
    signal(SIGPIPE, SIG_IGN);
    am->sigfd = signalfd(-1, &mask, SFD_CLOEXEC | SFD_NONBLOCK);
    if (am->sigfd < 0) {
        marie_error("signalfd: %s", strerror(errno));
        goto out_lcm;
    }
    marie_loop_add_fd(am->loop, am->sigfd, POLLIN, on_signalfd, am);
    am->status_timer = marie_loop_add_timer(am->loop, (int64_t)(1e6 / am->status_hz), on_status_timer, am);
    marie_loop_add_timer(am->loop, 50000, on_tick, am);
    uint64_t wd = 0;
    if (sd_watchdog_enabled(0, &wd) > 0 && wd > 0) {
        am->watchdog_us = wd;
        marie_loop_add_timer(am->loop, (int64_t)(wd / 2), on_watchdog, am);
    }

    kill_leftovers(am);
    if (am->sys) {
        am_up(am);
    } else {
        restore_up_state(am);
    }
    marie_info("managing host %s (state %s, bus %s)%s", am->host, am->state_dir, am->url,
               am->auth ? "" : " WITHOUT a key: orders refused");
    publish_status(am, true);
    sd_notifyf(0, "READY=1\nSTATUS=managing host %s", am->host);
    if (am->watchdog_us)
        sd_notify(0, "WATCHDOG=1");

    rc = marie_loop_run(am->loop) < 0 ? 1 : 0;
    /* whatever is still alive after the deadline goes now */
    for (size_t i = 0; i < am->ncomps; i++)
        if (am->comps[i].pid > 0)
            kill(-am->comps[i].pid, SIGKILL);
    publish_status(am, false);

    close(am->sigfd);
out_lcm:
    comps_free(am);
    lcm_destroy(am->lcm);
out_loop:
    comps_free(am);
    marie_loop_destroy(am->loop);
    balance_destroy(am->bal);
    marie_system_destroy(am->sys);
    marie_auth_destroy(am->auth);
    free(am->key_path);
    marie_replay_destroy(am->replay);
    free(am->sys_path);
    free(am->profile);
    free(am->state_dir);
    free(am->url);
    return rc;
}
