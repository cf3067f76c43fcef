/* marie-am's own parts, shared between its files (not a library interface): the manager, its
 * components, and the functions each file offers the others. */
#ifndef MARIE_MANAGERS_AM_H
#define MARIE_MANAGERS_AM_H

#include <limits.h>
#include <stdbool.h>
#include <stdint.h>
#include <sys/types.h>

#include <lcm/lcm.h>

#include "core/auth.h"
#include "core/config.h"
#include "core/loop.h"
#include "core/procstat.h"
#include "core/time.h"
#include "managers/am_settings.h"
#include "proto/am_proto.h"
#include "managers/balance.h"
#include "managers/limits.h"
#include "managers/logcap.h"
#include "managers/spawn.h"
#include "managers/supervise.h"

typedef struct am am_t;
typedef struct comp comp_t;

typedef struct {
    am_t *am;
    comp_t *c;
    int fd;
    int stream;
    marie_linebuf_t *lb;        /* from the first spawn: most of a system's components run on
                                 * other hosts, and 1 KiB a pipe for each was most of the heap */
    marie_timer_t *pause;       /* not read until it fires: the rate limit dropped lines */
} outpipe_t;

/* am_output.c: a component's output: its pipes, their rate limit, its log file. */
typedef struct {
    outpipe_t pipe[2];          /* stdout, stderr */
    marie_ratelimit_t rl;
    int64_t drops_pending, drops_total, seq;
    marie_logfile_t *file;
} am_output_t;

/* am_status.c: what a component uses, sampled for the status. */
typedef struct {
    marie_cpu_sample_t cpu_prev;
    float cpu;
    int64_t rss;
} am_usage_t;

/* A component: its configuration and host (am_system.c), the supervision state (pure,
 * supervise.c, its actions carried out by am_run.c) and what each file around it holds. */
struct comp {
    am_t *am;
    const marie_component_cfg_t *cfg;
    marie_sv_t sv;
    char host[128];             /* effective host (a move changes it) */
    marie_timer_t *timer;       /* am_run.c: backoff or kill timer, as the state machine asks */
    int64_t start_ticks;        /* am_system.c: /proc start time, with pid names the process */
    bool boosted;               /* am_run.c: started at the manager's real-time priority, until
                                 * its first heartbeat or AM_BOOST_MAX_US (am_comp_unboost) */
    marie_timer_t *boost_timer; /* am_run.c: the end of the boost, whatever the component does */
    am_usage_t use;             /* am_status.c */
    am_output_t out;            /* am_output.c */
    struct {
        marie_limit_watch_t w;
        int64_t next_us;            /* the next look at what it uses */
        int breaches;
        bool in_cgroup;             /* this instance runs in its cgroup, under the kernel's limits */
        char *cgroup;               /* its cgroup directory; NULL: none */
    } lim;                      /* am_limits.c: resource limits */
};

/* marie-am's state, split by concern: each part below is written by one file only, and the
 * others reach it through that file's functions (the pure state machines, supervise.c and
 * balance.c, are the model). env is decided at start-up and read-only afterwards. */

/* am.c: settings given on the command line (given_*: they override the system file's). */
typedef struct {
    double status_hz, log_rate;
    int64_t log_max_bytes;
    int log_keep;
    bool given_status_hz, given_log_rate, given_log_max, given_log_keep;
    int64_t order_lifetime_us, max_skew_us;    /* the replay table's window */
    int rt_priority;            /* --rt-priority: SCHED_FIFO priority, 0 for the normal policy */
} am_opts_t;

/* am.c: the command line and start-up; read by every file, written by none once the loop runs. */
typedef struct {
    char host[128];
    char *state_dir;
    char *key_path;             /* components verify their lifecycle orders with it; NULL: no key */
    char *url;
    char self_dir[PATH_MAX];
    marie_loop_t *loop;
    lcm_t *lcm;
    marie_spawner_t *spawner;   /* starts the components (spawn.c) */
    marie_auth_t *auth;         /* NULL: every order refused */
    am_opts_t opt;
} am_env_t;

