/* loop: one poll() loop over fds and fixed-rate timers, on the monotonic or a simulated clock. */
#include "core/loop.h"

#include <errno.h>
#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/signalfd.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "core/buf.h"
#include "core/err.h"
#include "core/log.h"
#include "core/time.h"

/* The waits for the fast path a loop remembers, to decide whether to spin before sleeping. */
#define FAST_GAPS 8

struct marie_timer {
    marie_timer_t *next;
    int64_t period;         /* 0: one-shot */
    int64_t deadline;       /* on the loop's timer clock */
    int64_t overruns;
    int wall;               /* always on CLOCK_MONOTONIC, whatever the loop's clock */
    marie_timer_cb_t cb;
    void *user;
    int removed;
};

typedef struct {
    int fd;
    short events;
    marie_fd_cb_t cb;
    void *user;
} fd_watch_t;

typedef struct lcm_watch {
    lcm_t *lcm;
    int burst;
    struct lcm_watch *next;
    int wake_fd;            /* the bus's fast-path doorbell (marie_bus_wake_fd), or -1 */
} lcm_watch_t;

struct marie_loop {
    fd_watch_t *fds;
    size_t nfds, capfds;
    int fds_changed;
    struct pollfd *pfds;
    size_t cappfds;
    marie_timer_t *timers;
    int in_timers;          /* nesting depth of run_timers (a callback may run the loop) */
    marie_clock_kind_t clock;
    int64_t sim_now;
    int sim_known;          /* a simulated time has been given */
    int quit;
    int sigpipe[2];
    marie_signal_cb_t on_signal;
    void *signal_user;
    int sigfd;              /* marie_loop_watch_signals' signalfd, or -1 */
    marie_signal_cb_t on_watched;
    void *watched_user;
    struct lcm_watch *lcms;
    int64_t spin_us;        /* marie_loop_set_spin: 0 never spins */
    int64_t last_active;    /* CLOCK_MONOTONIC when a callback last ran (spin only) */
    int32_t gaps[FAST_GAPS];    /* the last waits for the fast path, in us (fast_wait) */
    unsigned ngaps;
    uint8_t unpaid;         /* the last 8 spins, a bit each: 1 when it ended without a message */
    unsigned held;          /* waits since the last spin that found a message (probes) */
};

static volatile sig_atomic_t pending_signal;
static int signal_wake_fd = -1;

marie_loop_t *marie_loop_create(void)
{
    marie_loop_t *loop = calloc(1, sizeof *loop);
    if (!loop)
        return NULL;
    loop->sigpipe[0] = loop->sigpipe[1] = -1;
    loop->sigfd = -1;
    return loop;
}

void marie_loop_destroy(marie_loop_t *loop)
{
    if (!loop)
        return;
    if (loop->sigpipe[0] >= 0)
        marie_loop_catch_signals(loop, NULL, NULL);
    if (loop->sigfd >= 0)
        close(loop->sigfd);
    marie_timer_t *t = loop->timers;
    while (t) {
        marie_timer_t *next = t->next;
        free(t);
        t = next;
    }
    while (loop->lcms) {
        struct lcm_watch *next = loop->lcms->next;
        free(loop->lcms);
        loop->lcms = next;
    }
    free(loop->fds);
    free(loop->pfds);
    free(loop);
}

int marie_loop_add_fd(marie_loop_t *loop, int fd, short events, marie_fd_cb_t cb, void *user)
{
    if (fd < 0 || !cb)
        return marie_fail(EINVAL);
    for (size_t i = 0; i < loop->nfds; i++)
        if (loop->fds[i].fd == fd)
            return marie_fail(EEXIST);
    if (MARIE_GROW(loop->fds, loop->capfds, loop->nfds + 1) < 0)
        return -1;
    loop->fds[loop->nfds++] = (fd_watch_t){fd, events, cb, user};
    loop->fds_changed = 1;
    return 0;
}

int marie_loop_remove_fd(marie_loop_t *loop, int fd)
{
    for (size_t i = 0; i < loop->nfds; i++) {
        if (loop->fds[i].fd == fd) {
            memmove(&loop->fds[i], &loop->fds[i + 1], (loop->nfds - i - 1) * sizeof loop->fds[0]);
            loop->nfds--;
            loop->fds_changed = 1;
            return 0;
        }
    }
    return marie_fail(ENOENT);
}

