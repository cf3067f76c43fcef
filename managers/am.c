/* marie-am: the application manager of one host: starts, watches and restarts the
 * components the system file assigns to it, and obeys authenticated orders. */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <sched.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/signalfd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <lcm/lcm.h>
#include <sodium.h>

#include "core/component.h"
#include "core/file.h"
#include "core/log.h"
#include "core/loop.h"
#include "core/time.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_heartbeat_t.h"
#include "core/typeinfo.h"
#include "managers/am.h"
#include "managers/sdnotify.h"
#include "core/version.h"

static void am_arm_heartbeat_check(am_t *am);

/* ---------------------------------------------------------------- heartbeats */

static void on_heartbeat(am_t *am, const marie_heartbeat_t *hb)
{
    comp_t *c = am_comp_find(am, hb->component);
    if (!c || strcmp(hb->host, c->host) != 0)
        return;
    if (c->sv.local && c->sv.pid > 0 && hb->pid != c->sv.pid && !c->cfg->shell) {
        /* an old process's last words, or a stranger with our name */
        marie_warn_ratelimited(5, "%s: heartbeat from pid %d, but the component runs as pid %d",
                               c->cfg->name, (int)hb->pid, (int)c->sv.pid);
        return;
    }
    if (c->sv.local && hb->pid == c->sv.pid)
        am_comp_unboost(c);     /* it runs: back to the normal policy */
    marie_sv_state_t before = c->sv.st;
    marie_sv_action_t act;
    marie_sv_heartbeat(&c->sv, hb->state, hb->reason, am_now_us(), &act);
    am_comp_apply(c, before, &act);
    am_arm_heartbeat_check(am);
}

static void on_heartbeat_deadline(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    am_t *am = user;
    am->daemon.hb_check = NULL;        /* a one-shot: freed by the loop */
    am_check_heartbeats(am);
    am_arm_heartbeat_check(am);
}

/* A silent component is caught at its deadline, not at the next 50 ms tick: with a
 * heartbeat_timeout of 0.15 s the tick alone added up to a third to the time to its restart. */
static void am_arm_heartbeat_check(am_t *am)
{
    int64_t deadline = INT64_MAX;
    for (size_t i = 0; i < am_ncomps(am); i++) {
        int64_t d = marie_sv_heartbeat_deadline(&am_comp_at(am, i)->sv);
        deadline = d < deadline ? d : deadline;
    }
    marie_loop_remove_timer(am->env.loop, am->daemon.hb_check);
    am->daemon.hb_check = NULL;
    if (deadline == INT64_MAX)
        return;
    int64_t delay = deadline - am_now_us() + 1000;
    am->daemon.hb_check = marie_loop_add_wall_oneshot(am->env.loop, delay > 0 ? delay : 0, on_heartbeat_deadline, am);
}

static void on_peer_status(am_t *am, const marie_am_status_t *st)
{
    am_balance_on_status(am, st);
    if (strcmp(st->host, am->env.host) == 0)
        return;
    bool changed = false;
    for (int i = 0; i < st->ncomponents; i++) {
        comp_t *c = am_comp_find(am, st->components[i].name);
        if (!c || strcmp(c->host, st->host) != 0)
            continue;
        bool running = strcmp(st->components[i].state, "running") == 0 ||
                       strcmp(st->components[i].state, "degraded") == 0;
        changed |= marie_sv_peer_status(&c->sv, running, am_now_us());
    }
    if (changed)
        am_try_start_waiting(am);
}

static void on_tick(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    am_t *am = user;
    am_balance_tick(am);
    am_check_heartbeats(am);
    am_limits_tick(am);
    am_arm_heartbeat_check(am);
    am_progress_stops(am);
    am_try_start_waiting(am);
    if (am->daemon.quitting) {
        bool alive = false;
        for (size_t i = 0; i < am_ncomps(am); i++)
            alive |= am_comp_at(am, i)->sv.pid > 0;
        if (!alive || am_now_us() > am->daemon.quit_deadline)
            marie_loop_quit(am->env.loop);
    }
}

