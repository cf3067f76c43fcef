/* test_loop: fd callbacks, fixed-rate timers with overrun accounting, sim clock, signals. */
#include <errno.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <poll.h>
#include <pthread.h>
#include <pty.h>
#include <string.h>
#include <time.h>
#include <sys/resource.h>
#include <termios.h>
#include <unistd.h>

#include <cmocka.h>

#include "core/bus/bus.h"
#include "core/loop.h"
#include "core/time.h"
#include "tests/fails.h"

typedef struct {
    int fired;
    int64_t overruns;
    int64_t last_now;
} tick_state_t;

static void on_tick(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    tick_state_t *s = user;
    s->fired++;
    s->overruns += overruns;
    s->last_now = marie_loop_now(loop);
}

static void sim_timers_follow_simulated_time(void **state)
{
    marie_loop_t *loop = marie_loop_create();
    marie_loop_set_clock(loop, MARIE_CLOCK_SIM);
    tick_state_t s = {0};
    marie_timer_t *t = marie_loop_add_timer(loop, 100000, on_tick, &s);  /* 10 Hz */
    assert_non_null(t);
    /* Wall time passing does nothing while the simulated clock stands still. */
    marie_loop_run_once(loop, 30);
    assert_int_equal(s.fired, 0);
    /* One simulated second in 10 ms steps: exactly ten ticks, none late. */
    for (int64_t us = 10000; us <= 1000000; us += 10000) {
        marie_loop_set_sim_time(loop, us);
        marie_loop_run_once(loop, 0);
    }
    assert_int_equal(s.fired, 10);
    assert_int_equal(s.overruns, 0);
    assert_int_equal(marie_loop_now(loop), 1000000);
    /* Deadlines 1.1, 1.2 and 1.3 s all pass in one jump: one late call reporting the two
     * periods it skipped, not a burst of three. */
    marie_loop_set_sim_time(loop, 1350000);
    marie_loop_run_once(loop, 0);
    assert_int_equal(s.fired, 11);
    assert_int_equal(s.overruns, 2);
    assert_int_equal(marie_timer_overruns(t), 2);
    /* The next deadline keeps the original phase. */
    marie_loop_set_sim_time(loop, 1399999);
    marie_loop_run_once(loop, 0);
    assert_int_equal(s.fired, 11);
    marie_loop_set_sim_time(loop, 1400000);
    marie_loop_run_once(loop, 0);
    assert_int_equal(s.fired, 12);
    /* Time never runs backwards. */
    marie_loop_set_sim_time(loop, 5);
    assert_int_equal(marie_loop_now(loop), 1400000);
    marie_loop_destroy(loop);
}

static void wall_timer_ticks_and_counts_a_slow_callback(void **state)
{
    marie_loop_t *loop = marie_loop_create();
    tick_state_t s = {0};
    marie_timer_t *t = marie_loop_add_timer(loop, 5000, on_tick, &s);
    int64_t start = marie_mono_us();
    while (s.fired < 3 && marie_mono_us() - start < 5000000)
        marie_loop_run_once(loop, -1);
    assert_int_equal(s.fired, 3);
    /* Block for more than four periods: the next call reports them as overruns. */
    usleep(25000);
    int before = s.fired;
    marie_loop_run_once(loop, -1);
    assert_int_equal(s.fired, before + 1);
    assert_true(s.overruns >= 4);
    marie_loop_remove_timer(loop, t);
    marie_loop_destroy(loop);
}

typedef struct {
    int reads;
    marie_loop_t *loop;
} fd_state_t;

static void on_readable(marie_loop_t *loop, int fd, short revents, void *user)
{
    fd_state_t *s = user;
    char buf[16];
    assert_true(revents & POLLIN);
    assert_true(read(fd, buf, sizeof buf) > 0);
    s->reads++;
    /* Removing ourselves from inside the callback is allowed. */
    marie_loop_remove_fd(loop, fd);
}