int marie_loop_set_events(marie_loop_t *loop, int fd, short events)
{
    for (size_t i = 0; i < loop->nfds; i++) {
        if (loop->fds[i].fd == fd) {
            loop->fds[i].events = events;
            return 0;
        }
    }
    return marie_fail(ENOENT);
}

static void on_lcm_readable(marie_loop_t *loop, int fd, short revents, void *user)
{
    lcm_watch_t *w = user;
    marie_bus_handle(w->lcm, w->burst);
}

static void on_wake(marie_loop_t *loop, int fd, short revents, void *user)
{
    lcm_watch_t *w = user;
    marie_bus_handle_wake(w->lcm, w->burst);
}

/* A bus's doorbell comes with its first fast-path subscription, after the bus joined the loop:
 * watched from the next round on. */
static void sync_wake_fds(marie_loop_t *loop)
{
    for (lcm_watch_t *w = loop->lcms; w; w = w->next) {
        int fd = marie_bus_wake_fd(w->lcm);
        if (fd == w->wake_fd)
            continue;
        if (w->wake_fd >= 0)
            marie_loop_remove_fd(loop, w->wake_fd);
        w->wake_fd = fd >= 0 && marie_loop_add_fd(loop, fd, POLLIN, on_wake, w) == 0 ? fd : -1;
    }
}

/* Buses whose fast path holds messages: their doorbell's entry in pfds made ready without a
 * system call. sleeping: the loop is about to sleep (the buses are told, so that publishers ring
 * from now on). Returns how many. */
static int fast_ready(marie_loop_t *loop, size_t n, bool sleeping)
{
    int ready = 0;
    for (lcm_watch_t *w = loop->lcms; w; w = w->next) {
        if (w->wake_fd < 0 || !(sleeping ? marie_bus_sleep(w->lcm, true) : marie_bus_pending(w->lcm)))
            continue;
        for (size_t i = 0; i < n; i++)
            if (loop->pfds[i].fd == w->wake_fd) {
                loop->pfds[i].revents = POLLIN;
                ready++;
            }
    }
    return ready;
}

static void fast_awake(marie_loop_t *loop)
{
    for (lcm_watch_t *w = loop->lcms; w; w = w->next)
        if (w->wake_fd >= 0)
            marie_bus_sleep(w->lcm, false);
}

/* Under the simulated clock, what another fd brings (a device's bytes, a CAN frame) came at the
 * newest instant the simulator has sent, and that clock message may still wait in the bus's
 * socket behind others, read one a round: the driver would stamp the input with an older time
 * (marie-lms200 stamped a third of its scans 20-50 ms early while the simulator ran ahead).
 * So before such an fd's callback the bus is read up to now (bounded: a flood cannot starve the
 * device). */
#define CATCH_UP_MAX 256

static int is_lcm_fd(const marie_loop_t *loop, int fd)
{
    for (const lcm_watch_t *w = loop->lcms; w; w = w->next)
        if (marie_bus_fd(w->lcm) == fd || w->wake_fd == fd)
            return 1;
    return 0;
}

static void catch_up_clock(marie_loop_t *loop)
{
    /* A handler may remove a bus: each is looked up again before it is read. */
    lcm_t *buses[8];
    int n = 0;
    for (const lcm_watch_t *w = loop->lcms; w && n < 8; w = w->next)
        buses[n++] = w->lcm;
    for (int i = 0; i < n && !loop->quit; i++)
        for (const lcm_watch_t *w = loop->lcms; w; w = w->next)
            if (w->lcm == buses[i]) {
                marie_bus_handle(buses[i], CATCH_UP_MAX);
                break;
            }
}

int marie_loop_add_bus(marie_loop_t *loop, lcm_t *lcm, int burst)
{
    int fd = lcm ? marie_bus_fd(lcm) : -1;
    if (fd < 0)
        return marie_fail(EINVAL);
    lcm_watch_t *w = calloc(1, sizeof *w);
    if (!w)
        return marie_fail(ENOMEM);
    *w = (lcm_watch_t){lcm, burst > 0 ? burst : 1, loop->lcms, -1};
    int rc = marie_loop_add_fd(loop, fd, POLLIN, on_lcm_readable, w);
    if (rc < 0) {
        free(w);
        return rc;
    }
    loop->lcms = w;
    return 0;
}