static void on_watchdog(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    marie_sd_notify("WATCHDOG=1");
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
        } else if (!am->daemon.quitting) {
            marie_info("signal %d: stopping components, then exiting", (int)si[i].ssi_signo);
            marie_sd_notify("STOPPING=1");
            am->daemon.quitting = true;
            double longest = 0;
            for (size_t k = 0; k < am_ncomps(am); k++)
                if (am_comp_at(am, k)->cfg->stop_timeout_s > longest)
                    longest = am_comp_at(am, k)->cfg->stop_timeout_s;
            am->daemon.quit_deadline = am_now_us() + (int64_t)((longest + 3.0) * 1e6);
            am_stop_all(am);
            am_progress_stops(am);
        }
    }
    if (chld)
        am_reap_children(am);
}

/* Raw subscriptions: a malformed message is counted and logged at most once a second,
 * never printed per message as the generated handlers would. */
static void bad_message(am_t *am, const char *channel, const lcm_recv_buf_t *rbuf)
{
    am->daemon.bad_input++;
    marie_warn_ratelimited(1, "undecodable message on %s (%u bytes); %lld bad so far", channel,
                           rbuf->data_size, (long long)am->daemon.bad_input);
}

static void on_raw_order(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_am_order_t o;
    if (marie_decode_checked(&marie_type_am_order_t, rbuf->data, rbuf->data_size, &o) < 0) {
        bad_message(user, channel, rbuf);
        return;
    }
    am_on_order(user, &o);
    marie_am_order_t_decode_cleanup(&o);
}

static void on_raw_heartbeat(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_heartbeat_t hb;
    if (marie_decode_checked(&marie_type_heartbeat_t, rbuf->data, rbuf->data_size, &hb) < 0) {
        bad_message(user, channel, rbuf);
        return;
    }
    on_heartbeat(user, &hb);
    marie_heartbeat_t_decode_cleanup(&hb);
}

static void on_raw_status(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_am_status_t st;
    if (marie_decode_checked(&marie_type_am_status_t, rbuf->data, rbuf->data_size, &st) < 0) {
        bad_message(user, channel, rbuf);
        return;
    }
    on_peer_status(user, &st);
    marie_am_status_t_decode_cleanup(&st);
}

static void on_raw_status_request(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_am_status_request_t rq;
    if (marie_decode_checked(&marie_type_am_status_request_t, rbuf->data, rbuf->data_size, &rq) < 0) {
        bad_message(user, channel, rbuf);
        return;
    }
    am_on_status_request(user, &rq);
    marie_am_status_request_t_decode_cleanup(&rq);
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
            "  --max-skew S       how far the hosts' clocks may differ (default 5)\n"
            "  --rt-priority N    run at SCHED_FIFO priority N (1-99; its children at the normal policy\n"
            "                     unless their sched: says otherwise; default: the normal policy)\n");
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


/* --rt-priority: the manager's own wake-ups (a heartbeat's deadline, the stop timer, a child's
 * exit) come at once beside busy CPUs, where at the normal policy a stop timer of 20 ms fired
 * 43-133 ms late beside two busy loops. SCHED_RESET_ON_FORK: what it starts (the components,
 * the program check) runs at the normal policy unless a component's sched: asks otherwise
 * (spawn.c sets that policy around the clone and puts this one back). Refused (no
 * CAP_SYS_NICE, a user namespace): said once, and the manager runs on at the normal policy. */
static void am_rt_priority(int prio)
{
    struct sched_param p = {.sched_priority = prio};
    if (prio > 0 && sched_setscheduler(0, SCHED_FIFO | SCHED_RESET_ON_FORK, &p) < 0)
        marie_warn("--rt-priority %d refused (%s): running at the normal policy", prio, strerror(errno));
}

