/* The supervision rules of marie-am as a pure state machine: events in (order, exit,
 * heartbeat, timer, tick), actions out (spawn, stop signal, SIGKILL, arm the timer, an event).
 * No system call here: marie-am does the I/O, tests drive it with made-up clocks. */
#ifndef MARIE_MANAGERS_SUPERVISE_H
#define MARIE_MANAGERS_SUPERVISE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/config.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The manager's view of one component. */
typedef enum {
    MARIE_SV_STOPPED = 0,   /* not wanted */
    MARIE_SV_WAITING,       /* wanted, its dependencies are not all running yet */
    MARIE_SV_STARTING,      /* spawned, no running heartbeat yet */
    MARIE_SV_RUNNING,
    MARIE_SV_STOPPING,      /* stop signal sent, SIGKILL when stop_timeout passes */
    MARIE_SV_BACKOFF,       /* exited, respawn after a delay */
    MARIE_SV_FAILED,        /* gave up, or failed with policy never */
    MARIE_SV_EXITED,        /* exited cleanly and the policy does not restart it */
} marie_sv_state_t;

/* Names as marie status shows them ("stopped", "running", ...). */
const char *marie_sv_state_name(marie_sv_state_t st);

#define MARIE_SV_MAX_FAIL_TIMES 64

typedef struct {
    const marie_component_cfg_t *cfg;   /* kept, not owned */
    bool local;                 /* runs on this host (else: only its heartbeats are watched) */
    bool wanted;
    marie_sv_state_t st;
    int pid;                    /* > 0 while a process runs */
    int64_t started_us;         /* monotonic clock of the last spawn */
    int restarts;
    int last_exit;              /* exit status, or -signal */
    int64_t fail_times[MARIE_SV_MAX_FAIL_TIMES];
    int nfail_times;
    double next_backoff_s;
    bool restart_after_stop;
    bool count_failure;         /* the coming exit is a failure (hang, failed state) */
    bool stop_pending;          /* down: wait for dependents first */
    int64_t stop_pending_since;
    int64_t hb_us;              /* last heartbeat (any host), 0: none */
    int hb_state;               /* its marie_state_t, -1: none */
    int64_t peer_us;            /* last status of the component's manager (remote hosts) */
    bool peer_running;
} marie_sv_t;

/* What the caller does after an event, in this order: publish the event, signals, timer,
 * spawn, then look at the other components. */
enum {
    MARIE_SV_TERM = 1 << 0,          /* SIGTERM + SIGCONT to the process group */
    MARIE_SV_KILL = 1 << 1,          /* SIGKILL to the process group (stop timeout passed) */
    MARIE_SV_SPAWN = 1 << 2,         /* start the process now, then call marie_sv_spawned */
    MARIE_SV_START_WAITING = 1 << 3, /* dependencies may now be ready: try the waiting ones */
    MARIE_SV_PROGRESS_STOPS = 1 << 4,/* a dependent is gone: try the pending stops */
    MARIE_SV_STATUS = 1 << 5,        /* something shown in the status changed (besides st) */
};

typedef struct {
    unsigned what;              /* MARIE_SV_* bits */
    bool cancel_timer;          /* drop the component's timer */
    double timer_s;             /* > 0: (re)arm the component's timer; call marie_sv_timer */
    int event_sev;              /* marie_event_t severity, with event_kind */
    const char *event_kind;     /* NULL: no event */
    bool log_only;              /* event_text is a log line, not a bus event */
    char event_text[400];
} marie_sv_action_t;

/* Set up a component that is not running. cfg is kept, not copied. */
void marie_sv_init(marie_sv_t *sv, const marie_component_cfg_t *cfg, bool local);

/* Order start / up: wanted; leaves a stopped, failed or exited component waiting with a fresh
 * failure count. The caller then tries the waiting ones. */
void marie_sv_want(marie_sv_t *sv);
/* Order stop: not wanted; stop signal, SIGKILL after stop_timeout. */
void marie_sv_stop(marie_sv_t *sv, marie_sv_action_t *act);
/* Order restart: stop then start again (a restart asked for is not a failure). */
void marie_sv_restart(marie_sv_t *sv, marie_sv_action_t *act);
/* Down: not wanted; a live one waits for its dependents (see marie_sv_progress_stop). */
void marie_sv_stop_later(marie_sv_t *sv, int64_t now, marie_sv_action_t *act);
/* A pending stop goes ahead once no dependent is alive, or stop_timeout + 2 s later. */
void marie_sv_progress_stop(marie_sv_t *sv, bool dependents_alive, int64_t now, marie_sv_action_t *act);
/* The component moved to another host, or here. A move to this host while it is already
 * here changes nothing: its liveness stays that of the instance that runs (the caller does
 * not call this for a move between two other hosts that leaves its host as it was). */
void marie_sv_set_local(marie_sv_t *sv, bool local, bool up, marie_sv_action_t *act);

/* Dependencies are ready: a waiting component asks to be spawned. */
void marie_sv_ready(marie_sv_t *sv, marie_sv_action_t *act);
/* The spawn done for MARIE_SV_SPAWN: pid > 0, or <= 0 if it failed. */
void marie_sv_spawned(marie_sv_t *sv, int pid, int64_t now);
/* The process ended with this wait status (waitpid). */
void marie_sv_exited(marie_sv_t *sv, int status, int64_t now, marie_sv_action_t *act);
/* A heartbeat from this component's process (the caller checked its pid). */
void marie_sv_heartbeat(marie_sv_t *sv, int state, const char *reason, int64_t now, marie_sv_action_t *act);
/* Its manager's status says whether it runs (remote components). Returns true if that changed. */
bool marie_sv_peer_status(marie_sv_t *sv, bool running, int64_t now);
/* The timer armed with timer_s fired. */
void marie_sv_timer(marie_sv_t *sv, marie_sv_action_t *act);
/* The component broke its limits (limits.h): a failure. A live one gets the stop signal and is
 * started again as after any failure, unless stop: then it is not wanted any more (and one the
 * kernel already killed is not started again). */
void marie_sv_breach(marie_sv_t *sv, bool stop, marie_sv_action_t *act);
/* Periodic: a live component silent for heartbeat_timeout is restarted. */
void marie_sv_check_heartbeat(marie_sv_t *sv, int64_t now, marie_sv_action_t *act);
/* When marie_sv_check_heartbeat() would find it silent too long if nothing came (INT64_MAX:
 * never, no heartbeat is watched). */
int64_t marie_sv_heartbeat_deadline(const marie_sv_t *sv);

/* Is this component up enough for the ones that depend on it to start? */
bool marie_sv_up(const marie_sv_t *sv, int64_t now);
/* Is this component alive, so that what it depends on must not stop yet? */
bool marie_sv_alive(const marie_sv_t *sv, int64_t now);

/* Text for a wait status: "exit status 1", "killed by signal 9 (Killed)". */

#ifdef __cplusplus
}
#endif
#endif