int marie_loop_remove_bus(marie_loop_t *loop, lcm_t *lcm)
{
    for (lcm_watch_t **p = &loop->lcms; *p; p = &(*p)->next) {
        if ((*p)->lcm == lcm) {
            lcm_watch_t *w = *p;
            *p = w->next;
            if (w->wake_fd >= 0)
                marie_loop_remove_fd(loop, w->wake_fd);
            free(w);
            return marie_loop_remove_fd(loop, marie_bus_fd(lcm));
        }
    }
    return marie_fail(ENOENT);
}

/* Timers run on CLOCK_MONOTONIC for the wall clock kind, on simulated time otherwise. */
static int64_t clock_now(const marie_loop_t *loop, int wall)
{
    return loop->clock == MARIE_CLOCK_SIM && !wall ? loop->sim_now : marie_mono_us();
}

static marie_timer_t *add_timer(marie_loop_t *loop, int64_t period, int64_t delay,
                                marie_timer_cb_t cb, void *user, int wall)
{
    if (delay < 0 || !cb)
        return marie_fail_null(EINVAL);
    marie_timer_t *t = calloc(1, sizeof *t);
    if (!t)
        return NULL;
    t->period = period;
    t->wall = wall;
    t->deadline = clock_now(loop, wall) + delay;
    t->cb = cb;
    t->user = user;
    t->next = loop->timers;
    loop->timers = t;
    return t;
}

marie_timer_t *marie_loop_add_timer(marie_loop_t *loop, int64_t period_us, marie_timer_cb_t cb, void *user)
{
    if (period_us <= 0)
        return marie_fail_null(EINVAL);
    return add_timer(loop, period_us, period_us, cb, user, 0);
}

marie_timer_t *marie_loop_add_wall_timer(marie_loop_t *loop, int64_t period_us, marie_timer_cb_t cb, void *user)
{
    if (period_us < 0)
        return marie_fail_null(EINVAL);
    return add_timer(loop, period_us, period_us, cb, user, 1);
}

marie_timer_t *marie_loop_add_oneshot(marie_loop_t *loop, int64_t delay_us, marie_timer_cb_t cb, void *user)
{
    return add_timer(loop, 0, delay_us, cb, user, 0);
}

marie_timer_t *marie_loop_add_wall_oneshot(marie_loop_t *loop, int64_t delay_us, marie_timer_cb_t cb, void *user)
{
    return add_timer(loop, 0, delay_us, cb, user, 1);
}

static void reap_timers(marie_loop_t *loop)
{
    marie_timer_t **pp = &loop->timers;
    while (*pp) {
        if ((*pp)->removed) {
            marie_timer_t *dead = *pp;
            *pp = dead->next;
            free(dead);
        } else {
            pp = &(*pp)->next;
        }
    }
}

void marie_loop_remove_timer(marie_loop_t *loop, marie_timer_t *t)
{
    if (!t)
        return;
    t->removed = 1;
    if (!loop->in_timers)
        reap_timers(loop);
}

int64_t marie_timer_overruns(const marie_timer_t *t) { return t->overruns; }
int64_t marie_timer_period(const marie_timer_t *t) { return t->period; }

void marie_timer_set_period(marie_timer_t *t, int64_t period_us)
{
    if (t->period > 0 && period_us > 0)
        t->period = period_us;      /* from the next firing on */
}

void marie_loop_set_clock(marie_loop_t *loop, marie_clock_kind_t kind)
{
    if (loop->clock == kind)
        return;
    int64_t before = clock_now(loop, 0);
    loop->clock = kind;
    int64_t after = clock_now(loop, 0);
    /* Keep every timer's remaining delay across the change of time base. */
    for (marie_timer_t *t = loop->timers; t; t = t->next)
        if (!t->wall)
            t->deadline += after - before;
}

marie_clock_kind_t marie_loop_clock(const marie_loop_t *loop) { return loop->clock; }

void marie_loop_set_sim_time(marie_loop_t *loop, int64_t utime)
{
    loop->sim_known = 1;
    if (utime > loop->sim_now)
        loop->sim_now = utime;
}

int64_t marie_loop_now(const marie_loop_t *loop)
{
    return loop->clock == MARIE_CLOCK_SIM ? loop->sim_now : marie_wall_us();
}