static void fd_callbacks_and_removal_inside_them(void **state)
{
    marie_loop_t *loop = marie_loop_create();
    int p[2];
    assert_int_equal(pipe(p), 0);
    fd_state_t s = {0, loop};
    assert_int_equal(marie_loop_add_fd(loop, p[0], POLLIN, on_readable, &s), 0);
    assert_fails(marie_loop_add_fd(loop, p[0], POLLIN, on_readable, &s), EEXIST);
    assert_int_equal(write(p[1], "x", 1), 1);
    marie_loop_run_once(loop, 1000);
    assert_int_equal(s.reads, 1);
    assert_int_equal(write(p[1], "y", 1), 1);
    assert_int_equal(marie_loop_run_once(loop, 20), 0);
    assert_int_equal(s.reads, 1);
    assert_fails(marie_loop_remove_fd(loop, p[0]), ENOENT);
    close(p[0]);
    close(p[1]);
    marie_loop_destroy(loop);
}

static void on_ready(marie_loop_t *loop, int fd, short revents, void *user)
{
    *(short *)user = revents;
}

/* A writer that waits for room: POLLOUT only while asked for, POLLIN meanwhile untouched. */
static void events_change_between_rounds(void **state)
{
    marie_loop_t *loop = marie_loop_create();
    int p[2];
    assert_int_equal(pipe(p), 0);
    short got = 0;
    assert_int_equal(marie_loop_add_fd(loop, p[1], 0, on_ready, &got), 0);
    assert_int_equal(marie_loop_run_once(loop, 20), 0);
    assert_int_equal(marie_loop_set_events(loop, p[1], POLLOUT), 0);
    assert_int_equal(marie_loop_run_once(loop, 1000), 1);
    assert_true(got & POLLOUT);
    got = 0;
    assert_int_equal(marie_loop_set_events(loop, p[1], 0), 0);
    assert_int_equal(marie_loop_run_once(loop, 20), 0);
    assert_int_equal(got, 0);
    assert_fails(marie_loop_set_events(loop, p[0], POLLIN), ENOENT);
    close(p[0]);
    close(p[1]);
    marie_loop_destroy(loop);
}

static void on_oneshot(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    (*(int *)user)++;
    marie_loop_quit(loop);
}

static void oneshot_fires_once_and_quit_stops_run(void **state)
{
    marie_loop_t *loop = marie_loop_create();
    int n = 0;
    assert_non_null(marie_loop_add_oneshot(loop, 2000, on_oneshot, &n));
    assert_int_equal(marie_loop_run(loop), 0);
    assert_int_equal(n, 1);
    assert_true(marie_loop_quitting(loop));
    marie_loop_destroy(loop);
}

static void wall_timers_run_while_sim_time_stands(void **state)
{
    marie_loop_t *loop = marie_loop_create();
    marie_loop_set_clock(loop, MARIE_CLOCK_SIM);
    tick_state_t s = {0};
    assert_non_null(marie_loop_add_wall_timer(loop, 2000, on_tick, &s));
    int64_t start = marie_mono_us();
    while (s.fired < 2 && marie_mono_us() - start < 5000000)
        marie_loop_run_once(loop, -1);
    assert_int_equal(s.fired, 2);
    marie_loop_destroy(loop);
}

static void on_sig(marie_loop_t *loop, int signo, void *user)
{
    *(int *)user = signo;
    marie_loop_quit(loop);
}

static void sigterm_reaches_the_loop_as_a_callback(void **state)
{
    marie_loop_t *loop = marie_loop_create();
    int got = 0;
    assert_int_equal(marie_loop_catch_signals(loop, on_sig, &got), 0);
    kill(getpid(), SIGTERM);
    assert_int_equal(marie_loop_run(loop), 0);
    assert_int_equal(got, SIGTERM);
    marie_loop_catch_signals(loop, NULL, NULL);
    marie_loop_destroy(loop);
}

static void on_set_flag(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    *(int *)user = 1;
}

static int flag_set(void *user) { return *(int *)user; }