/* am.c: the daemon around the loop: signals, the watchdog, bad input, quitting. */
typedef struct {
    int sigfd;
    uint64_t watchdog_us;
    int64_t bad_input;          /* undecodable messages */
    bool quitting;
    int64_t quit_deadline;
    marie_timer_t *hb_check;    /* at the earliest heartbeat deadline (am_arm_heartbeat_check) */
} am_daemon_t;

/* am_system.c: the loaded system, its components, and what survives a restart of the manager. */
typedef struct {
    marie_system_t *sys;
    char hash[65];
    uint64_t text_hash;         /* marie_text_hash of the file, for MARIE_SYSTEM_ENTRY */
    char *path;                 /* path given to components as MARIE_SYSTEM */
    char *profile;
    bool up;
    comp_t *comps;
    size_t ncomps;
    double log_rate;            /* in effect: the command line's, else the system file's */
    int64_t log_max_bytes;
    int log_keep;
    marie_timer_t *children_timer;  /* the children file is written when it fires (am_save_children) */
    marie_timer_t *up_timer;    /* an up's hashes and log files, once its first spawns are done */
} am_system_t;

/* am_status.c: events and the status message. */
typedef struct {
    double hz;
    marie_timer_t *timer;
    bool pending;               /* a status soon (am_status_changed) */
    bool settled;               /* the last status published showed no component between states */
    int64_t start_mono, seq, event_seq;
    marie_cpu_sample_t self_cpu;
    float self_cpu_pct;
    int64_t self_rss;
    marie_ratelimit_t answer_rl;                /* statuses sent on request (am_on_status_request) */
    int64_t requests_unanswered;
} am_status_t;

/* am_orders.c: orders checked and answered. */
typedef struct {
    marie_replay_t *replay;
    int64_t lifetime_us, max_skew_us;
    marie_ratelimit_t refusal_rl;               /* answers and events for refused orders */
    int64_t refused, refusals_unannounced;
    int64_t lc_seq;             /* the last lifecycle command's seq */
} am_orders_t;

/* am_balance.c: automatic placement (the system's balance: section; b NULL without one). */
typedef struct {
    balance_cfg_t cfg;
    balance_t *b;
    char sender[160];           /* "balance@HOST": its orders' sender */
    char last[sizeof ((balance_move_t *)0)->reason]; /* its last decision, in the status */
    int64_t adopt_until;        /* a returning manager learns the placement before it starts */
} am_balance_t;

struct am {
    am_env_t env;               /* am.c, read-only once the loop runs */
    am_daemon_t daemon;         /* am.c */
    am_system_t system;         /* am_system.c */
    am_status_t status;         /* am_status.c */
    am_orders_t orders;         /* am_orders.c */
    am_balance_t balance;       /* am_balance.c */
    struct am_check *check;     /* am_check.c: an up order's programs being checked, or NULL */
    struct am_limits *limits;   /* am_limits.c: how components' limits are held, or NULL */
    struct am_loading *applying;/* am_apply.c: an up order's changed system, installed once the
                                 * components it changes or drops have exited, or NULL */
};

static inline int64_t am_now_us(void) { return marie_mono_us(); }

/* am_status.c: events and the status message */
/* Status requests are answered at once, at most AM_STATUS_ANSWER_BURST together and then
 * AM_STATUS_ANSWER_RATE a second: a flood of requests costs the bus a few statuses a second
 * (as refused orders do), and the periodic status goes on regardless. */