int64_t marie_loop_mono(const marie_loop_t *loop) { return clock_now(loop, 0); }
int marie_loop_clock_known(const marie_loop_t *loop) { return loop->clock != MARIE_CLOCK_SIM || loop->sim_known; }

int marie_fd_unread(int fd)
{
    struct pollfd p = { .fd = fd, .events = POLLIN };
    int n = 0;
    if (fd < 0 || poll(&p, 1, 0) < 0 || ioctl(fd, FIONREAD, &n) < 0)
        return 0;
    return n;
}

/* Runs due timers once each; returns how many ran. */
static int run_timers(marie_loop_t *loop)
{
    int ran = 0;
    int64_t sim_now = clock_now(loop, 0), mono_now = marie_mono_us();
    loop->in_timers++;
    for (marie_timer_t *t = loop->timers; t && !loop->quit; t = t->next) {
        int64_t now = t->wall || loop->clock != MARIE_CLOCK_SIM ? mono_now : sim_now;
        if (t->removed || t->deadline > now)
            continue;
        int64_t missed = 0;
        if (t->period > 0) {
            /* Skip whole periods that already passed rather than firing a burst. */
            missed = (now - t->deadline) / t->period;
            t->deadline += (missed + 1) * t->period;
            t->overruns += missed;
        } else {
            t->removed = 1;
        }
        t->cb(loop, t, missed, t->user);
        ran++;
    }
    if (--loop->in_timers == 0)
        reap_timers(loop);
    return ran;
}

static int next_timeout_ms(const marie_loop_t *loop, int timeout_ms)
{
    /* Simulated deadlines are reached through set_sim_time, not by waiting. */
    int sim = loop->clock == MARIE_CLOCK_SIM;
    int64_t now = marie_mono_us(), best = -1;
    for (const marie_timer_t *t = loop->timers; t; t = t->next) {
        if (t->removed || (sim && !t->wall))
            continue;
        int64_t wait = t->deadline > now ? t->deadline - now : 0;
        if (best < 0 || wait < best)
            best = wait;
    }
    if (best < 0)
        return timeout_ms;
    int ms = (int)((best + 999) / 1000);
    return (timeout_ms < 0 || ms < timeout_ms) ? ms : timeout_ms;
}

void marie_loop_set_spin(marie_loop_t *loop, int64_t spin_us) { loop->spin_us = spin_us > 0 ? spin_us : 0; }
int64_t marie_loop_spin(const marie_loop_t *loop) { return loop->spin_us; }

static bool fast_path(const marie_loop_t *loop)
{
    for (const lcm_watch_t *w = loop->lcms; w; w = w->next)
        if (w->wake_fd >= 0)
            return true;
    return false;
}

/* Spinning with a fast path: its rings are looked at in memory at every turn and the fds every
 * SPIN_POLL_EVERY turns, with the CPU yielded at every turn, as the plain spin does (a process
 * woken on this CPU runs at once). */
#define SPIN_POLL_EVERY 16
static int spin_fast(marie_loop_t *loop, size_t n, int64_t now, int64_t until, int *timeout_ms, int64_t start)
{
    int rc = 0;
    for (unsigned k = 1; now < until; k++) {
        if ((rc = fast_ready(loop, n, false)) > 0 || (k % SPIN_POLL_EVERY == 0 && (rc = poll(loop->pfds, n, 0)) != 0))
            break;
        sched_yield();
        now = marie_mono_us();
    }
    if (*timeout_ms > 0) {
        int spent_ms = (int)((now - start) / 1000);
        *timeout_ms = spent_ms < *timeout_ms ? *timeout_ms - spent_ms : 0;
    }
    return rc;
}

/* Waiting for the fast path: a loop whose recent waits for its rings were short looks at them
 * in memory for a while before it sleeps on the doorbell, so that an answer that comes within
 * that time costs neither side a system call nor the wake-up of a sleeping process. Bounded by
 * FAST_SPIN_MAX_US and taken only when the median of the last FAST_GAPS waits was shorter
 * (then 2x it, plus a margin): a reader of a stream at 1 kHz or slower never spins, and one
 * whose answers stop coming goes back to sleeping at once after its next long wait. No
 * sched_yield(): beside busy processes a yield hands one of them the CPU for a whole slice
 * (docs/transport.md, "Waiting for the fast path"). Not while a reader this loop's publish
 * woke likely waits for this CPU (marie_bus_waking), when the loop spins anyway (spin_us), nor
 * on the simulator's clock. */
