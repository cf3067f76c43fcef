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
#include "managers/am_proto.h"
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
} outpipe_t;

/* A component: the supervision state (pure) and what the I/O around it holds. */
struct comp {
    am_t *am;
    const marie_component_cfg_t *cfg;
    marie_sv_t sv;
    char host[128];             /* effective host (a move changes it) */
    marie_timer_t *timer;       /* backoff or kill timer, as the state machine asks */
    int64_t start_ticks;        /* /proc start time, with pid names the process */
    /* usage */
    marie_cpu_sample_t cpu_prev;
    float cpu;
    int64_t rss;
    /* output */
    outpipe_t out[2];
    marie_ratelimit_t rl;
    int64_t drops_pending, drops_total, log_seq;
    marie_logfile_t *logf;
    /* resource limits (am_limits.c) */
    struct {
        marie_limit_watch_t w;
        int64_t next_us;            /* the next look at what it uses */
        int breaches;
        bool in_cgroup;             /* this instance runs in its cgroup, under the kernel's limits */
        char *cgroup;               /* its cgroup directory; NULL: none */
    } lim;
};

struct am {
    char host[128];
    char *state_dir;
    char *key_path;
    char *url;
    char self_dir[PATH_MAX];
    marie_loop_t *loop;
    lcm_t *lcm;
    int sigfd;
    marie_spawner_t *spawner;   /* starts the components (spawn.c) */
    marie_auth_t *auth;
    marie_replay_t *replay;
    int64_t order_lifetime_us, max_skew_us;    /* the replay table's window */
    marie_ratelimit_t refusal_rl;              /* answers and events for refused orders */
    int64_t refusals_unannounced;
    marie_ratelimit_t status_answer_rl;        /* statuses sent on request (am_on_status_request) */
    int64_t status_requests_unanswered;
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
    bool status_settled;
    int rt_priority;            /* --rt-priority: SCHED_FIFO priority, 0 for the normal policy */        /* the last status published showed no component between states */
    bool quitting;
    int64_t quit_deadline;
    uint64_t watchdog_us;
    marie_timer_t *status_timer;
    marie_timer_t *hb_check;    /* at the earliest heartbeat deadline (am_arm_heartbeat_check) */
    marie_timer_t *children_timer;  /* the children file is written when it fires (am_save_children) */
    bool opt_status_hz, opt_log_rate, opt_log_max, opt_log_keep;   /* given on the command line */
    /* automatic placement (the system's balance: section; NULL without one) */
    balance_cfg_t bal_cfg;
    balance_t *bal;
    char bal_sender[160];       /* "balance@HOST": its orders' sender */
    char bal_last[sizeof ((balance_move_t *)0)->reason]; /* its last decision, in the status */
    int64_t adopt_until;        /* a returning manager learns the placement before it starts */
    struct am_check *check;     /* an up order's programs being checked (am_check.c), or NULL */
    struct am_limits *limits;   /* how components' limits are held (am_limits.c), or NULL */
    struct am_loading *applying;/* an up order's changed system, installed once the components it
                                 * changes or drops have exited (am_apply.c), or NULL */
};

static inline int64_t am_now_us(void) { return marie_mono_us(); }

/* am_status.c: events and the status message */
/* Status requests are answered at once, at most AM_STATUS_ANSWER_BURST together and then
 * AM_STATUS_ANSWER_RATE a second: a flood of requests costs the bus a few statuses a second
 * (as refused orders do), and the periodic status goes on regardless. */
#define AM_STATUS_ANSWER_BURST 10
#define AM_STATUS_ANSWER_RATE 5
void am_on_status_request(am_t *am, const marie_am_status_request_t *rq);
void am_event(am_t *am, int sev, const char *kind, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
void am_status_changed(am_t *am);
void am_publish_status(am_t *am, bool sample);
void am_on_status_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user);

/* am_run.c: the state machine's actions carried out */
comp_t *am_comp_find(am_t *am, const char *name);
bool am_comp_matches(const comp_t *c, const char *target);
/* Do what the state machine asked after an event that found the component in `before`. */
void am_comp_apply(comp_t *c, marie_sv_state_t before, const marie_sv_action_t *act);
void am_comp_want(comp_t *c);
void am_comp_stop(comp_t *c);
void am_comp_restart(comp_t *c);
void am_comp_cancel_timer(comp_t *c);
void am_comp_close_output(comp_t *c);
void am_try_start_waiting(am_t *am);
void am_stop_all(am_t *am);
void am_progress_stops(am_t *am);
void am_check_heartbeats(am_t *am);
/* Arms the check of the earliest heartbeat deadline (am.c). */
void am_arm_heartbeat_check(am_t *am);
void am_reap_children(am_t *am);

/* am_system.c: the loaded system and what survives a restart of the manager */
/* Loading a system: read and check the file (NULL with errs), check this host's programs (they
 * answer --describe: seconds, so an order does it in a child, am_check.c), then install it
 * (not yet started; takes the loading). am_load_system does the three at once. origin (NULL:
 * path) is the file path is a copy of, where the sender read it: the name in messages and the
 * folder its relative paths (exec, types) start from. */
typedef struct am_loading am_loading_t;
const marie_system_t *am_loading_system(const am_loading_t *l);
am_loading_t *am_loading_open(const char *path, const char *origin, const char *profile, marie_errors_t *errs);
int am_loading_check_programs(am_t *am, const am_loading_t *l, marie_errors_t *errs);
/* Installing carries over the components of the same name and configuration hash that have
 * no timer pending (not stopping, not backing off): their process, output, log and counters go
 * on as they are. */
void am_loading_install(am_t *am, am_loading_t *l);
bool am_comp_carried(const comp_t *c, const marie_system_t *next);
void am_loading_free(am_loading_t *l);
int am_load_system(am_t *am, const char *path, const char *origin, const char *profile, marie_errors_t *errs);
void am_comps_free(am_t *am);
/* The user's file the running system is a copy of (MARIE_SYSTEM_ORIGIN), or NULL. */
const char *am_system_origin(const am_t *am);
void am_up(am_t *am);
void am_apply_move(am_t *am, comp_t *c, const char *host);
bool am_host_known(am_t *am, const char *h);
void am_comp_open_log(comp_t *c);
void am_save_up_state(am_t *am);
void am_restore_up_state(am_t *am);
void am_save_children(am_t *am);       /* written from the loop, once it has done its work */
void am_flush_children(am_t *am);      /* a write still waiting, now (before READY=1, at exit) */
void am_kill_leftovers(am_t *am);
/* Replace path atomically (written beside it, then renamed); failures are silent. */
void am_write_file(const char *path, const char *text, size_t len, mode_t mode);
void am_sha256_hex(const void *data, size_t len, const char *extra, char out[65]);

/* am_balance.c: automatic placement (the decisions are balance.c's) */
void am_balance_on_status(am_t *am, const marie_am_status_t *st);
void am_balance_decide(am_t *am);
/* After restoring a system: start now, or first learn the placement (balance: only). */
void am_balance_up_when_placed(am_t *am);
void am_balance_tick(am_t *am);

/* am_check.c: an up order's programs checked in a child process, so that the loop goes on
 * (heartbeats, status, other orders) while the programs answer --describe. done runs on the
 * loop once, and owns the loading: ok, to install; not ok, with the errors as text, to free.
 * One check at a time; am_check_start takes l (freed when it fails: -1). */
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

/* am_orders.c */
void am_on_order(am_t *am, const marie_am_order_t *o);

#endif