#define AM_STATUS_ANSWER_BURST 10
#define AM_STATUS_ANSWER_RATE 5
void am_status_init(am_t *am);                 /* at start-up: the uptime counts from here */
void am_status_start(am_t *am);                /* the periodic status, once the bus is there */
void am_status_set_hz(am_t *am, double hz);    /* the system's rate (its timer re-armed) */
void am_on_status_request(am_t *am, const marie_am_status_request_t *rq);
void am_event(am_t *am, int sev, const char *kind, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
/* The event published but not logged (its caller logs within its own rate limit). */
void am_event_quiet(am_t *am, int sev, const char *kind, const char *text);
void am_status_changed(am_t *am);
void am_publish_status(am_t *am, bool sample);
void am_status_usage_reset(comp_t *c);            /* a new process: no sample yet */

/* am_run.c: the state machine's actions carried out */
comp_t *am_comp_find(am_t *am, const char *name);
/* A component started at the manager's real-time priority (--rt-priority) goes back to the
 * normal policy: at its first heartbeat, AM_BOOST_MAX_US after its start if none came by then
 * (a start that computes, or spins, must not hold a CPU from everything else), or when its
 * process ends. */
#define AM_BOOST_MAX_US 100000
void am_comp_unboost(comp_t *c);
bool am_comp_matches(const comp_t *c, const char *target);
/* Do what the state machine asked after an event that found the component in `before`. */
void am_comp_apply(comp_t *c, marie_sv_state_t before, const marie_sv_action_t *act);
void am_comp_want(comp_t *c);
void am_comp_stop(comp_t *c);
void am_comp_restart(comp_t *c);
void am_comp_cancel_timer(comp_t *c);
bool am_comp_timer_pending(const comp_t *c);       /* backing off, or stopping */
void am_try_start_waiting(am_t *am);
void am_stop_all(am_t *am);
void am_progress_stops(am_t *am);
void am_check_heartbeats(am_t *am);
/* Arms the check of the earliest heartbeat deadline (am.c). */
bool am_quitting(const am_t *am);              /* am.c: a signal asked it to stop and exit */
void am_reap_children(am_t *am);

/* am_output.c: components' output captured (c->out) */
void am_output_init(comp_t *c);                /* a new component: no pipes yet */
void am_output_set_rate(comp_t *c, double rate);   /* lines per second (burst 2x) */
int am_output_prepare(comp_t *c);              /* before a spawn: its line buffers; -1 with errno */
void am_output_attach(comp_t *c, int out_fd, int err_fd);   /* the spawned child's pipes */
void am_output_drain(comp_t *c);               /* its process exited: what the pipes still hold */
void am_output_moved(comp_t *c);               /* c was copied to a new place: the loop follows */
void am_comp_close_output(comp_t *c);
void am_comp_open_log(comp_t *c);
int64_t am_output_drops(const comp_t *c);      /* lines dropped by the rate limit */
void am_output_free(comp_t *c);

/* am_system.c: the loaded system and what survives a restart of the manager */
/* Loading a system: read and check the file (NULL with errs), check this host's programs (they
 * answer --describe: seconds, so an order does it in a child, am_check.c), then install it
 * (not yet started; takes the loading). am_load_system does the three at once. origin (NULL:
 * path) is the file path is a copy of, where the sender read it: the name in messages and the
 * folder its relative paths (exec, types) start from. */
typedef struct am_loading am_loading_t;
const marie_system_t *am_loading_system(const am_loading_t *l);
/* An up order's system text: the sender's file (sender_path) where this host reads the same
 * text, else a copy in the state directory, opened. */
am_loading_t *am_loading_sent(am_t *am, const char *text, const char *sender_path, const char *profile,
                              marie_errors_t *errs);
bool am_system_is(const am_t *am, const char *text, const char *profile);   /* the one loaded */
int am_loading_check_programs(am_t *am, const am_loading_t *l, marie_errors_t *errs);
/* The same without running any program: *must_run when one has to answer --describe first
 * (its description is not in the state directory's cache), and then the verdict is not one. */
int am_loading_check_cached(am_t *am, const am_loading_t *l, marie_errors_t *errs, bool *must_run);
/* Installing carries over the components of the same name and configuration hash that have
 * no timer pending (not stopping, not backing off): their process, output, log and counters go
 * on as they are. */
void am_loading_install(am_t *am, am_loading_t *l);
bool am_comp_carried(const comp_t *c, const marie_system_t *next);
void am_loading_free(am_loading_t *l);
int am_load_system(am_t *am, const char *path, const char *origin, const char *profile, marie_errors_t *errs);
void am_comps_free(am_t *am);
void am_system_free(am_t *am);                 /* the components and the system */
/* The loaded system (NULL: none) and its components, i from 0 to am_ncomps. */
const marie_system_t *am_system(const am_t *am);
size_t am_ncomps(const am_t *am);
comp_t *am_comp_at(const am_t *am, size_t i);
const char *am_system_hash(const am_t *am);    /* "" without a system */
const char *am_system_path(const am_t *am);
uint64_t am_system_text_hash(const am_t *am);     /* marie_text_hash of its text */
const char *am_profile(const am_t *am);        /* NULL: none */
bool am_is_up(const am_t *am);
void am_down(am_t *am);                        /* a down order: not up, across restarts too */
/* The user's file the running system is a copy of (MARIE_SYSTEM_ORIGIN), or NULL. */
const char *am_system_origin(const am_t *am);
void am_up(am_t *am);
void am_apply_move(am_t *am, comp_t *c, const char *host);
bool am_host_known(am_t *am, const char *h);
void am_log_settings(const am_t *am, int64_t *max_bytes, int *keep);   /* in effect */
void am_save_up_state(am_t *am);
void am_restore_up_state(am_t *am);
void am_save_children(am_t *am);       /* written from the loop, once it has done its work */
void am_children_add(comp_t *c);       /* c was spawned: saved with the others */
void am_flush_children(am_t *am);      /* a write still waiting, now (before READY=1, at exit) */
void am_kill_leftovers(am_t *am);

/* am_balance.c: automatic placement (the decisions are balance.c's) */
void am_balance_on_status(am_t *am, const marie_am_status_t *st);
void am_balance_decide(am_t *am);
/* After restoring a system: start now, or first learn the placement (balance: only). */
void am_balance_up_when_placed(am_t *am);
void am_balance_tick(am_t *am);
void am_balance_install(am_t *am, const marie_system_t *sys, const balance_cfg_t *cfg);
void am_balance_placed(am_t *am, const char *component, const char *host);
void am_balance_status(const am_t *am, marie_am_status_t *st, int64_t now);   /* its fields */
void am_balance_free(am_t *am);

/* am_check.c: an up order's programs checked in a child process, so that the loop goes on
 * (heartbeats, status, other orders) while the programs answer --describe. done runs on the
 * loop once, and owns the loading: ok, to install; not ok, with the errors as text, to free.
 * Where every program's description is cached, nothing is run: the check is made at once, and
 * done runs before am_check_start returns. One check at a time; am_check_start takes l (freed
 * when it fails: -1). */
typedef void (*am_check_done_t)(am_t *am, am_loading_t *l, bool ok, const char *errors, void *user);
int am_check_start(am_t *am, am_loading_t *l, am_check_done_t done, void *user);
bool am_check_busy(const am_t *am);
/* Ends a check under way: its child is killed and done runs with ok false and `why`. */
void am_check_cancel(am_t *am, const char *why);

/* am_limits.c: components held to their limits: a cgroup v2 where marie-am may make one, the
 * open-file rlimit, and marie-am's own watch */
void am_limits_prepare(comp_t *c, int *cgroup_fd, long *nofile);   /* before a spawn (the request's fields) */
void am_limits_spawned(comp_t *c, int cgroup_fd);                  /* after it, whatever came of it */
void am_limits_tick(am_t *am);
void am_limits_exited(comp_t *c);                                   /* before the exit is handled */
const char *am_limits_text(const comp_t *c, char *out, size_t len); /* for the status; "" without */
int am_limits_breaches(const comp_t *c);
void am_limits_comp_free(comp_t *c);
void am_limits_free(am_t *am);

/* am_apply.c: an up order of a changed system while components run (one at a time) */
bool am_any_running(const am_t *am);
bool am_apply_busy(const am_t *am);
/* Stops what l changes or drops and installs l once they have exited (takes l); the plan, as
 * the order's answer, in plan_text. Returns how many components it starts or stops here. */
int am_apply_start(am_t *am, am_loading_t *l, char *plan_text, size_t plan_len);
void am_apply_progress(am_t *am);      /* after exits: install when the stops are done */
void am_apply_cancel(am_t *am);        /* a down order, or the manager quits */

/* am_run.c: c's run moved into to (the same component of a new system) */
void am_comp_carry(comp_t *to, comp_t *from);

/* am_orders.c: orders checked (signature, freshness, replay) and answered */
int am_orders_init(am_t *am);                  /* the replay table; -1 (logged) on failure */
void am_on_order(am_t *am, const marie_am_order_t *o);
int64_t am_orders_refused(const am_t *am);
void am_orders_free(am_t *am);

#endif