#define FAST_SPIN_MAX_US 50
#define FAST_SPIN_MARGIN_US 5
/* When none of the last 8 spins found a message (the answer comes from this loop's own CPU,
 * after it sleeps: two processes the kernel keeps on one CPU), the loop sleeps at once but for
 * probes, which spin to see whether that changed: the 1st, 2nd, 4th, ... wait after the last spin
 * that paid, then one in FAST_PROBE_EVERY (a loop whose peers change, one answering from another
 * CPU after one from its own, spins again within a few waits). */
#define FAST_PROBE_EVERY 32
#define FAST_CLOCK_EVERY 4
#define FAST_POLL_EVERY 64      /* the fds every 64 turns: every 5-10 us */


/* A CPU's hint that it is spinning (the other hyperthread gets the core meanwhile). */
static inline void cpu_relax(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__)
    __asm__ volatile("yield");
#endif
}

/* How long to spin, in us, from the last waits: 0 while fewer than FAST_GAPS were seen. */
static int64_t fast_window(const marie_loop_t *loop)
{
    if (loop->ngaps < FAST_GAPS)
        return 0;
    int32_t g[FAST_GAPS];
    for (int i = 0; i < FAST_GAPS; i++) {       /* sorted as they come: qsort's calls cost more */
        int j = i;
        for (; j > 0 && g[j - 1] > loop->gaps[i]; j--)
            g[j] = g[j - 1];
        g[j] = loop->gaps[i];
    }
    int64_t median = g[FAST_GAPS / 2];
    if (median >= FAST_SPIN_MAX_US)
        return 0;
    return 2 * median + FAST_SPIN_MARGIN_US < FAST_SPIN_MAX_US ? 2 * median + FAST_SPIN_MARGIN_US : FAST_SPIN_MAX_US;
}

static bool fast_waking(const marie_loop_t *loop)
{
    for (const lcm_watch_t *w = loop->lcms; w; w = w->next)
        if (w->wake_fd >= 0 && marie_bus_waking(w->lcm))
            return true;
    return false;
}

/* Whether this wait may spin: not while the last 8 spins all came to nothing, but to probe. */
static bool fast_spin_pays(marie_loop_t *loop)
{
    if (loop->unpaid != 0xff)
        return true;
    unsigned h = ++loop->held;
    return h % FAST_PROBE_EVERY == 0 || (h < FAST_PROBE_EVERY && (h & (h - 1)) == 0);
}

static int fast_spin(marie_loop_t *loop, size_t n, int64_t start, int wait_ms)
{
    if (loop->spin_us || loop->clock == MARIE_CLOCK_SIM || !fast_path(loop))
        return 0;
    int64_t window = fast_window(loop);
    if (window == 0 || !fast_spin_pays(loop))
        return 0;
    int64_t until = start + window;
    if (wait_ms > 0 && start + (int64_t)wait_ms * 1000 < until)
        until = start + (int64_t)wait_ms * 1000;
    unsigned turns = 0;
    int rc = 0;
    /* A turn is a look at the rings and two pauses (20 ns each here): the answer is seen within
     * about 0.1 us of its commit. The clock is read every FAST_CLOCK_EVERY turns (40 ns a read). */
    for (int64_t now = start; now < until;) {
        if ((rc = fast_ready(loop, n, false)) != 0 || fast_waking(loop))
            break;
        if (++turns % FAST_POLL_EVERY == 0 && (rc = poll(loop->pfds, n, 0)) != 0)
            break;
        cpu_relax();
        cpu_relax();
        if (turns % FAST_CLOCK_EVERY == 0)
            now = marie_mono_us();
    }
    loop->unpaid = (uint8_t)(loop->unpaid << 1 | (rc <= 0));
    if (rc > 0)
        loop->held = 0;
    return rc;
}

/* After a wait: how long the fast path took to bring something, or, when something else ended
 * the wait (a socket, a timer), a wait the spin would not have shortened. */