/* The command line into am and the three names main needs; -1 to go on, else the exit status. */
static int parse_args(am_t *am, int argc, char **argv, const char **system, const char **profile, const char **key)
{
    static const struct option opts[] = {
        {"host", required_argument, 0, 'H'}, {"state-dir", required_argument, 0, 'd'},
        {"key", required_argument, 0, 'k'}, {"system", required_argument, 0, 's'},
        {"profile", required_argument, 0, 'p'}, {"url", required_argument, 0, 'u'},
        {"status-hz", required_argument, 0, 'z'}, {"log-rate", required_argument, 0, 'r'},
        {"log-max-bytes", required_argument, 0, 'm'}, {"log-keep", required_argument, 0, 'K'},
        {"order-lifetime", required_argument, 0, 'L'}, {"max-skew", required_argument, 0, 'S'},
        {"rt-priority", required_argument, 0, 'R'}, {"help", no_argument, 0, 'h'}, {0, 0, 0, 0},
    };
    am->env.opt.status_hz = 2;
    am->env.opt.log_rate = 200;
    am->env.opt.log_max_bytes = 1 << 20;
    am->env.opt.log_keep = 3;
    am->env.opt.order_lifetime_us = MARIE_AUTH_LIFETIME_US;
    am->env.opt.max_skew_us = MARIE_AUTH_MAX_SKEW_US;
    am->daemon.sigfd = -1;
    int opt;
    while ((opt = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
        switch (opt) {
        case 'H': snprintf(am->env.host, sizeof am->env.host, "%s", optarg); break;
        case 'd': am->env.state_dir = strdup(optarg); break;
        case 'k': *key = optarg; break;
        case 's': *system = optarg; break;
        case 'p': *profile = optarg; break;
        case 'u': am->env.url = strdup(optarg); break;
        case 'z': am->env.opt.status_hz = atof(optarg); am->env.opt.given_status_hz = true; break;
        case 'r': am->env.opt.log_rate = atof(optarg); am->env.opt.given_log_rate = true; break;
        case 'm': am->env.opt.log_max_bytes = atoll(optarg); am->env.opt.given_log_max = true; break;
        case 'K': am->env.opt.log_keep = atoi(optarg); am->env.opt.given_log_keep = true; break;
        case 'L': if (parse_window_s(optarg, &am->env.opt.order_lifetime_us) < 0) return 2; break;
        case 'S': if (parse_window_s(optarg, &am->env.opt.max_skew_us) < 0) return 2; break;
        case 'R': am->env.opt.rt_priority = atoi(optarg); break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    if (optind != argc || am->env.opt.status_hz <= 0 || am->env.opt.rt_priority < 0 || am->env.opt.rt_priority > 99) {
        usage(stderr);
        return 2;
    }
    if (!am->env.host[0])
        gethostname(am->env.host, sizeof am->env.host - 1);
    if (!am->env.state_dir)
        am->env.state_dir = marie_state_dir();
    if (!am->env.url)
        am->env.url = strdup(marie_default_url());
    return -1;
}

int main(int argc, char **argv)
{
    marie_version_exit("marie-am", argc, argv);
    am_t am_storage = {0}, *am = &am_storage;
    const char *system = NULL, *profile = NULL, *key = NULL;
    int done = parse_args(am, argc, argv, &system, &profile, &key);
    if (done >= 0)
        return done;
    char log_name[160];
    snprintf(log_name, sizeof log_name, "marie-am@%.128s", am->env.host);
    marie_log_set_name(log_name);
    am_rt_priority(am->env.opt.rt_priority);
    {
        char self[PATH_MAX];
        ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
        if (n > 0) {
            self[n] = 0;
            char *slash = strrchr(self, '/');
            if (slash)
                *slash = 0;
            snprintf(am->env.self_dir, sizeof am->env.self_dir, "%s", self);
        }
    }
    if (sodium_init() < 0) {
        marie_error("libsodium failed to initialise");
        return 1;
    }
    if (!am->env.state_dir) {
        marie_error("no state directory (%s): give --state-dir or set MARIE_STATE_DIR", strerror(errno));
        return 1;
    }
    if (mkdir(am->env.state_dir, 0755) < 0 && errno != EEXIST) {
        marie_error("state directory %s: %s", am->env.state_dir, strerror(errno));
        return 1;
    }
    int rc = 1;
    /* Validate a given system before anything starts. */
    marie_errors_t errs = {0};
    am_status_init(am);
    am->env.loop = marie_loop_create();
    am->env.spawner = marie_spawner_create();
    if (!am->env.loop || !am->env.spawner) {
        marie_error("%s: %s", am->env.loop ? "spawner" : "loop", strerror(errno));
        marie_loop_destroy(am->env.loop);
        marie_spawner_destroy(am->env.spawner);
        return 1;
    }
    if (system) {
        if (am_load_system(am, system, NULL, profile, &errs) < 0) {
            marie_errors_print(&errs, stderr);
            marie_errors_clear(&errs);
            rc = 2;
            goto out_loop;
        }
    }
    if (!key && am_system(am) && am_system(am)->key_file)
        key = am_system(am)->key_file;
    const char *key_path = marie_am_key_path(key);
    char err[512];
    am->env.auth = marie_auth_load(key_path, err, sizeof err);
    if (am->env.auth)
        am->env.key_path = strdup(key_path);  /* components verify their lifecycle orders with it */
    if (!am->env.auth) {
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
    if (am_orders_init(am) < 0)
        goto out_loop;

    am->env.lcm = marie_bus_create(am->env.url);
    if (!am->env.lcm) {
        marie_error("lcm_create(%s) failed", am->env.url);
        goto out_loop;
    }
    marie_bus_subscribe(am->env.lcm, MARIE_CH_HEARTBEAT, on_raw_heartbeat, am);
    marie_bus_subscribe(am->env.lcm, MARIE_CH_AM_ORDER, on_raw_order, am);
    marie_bus_subscribe(am->env.lcm, MARIE_CH_AM_STATUS, on_raw_status, am);
    marie_bus_subscribe(am->env.lcm, MARIE_CH_AM_STATUS_REQUEST, on_raw_status_request, am);
    marie_loop_add_bus(am->env.loop, am->env.lcm, 1);

    sigset_t mask;
    sigemptyset(&mask);
    sigaddset(&mask, SIGCHLD);
    sigaddset(&mask, SIGTERM);
    sigaddset(&mask, SIGINT);
    sigaddset(&mask, SIGHUP);
    sigprocmask(SIG_BLOCK, &mask, NULL);
    signal(SIGPIPE, SIG_IGN);
    am->daemon.sigfd = signalfd(-1, &mask, SFD_CLOEXEC | SFD_NONBLOCK);
    if (am->daemon.sigfd < 0) {
        marie_error("signalfd: %s", strerror(errno));
        goto out_lcm;
    }
    marie_loop_add_fd(am->env.loop, am->daemon.sigfd, POLLIN, on_signalfd, am);
    am_status_start(am);
    marie_loop_add_timer(am->env.loop, 50000, on_tick, am);
    uint64_t wd = marie_sd_watchdog_usec();
    if (wd > 0) {
        am->daemon.watchdog_us = wd;
        marie_loop_add_timer(am->env.loop, (int64_t)(wd / 2), on_watchdog, am);
    }

    am_kill_leftovers(am);
    if (am_system(am)) {
        am_up(am);
    } else {
        am_restore_up_state(am);
    }
    marie_info("managing host %s (state %s, bus %s)%s", am->env.host, am->env.state_dir, am->env.url,
               am->env.auth ? "" : " WITHOUT a key: orders refused");
    am_publish_status(am, true);
    am_flush_children(am);      /* READY=1: what it started at start-up is on disk */
    char ready[sizeof am->env.host + 40];
    snprintf(ready, sizeof ready, "READY=1\nSTATUS=managing host %.127s", am->env.host);
    marie_sd_notify(ready);
    if (am->daemon.watchdog_us)
        marie_sd_notify("WATCHDOG=1");

    rc = marie_loop_run(am->env.loop) < 0 ? 1 : 0;
    am_check_cancel(am, "the manager stopped\n");
    am_apply_cancel(am);
    /* whatever is still alive after the deadline goes now */
    for (size_t i = 0; i < am_ncomps(am); i++)
        if (am_comp_at(am, i)->sv.pid > 0)
            kill(-am_comp_at(am, i)->sv.pid, SIGKILL);
    am_publish_status(am, false);
    am_flush_children(am);

    close(am->daemon.sigfd);
out_lcm:
    am_comps_free(am);
    marie_bus_destroy(am->env.lcm);
out_loop:
    am_comps_free(am);
    am_limits_free(am);
    marie_loop_destroy(am->env.loop);
    marie_spawner_destroy(am->env.spawner);
    am_balance_free(am);
    am_system_free(am);
    marie_auth_destroy(am->env.auth);
    free(am->env.key_path);
    am_orders_free(am);
    free(am->env.state_dir);
    free(am->env.url);
    return rc;
}

bool am_quitting(const am_t *am) { return am->daemon.quitting; }