static void run_until_returns_when_the_condition_holds(void **state)
{
    marie_loop_t *loop = marie_loop_create();
    int flag = 0;
    assert_non_null(marie_loop_add_oneshot(loop, 20000, on_set_flag, &flag));
    int64_t start = marie_mono_us();
    assert_int_equal(marie_loop_run_until(loop, 5000, flag_set, &flag), 1);
    int64_t took = marie_mono_us() - start;
    assert_true(took >= 20000);
    assert_true(took < 4000000);    /* not at the deadline */
    /* Already true: no round is run, even with no deadline. */
    assert_int_equal(marie_loop_run_until(loop, -1, flag_set, &flag), 1);
    marie_loop_destroy(loop);
}

static void on_pipe_readable(marie_loop_t *loop, int fd, short revents, void *user)
{
    char c;
    if (read(fd, &c, 1) == 1)
        (*(int *)user)++;
}

static void run_until_stops_at_the_deadline_and_serves_fds_meanwhile(void **state)
{
    marie_loop_t *loop = marie_loop_create();
    int p[2], got = 0, never = 0;
    assert_int_equal(pipe(p), 0);
    assert_int_equal(marie_loop_add_fd(loop, p[0], POLLIN, on_pipe_readable, &got), 0);
    assert_int_equal(write(p[1], "x", 1), 1);
    int64_t start = marie_mono_us();
    assert_int_equal(marie_loop_run_until(loop, 100, flag_set, &never), 0);
    int64_t took = marie_mono_us() - start;
    assert_true(took >= 100000);
    assert_true(took < 3000000);
    assert_int_equal(got, 1);
    /* 0 ms: one round of what is ready, no waiting. */
    assert_int_equal(write(p[1], "y", 1), 1);
    start = marie_mono_us();
    assert_int_equal(marie_loop_run_until(loop, 0, NULL, NULL), 0);
    assert_true(marie_mono_us() - start < 50000);
    assert_int_equal(got, 2);
    marie_loop_destroy(loop);
    close(p[0]);
    close(p[1]);
}

static void run_until_returns_on_quit(void **state)
{
    marie_loop_t *loop = marie_loop_create();
    int n = 0, never = 0;
    assert_non_null(marie_loop_add_oneshot(loop, 2000, on_oneshot, &n));    /* quits */
    int64_t start = marie_mono_us();
    assert_int_equal(marie_loop_run_until(loop, -1, flag_set, &never), 0);
    assert_true(marie_mono_us() - start < 3000000);
    assert_int_equal(n, 1);
    marie_loop_destroy(loop);
}

static int usr_seen[3];
static void on_usr(marie_loop_t *loop, int signo, void *user)
{
    usr_seen[signo == SIGUSR1 ? 1 : signo == SIGUSR2 ? 2 : 0]++;
}

/* SIGUSR1/SIGUSR2 watched: each arrives as a callback from the loop, none kills the process. */
static void watched_signals_arrive_from_the_loop(void **state)
{
    marie_loop_t *loop = marie_loop_create();
    assert_int_equal(marie_loop_watch_signals(loop, (const int[]){ SIGUSR1, SIGUSR2 }, 2, on_usr, NULL), 0);
    assert_fails(marie_loop_watch_signals(loop, (const int[]){ SIGHUP }, 1, on_usr, NULL), EINVAL);
    kill(getpid(), SIGUSR1);
    kill(getpid(), SIGUSR2);
    for (int i = 0; i < 10 && usr_seen[1] + usr_seen[2] < 2; i++)
        marie_loop_run_once(loop, 100);
    assert_int_equal(usr_seen[1], 1);
    assert_int_equal(usr_seen[2], 1);
    assert_int_equal(usr_seen[0], 0);
    marie_loop_destroy(loop);
}

/* Bytes written to a pty's master are counted on the slave at once, though the kernel pushes
 * them to it from a worker thread (FIONREAD alone read 0 right after most writes). */
static void fd_unread_counts_a_pty_write_at_once(void **state)
{
    int m, s;
    assert_int_equal(openpty(&m, &s, NULL, NULL, NULL), 0);
    struct termios t;
    assert_int_equal(tcgetattr(s, &t), 0);
    cfmakeraw(&t);
    assert_int_equal(tcsetattr(s, TCSANOW, &t), 0);
    char buf[370];
    memset(buf, 'x', sizeof buf);
    for (int i = 0; i < 200; i++) {
        assert_int_equal(write(m, buf, sizeof buf), (ssize_t)sizeof buf);
        assert_int_equal(marie_fd_unread(s), (int)sizeof buf);
        assert_int_equal(read(s, buf, sizeof buf), (ssize_t)sizeof buf);
        assert_int_equal(marie_fd_unread(s), 0);
    }
    assert_int_equal(marie_fd_unread(-1), 0);
    close(m);
    close(s);
}