static void fast_waited(marie_loop_t *loop, size_t n, int64_t start)
{
    int64_t gap = INT32_MAX;
    for (const lcm_watch_t *w = loop->lcms; w; w = w->next)
        for (size_t i = 0; w->wake_fd >= 0 && i < n; i++)
            if (loop->pfds[i].fd == w->wake_fd && loop->pfds[i].revents)
                gap = marie_mono_us() - start;
    loop->gaps[loop->ngaps++ % FAST_GAPS] = gap < INT32_MAX ? (int32_t)gap : INT32_MAX;
}

/* Within spin_us of the last callback, look at the fds without sleeping until one is ready or
 * the window (or the round's wait) ends: a reply that comes back within it is read without the
 * wake-up of a sleeping process. Returns poll()'s result (0: nothing came, sleep in poll) or 0
 * when not spinning; *timeout_ms loses the time spun. Never on the simulator's clock (simulated
 * time needs no CPU on time). */
static int spin(marie_loop_t *loop, size_t n, int *timeout_ms)
{
    if (!loop->spin_us || loop->clock == MARIE_CLOCK_SIM)
        return 0;
    int64_t start = marie_mono_us(), now = start, until = loop->last_active + loop->spin_us;
    int wait_ms = next_timeout_ms(loop, *timeout_ms);
    if (wait_ms == 0)
        return 0;
    if (wait_ms > 0 && now + (int64_t)wait_ms * 1000 < until)
        until = now + (int64_t)wait_ms * 1000;
    int rc = 0;
    if (fast_path(loop))
        return spin_fast(loop, n, now, until, timeout_ms, start);
    while (now < until && (rc = poll(loop->pfds, n, 0)) == 0) {
        /* A process woken on this CPU (the peer this loop just sent to, often: the kernel
         * likes to wake it beside its waker) runs now instead of after the window. */
        sched_yield();
        now = marie_mono_us();
    }
    if (*timeout_ms > 0) {
        int spent_ms = (int)((now - start) / 1000);
        *timeout_ms = spent_ms < *timeout_ms ? *timeout_ms - spent_ms : 0;
    }
    return rc;
}

int marie_loop_run_once(marie_loop_t *loop, int timeout_ms)
{
    int ran = run_timers(loop);
    if (loop->quit)
        return ran;
    if (ran)
        timeout_ms = 0;
    sync_wake_fds(loop);
    if (loop->cappfds < loop->nfds) {
        struct pollfd *n = realloc(loop->pfds, loop->nfds * sizeof *n);
        if (!n)
            return marie_fail(ENOMEM);
        loop->pfds = n;
        loop->cappfds = loop->nfds;
    }
    size_t n = loop->nfds;
    for (size_t i = 0; i < n; i++)
        loop->pfds[i] = (struct pollfd){loop->fds[i].fd, loop->fds[i].events, 0};
    int rc = spin(loop, n, &timeout_ms);
    if (rc == 0) {
        int wait = next_timeout_ms(loop, timeout_ms);
        int64_t start = wait != 0 ? marie_mono_us() : 0;
        rc = wait != 0 ? fast_spin(loop, n, start, wait) : 0;
        /* Before sleeping the fast path's publishers are told to ring: what came before is
         * handled now instead. */
        if (rc == 0 && wait != 0)
            rc = fast_ready(loop, n, true);
        if (rc == 0)
            do {
                rc = poll(loop->pfds, n, wait);
            } while (rc < 0 && errno == EINTR && !pending_signal);
        fast_awake(loop);
        if (start && rc >= 0 && fast_path(loop))
            fast_waited(loop, n, start);
    }
    if (rc < 0 && errno != EINTR) {
        int err = errno;
        marie_error("poll: %s", strerror(err));
        return marie_fail(err);
    }
    loop->fds_changed = 0;
    for (size_t i = 0; rc > 0 && i < n && !loop->quit; i++) {
        if (!loop->pfds[i].revents)
            continue;
        /* A callback may add or remove fds: look the watch up again by fd. */
        int fd = loop->pfds[i].fd;
        short revents = loop->pfds[i].revents;
        if (loop->clock == MARIE_CLOCK_SIM && loop->lcms && !is_lcm_fd(loop, fd))
            catch_up_clock(loop);
        for (size_t k = 0; k < loop->nfds; k++) {
            if (loop->fds[k].fd == fd) {
                fd_watch_t w = loop->fds[k];
                w.cb(loop, fd, revents, w.user);
                ran++;
                break;
            }
        }
    }
    if (!loop->quit)
        ran += run_timers(loop);
    if (ran && loop->spin_us)
        loop->last_active = marie_mono_us();
    return ran;
}

