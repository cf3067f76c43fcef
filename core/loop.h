/* loop: one poll() event loop per process over fds and fixed-rate timers, on a wall or simulated clock. */
#ifndef MARIE_LOOP_H
#define MARIE_LOOP_H

#include <stdint.h>
#include <poll.h>

#include <lcm/lcm.h>

#include "core/bus/bus.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct marie_loop marie_loop_t;
typedef struct marie_timer marie_timer_t;

typedef void (*marie_fd_cb_t)(marie_loop_t *loop, int fd, short revents, void *user);
/* `overruns` is how many whole periods were missed before this call (0 when on time). */
typedef void (*marie_timer_cb_t)(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user);

typedef enum {
    MARIE_CLOCK_WALL = 0,   /* timers on CLOCK_MONOTONIC, now() on CLOCK_REALTIME */
    MARIE_CLOCK_SIM,        /* now() and timers follow marie_loop_set_sim_time() */
} marie_clock_kind_t;

marie_loop_t *marie_loop_create(void);
void marie_loop_destroy(marie_loop_t *loop);            /* NULL is a no-op */

int marie_loop_add_fd(marie_loop_t *loop, int fd, short events, marie_fd_cb_t cb, void *user);
int marie_loop_remove_fd(marie_loop_t *loop, int fd);
/* Change what a watched fd waits for (POLLIN, POLLOUT...), from the next poll round on. */
int marie_loop_set_events(marie_loop_t *loop, int fd, short events);

/* A bus as one more fd (core/bus/bus.h): its handlers run from the loop, at most `burst` messages per
 * round (1 keeps timers and other fds served between messages; a bridge that forwards floods
 * may take more). 0, or -1 with errno. */
int marie_loop_add_bus(marie_loop_t *loop, lcm_t *lcm, int burst);
int marie_loop_remove_bus(marie_loop_t *loop, lcm_t *lcm);

/* Bytes waiting to be read on fd now, without waiting for more (0 when the fd cannot say).
 * For a tty this includes what the kernel still holds in its flip buffer: bytes written to a
 * pty's master reach the slave through a worker thread, and FIONREAD alone reads 0 until it has
 * run; a poll of the fd waits for that push. */
int marie_fd_unread(int fd);

/* A fixed-rate timer: fires every period_us on the loop's clock, first after period_us.
 * Late firings are not queued: the next deadline skips the missed periods, which are
 * counted as overruns. Returns NULL with errno set on failure; the loop owns the timer. */
marie_timer_t *marie_loop_add_timer(marie_loop_t *loop, int64_t period_us, marie_timer_cb_t cb, void *user);
/* A one-shot timer after delay_us. It is freed after it fires: do not remove it then. */
marie_timer_t *marie_loop_add_oneshot(marie_loop_t *loop, int64_t delay_us, marie_timer_cb_t cb, void *user);
/* The same on CLOCK_MONOTONIC even when the loop follows simulated time (heartbeats, timeouts). */
marie_timer_t *marie_loop_add_wall_timer(marie_loop_t *loop, int64_t period_us, marie_timer_cb_t cb, void *user);
marie_timer_t *marie_loop_add_wall_oneshot(marie_loop_t *loop, int64_t delay_us, marie_timer_cb_t cb, void *user);
void marie_loop_remove_timer(marie_loop_t *loop, marie_timer_t *t);    /* NULL is a no-op */
int64_t marie_timer_overruns(const marie_timer_t *t);                  /* total so far */
int64_t marie_timer_period(const marie_timer_t *t);
/* A fixed-rate timer's new period, from its next firing on (one-shots are left alone). */
void marie_timer_set_period(marie_timer_t *t, int64_t period_us);

/* Clock. In MARIE_CLOCK_SIM, now() is the last simulated time given (0 before the first)
 * and timers fire as simulated time passes their deadlines. */
void marie_loop_set_clock(marie_loop_t *loop, marie_clock_kind_t kind);
marie_clock_kind_t marie_loop_clock(const marie_loop_t *loop);
void marie_loop_set_sim_time(marie_loop_t *loop, int64_t utime);
int64_t marie_loop_now(const marie_loop_t *loop);       /* microseconds on the loop's clock */
/* Microseconds on the clock the loop's (non-wall) timers run on: CLOCK_MONOTONIC on the wall
 * clock, simulated time on the sim clock. Deadlines code keeps itself (a driver's protocol
 * timeouts) use it, so they follow `--clock sim` as the timers do and never jump with NTP. */
int64_t marie_loop_mono(const marie_loop_t *loop);
/* 0 on the sim clock until a simulated time has been given (deadlines taken before would count
 * from 0 and expire at the first clock message), 1 after it and always on the wall clock. */
int marie_loop_clock_known(const marie_loop_t *loop);

/* Spinning: for spin_us after a callback ran, a round that would sleep looks at its fds
 * without sleeping first (poll with no wait, again and again), so an answer that comes within
 * the window is read without waking a sleeping process: the round trip of a request and its
 * reply loses the kernel's wake-ups (docs/transport.md, "Spinning"). It costs up to spin_us of
 * CPU after each burst of work and nothing while idle. 0 (the default) never spins; never on
 * the simulator's clock. Components take it from `sched: {spin_us: N}` in the system file. */
void marie_loop_set_spin(marie_loop_t *loop, int64_t spin_us);
int64_t marie_loop_spin(const marie_loop_t *loop);

/* Run one poll round, waiting at most timeout_ms (-1: until an fd or timer is due).
 * Returns the number of callbacks run, or -1 with errno. EINTR is retried. */
int marie_loop_run_once(marie_loop_t *loop, int timeout_ms);
/* Run until marie_loop_quit(). Returns 0, or -1 with errno on a poll failure. */
int marie_loop_run(marie_loop_t *loop);
void marie_loop_quit(marie_loop_t *loop);
int marie_loop_quitting(const marie_loop_t *loop);

/* How a program that genuinely waits (a command line for its reply, a benchmark for its
 * messages) waits: run rounds until done(user) returns non-zero (checked before each round and
 * after the last; NULL: never), marie_loop_quit() is called, or timeout_ms of monotonic time
 * pass (-1: no deadline; 0: one round of what is ready). Not from a callback of the same loop.
 * Returns 1 when done held, 0 at the deadline or on quit, or -1 with errno on a poll failure. */
typedef int (*marie_loop_cond_t)(void *user);
int marie_loop_run_until(marie_loop_t *loop, int timeout_ms, marie_loop_cond_t done, void *user);

/* Process-wide SIGTERM/SIGINT: the handler only sets a flag and wakes the loop through a
 * pipe; on_signal then runs from the loop. Pass NULL to restore default handling. */
typedef void (*marie_signal_cb_t)(marie_loop_t *loop, int signo, void *user);
int marie_loop_catch_signals(marie_loop_t *loop, marie_signal_cb_t on_signal, void *user);
/* Other signals as loop events (SIGUSR1 to inject a fault, SIGHUP to reload...): they are
 * blocked in this thread and read from a signalfd; on_signal runs from the loop once per signal
 * received, with its number. Once per loop; 0, or -1 with errno. Children inherit the block: unblock in
 * them before exec if they need these signals. */
int marie_loop_watch_signals(marie_loop_t *loop, const int *signos, int n, marie_signal_cb_t on_signal, void *user);

#ifdef __cplusplus
}
#endif
#endif