/* ---- under the simulated clock, a device's input sees the newest clock already sent ---- */

typedef struct {
    marie_loop_t *loop;
    int64_t seen;       /* the loop's time when the device's byte was read; -1: not yet */
} device_clock_t;

static void on_clock_msg(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    int64_t us;
    memcpy(&us, rb->data, sizeof us);
    marie_loop_set_sim_time(user, us);
}

static void on_device_byte(marie_loop_t *loop, int fd, short revents, void *user)
{
    device_clock_t *d = user;
    char c;
    if (read(fd, &c, 1) == 1)
        d->seen = marie_loop_now(loop);
}

static void device_input_is_read_at_the_newest_clock_sent_before_it(void **state)
{
    marie_loop_t *loop = marie_loop_create();
    marie_loop_set_clock(loop, MARIE_CLOCK_SIM);
    lcm_t *bus = marie_bus_create("udpm://239.255.76.67:7667?ttl=0");
    assert_non_null(bus);
    assert_non_null(marie_bus_subscribe(bus, "TEST_CLOCK", on_clock_msg, loop));
    assert_int_equal(marie_loop_add_bus(loop, bus, 1), 0);     /* one message a round */
    int p[2];
    assert_int_equal(pipe(p), 0);
    device_clock_t d = {loop, -1};
    assert_int_equal(marie_loop_add_fd(loop, p[0], POLLIN, on_device_byte, &d), 0);
    /* As the simulator does: the clock ticks (the last one the instant of the device's
     * output), then the output; the reader was busy meanwhile and finds all of it queued. */
    for (int64_t us = 10000; us <= 50000; us += 10000)
        assert_int_equal(marie_bus_publish(bus, "TEST_CLOCK", &us, sizeof us), 0);
    assert_int_equal(write(p[1], "x", 1), 1);
    for (int i = 0; i < 10 && d.seen < 0; i++)
        marie_loop_run_once(loop, 1000);
    assert_int_equal(d.seen, 50000);
    marie_loop_remove_fd(loop, p[0]);
    marie_loop_remove_bus(loop, bus);
    marie_bus_destroy(bus);
    close(p[0]);
    close(p[1]);
    marie_loop_destroy(loop);
}

/* ---- spinning ---- */

/* Times this thread has slept (given up its CPU waiting): a round that spins does not. Being
 * preempted or yielding does not count, so other work on the machine cannot change it. */
static long thread_sleeps(void)
{
    struct rusage u;
    getrusage(RUSAGE_THREAD, &u);
    return u.ru_nvcsw;
}

static void on_byte(marie_loop_t *loop, int fd, short revents, void *user)
{
    char c;
    if (read(fd, &c, 1) == 1)
        (*(int *)user)++;
}

/* A loop spinning spin_us on the given clock, watching pipe p (a byte read counts in *got),
 * right after a piece of work: one byte read. */
static marie_loop_t *spinning_after_work(int64_t spin_us, marie_clock_kind_t clock, int p[2], int *got)
{
    marie_loop_t *loop = marie_loop_create();
    marie_loop_set_clock(loop, clock);
    marie_loop_set_spin(loop, spin_us);
    assert_int_equal(marie_loop_spin(loop), spin_us);
    assert_int_equal(pipe(p), 0);
    marie_loop_add_fd(loop, p[0], POLLIN, on_byte, got);
    assert_int_equal(write(p[1], "x", 1), 1);
    assert_int_equal(marie_loop_run_once(loop, 100), 1);
    return loop;
}

static void *write_later(void *arg)
{
    usleep(10000);
    if (write(*(int *)arg, "y", 1) != 1)
        return arg;
    return NULL;
}