int marie_loop_run(marie_loop_t *loop)
{
    while (!loop->quit) {
        int rc = marie_loop_run_once(loop, -1);
        if (rc < 0)
            return rc;
    }
    return 0;
}

int marie_loop_run_until(marie_loop_t *loop, int timeout_ms, marie_loop_cond_t done, void *user)
{
    int64_t end = marie_mono_us() + (int64_t)(timeout_ms > 0 ? timeout_ms : 0) * 1000;
    do {
        if (done && done(user))
            return 1;
        if (loop->quit)
            return 0;
        int64_t left = end - marie_mono_us();
        int rc = marie_loop_run_once(loop, timeout_ms < 0 ? -1 : left > 0 ? (int)((left + 999) / 1000) : 0);
        if (rc < 0)
            return rc;
    } while (timeout_ms < 0 || marie_mono_us() < end);
    return done && done(user) ? 1 : 0;
}

void marie_loop_quit(marie_loop_t *loop) { loop->quit = 1; }
int marie_loop_quitting(const marie_loop_t *loop) { return loop->quit; }

static void on_signal(int signo)
{
    pending_signal = signo;
    if (signal_wake_fd >= 0) {
        char c = 1;
        ssize_t r = write(signal_wake_fd, &c, 1);
        (void)r;
    }
}

static void on_sigpipe_readable(marie_loop_t *loop, int fd, short revents, void *user)
{
    char buf[64];
    while (read(fd, buf, sizeof buf) > 0)
        ;
    int signo = pending_signal;
    pending_signal = 0;
    if (signo && loop->on_signal)
        loop->on_signal(loop, signo, loop->signal_user);
}

int marie_loop_catch_signals(marie_loop_t *loop, marie_signal_cb_t cb, void *user)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sigemptyset(&sa.sa_mask);
    if (!cb) {
        sa.sa_handler = SIG_DFL;
        sigaction(SIGTERM, &sa, NULL);
        sigaction(SIGINT, &sa, NULL);
        if (loop->sigpipe[0] >= 0) {
            marie_loop_remove_fd(loop, loop->sigpipe[0]);
            signal_wake_fd = -1;
            close(loop->sigpipe[0]);
            close(loop->sigpipe[1]);
            loop->sigpipe[0] = loop->sigpipe[1] = -1;
        }
        loop->on_signal = NULL;
        return 0;
    }
    if (loop->sigpipe[0] < 0) {
        if (pipe2(loop->sigpipe, O_NONBLOCK | O_CLOEXEC) < 0)
            return -1;
        int rc = marie_loop_add_fd(loop, loop->sigpipe[0], POLLIN, on_sigpipe_readable, NULL);
        if (rc < 0)
            return rc;
    }
    loop->on_signal = cb;
    loop->signal_user = user;
    signal_wake_fd = loop->sigpipe[1];
    sa.sa_handler = on_signal;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);
    return 0;
}

static void on_sigfd_readable(marie_loop_t *loop, int fd, short revents, void *user)
{
    struct signalfd_siginfo si;
    while (read(fd, &si, sizeof si) == (ssize_t)sizeof si)
        loop->on_watched(loop, (int)si.ssi_signo, loop->watched_user);
}

int marie_loop_watch_signals(marie_loop_t *loop, const int *signos, int n, marie_signal_cb_t cb, void *user)
{
    if (loop->sigfd >= 0 || !cb || n <= 0)
        return marie_fail(EINVAL);
    sigset_t set;
    sigemptyset(&set);
    for (int i = 0; i < n; i++)
        if (sigaddset(&set, signos[i]) < 0)
            return -1;
    if (sigprocmask(SIG_BLOCK, &set, NULL) < 0)
        return -1;
    int fd = signalfd(-1, &set, SFD_NONBLOCK | SFD_CLOEXEC);
    if (fd < 0)
        return -1;
    int rc = marie_loop_add_fd(loop, fd, POLLIN, on_sigfd_readable, NULL);
    if (rc < 0) {
        MARIE_KEEP_ERRNO(close(fd));
        return -1;
    }
    loop->sigfd = fd;
    loop->on_watched = cb;
    loop->watched_user = user;
    return 0;
}