/* After work a spinning loop keeps its CPU for the window: a byte written 10 ms into it is read
 * without the thread ever sleeping. Idle, it sleeps as any loop; on the simulator's clock it
 * never spins. */
static void spinning_keeps_the_cpu_after_work_only(void **state)
{
    for (int sim = 0; sim < 2; sim++) {
        int p[2], got = 0;
        /* 300 ms: far longer than the writer takes, even beside other work */
        marie_loop_t *loop = spinning_after_work(300000, sim ? MARIE_CLOCK_SIM : MARIE_CLOCK_WALL, p, &got);
        pthread_t th;
        assert_int_equal(pthread_create(&th, NULL, write_later, &p[1]), 0);
        long slept = thread_sleeps();
        assert_int_equal(marie_loop_run_once(loop, 1000), 1);
        slept = thread_sleeps() - slept;
        pthread_join(th, NULL);
        assert_int_equal(got, 2);
        if (sim)
            assert_true(slept >= 1);
        else
            assert_int_equal(slept, 0);
        /* Idle past the window: the next round sleeps. */
        usleep(350000);
        slept = thread_sleeps();
        assert_int_equal(marie_loop_run_once(loop, 20), 0);
        assert_true(thread_sleeps() - slept >= 1);
        marie_loop_destroy(loop);
        close(p[0]);
        close(p[1]);
    }
}

/* The window never holds up what the round waits for: input that comes meanwhile, a timer,
 * the round's own timeout. */
static void spinning_keeps_deadlines_and_reads_what_comes(void **state)
{
    int p[2], got = 0;
    /* 300 ms: longer than any wait below */
    marie_loop_t *loop = spinning_after_work(300000, MARIE_CLOCK_WALL, p, &got);
    /* A byte written 10 ms into the window is read then. */
    pthread_t th;
    assert_int_equal(pthread_create(&th, NULL, write_later, &p[1]), 0);
    int64_t t0 = marie_mono_us();
    assert_int_equal(marie_loop_run_once(loop, 1000), 1);
    assert_int_equal(got, 2);
    assert_true(marie_mono_us() - t0 < 200000);
    pthread_join(th, NULL);
    /* A timer due in 20 ms fires at its time. */
    tick_state_t s = {0};
    marie_loop_add_oneshot(loop, 20000, on_tick, &s);
    t0 = marie_mono_us();
    while (!s.fired && marie_mono_us() - t0 < 1000000)
        marie_loop_run_once(loop, 1000);
    assert_int_equal(s.fired, 1);
    assert_true(marie_mono_us() - t0 < 200000);
    /* The round's own timeout (100 ms) ends the window, and the round: spinning and sleeping
     * together wait that long, not twice. */
    t0 = marie_mono_us();
    assert_int_equal(marie_loop_run_once(loop, 100), 0);
    int64_t waited = marie_mono_us() - t0;
    assert_true(waited >= 95000);
    assert_true(waited < 170000);
    marie_loop_destroy(loop);
    close(p[0]);
    close(p[1]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(sim_timers_follow_simulated_time),
        cmocka_unit_test(wall_timer_ticks_and_counts_a_slow_callback),
        cmocka_unit_test(fd_callbacks_and_removal_inside_them),
        cmocka_unit_test(events_change_between_rounds),
        cmocka_unit_test(oneshot_fires_once_and_quit_stops_run),
        cmocka_unit_test(wall_timers_run_while_sim_time_stands),
        cmocka_unit_test(sigterm_reaches_the_loop_as_a_callback),
        cmocka_unit_test(run_until_returns_when_the_condition_holds),
        cmocka_unit_test(run_until_stops_at_the_deadline_and_serves_fds_meanwhile),
        cmocka_unit_test(run_until_returns_on_quit),
        cmocka_unit_test(watched_signals_arrive_from_the_loop),
        cmocka_unit_test(fd_unread_counts_a_pty_write_at_once),
        cmocka_unit_test(device_input_is_read_at_the_newest_clock_sent_before_it),
        cmocka_unit_test(spinning_keeps_the_cpu_after_work_only),
        cmocka_unit_test(spinning_keeps_deadlines_and_reads_what_comes),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
