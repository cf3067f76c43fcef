/* test_local: the same-host fast path (`kind: local`): messages between processes whole and in
 * order without LCM carrying them, a notice a second for lcm-spy, late publishers and
 * subscribers, slow readers, another host over LCM, a killed publisher, a reader that spins
 * while answers come quickly and sleeps when idle, nothing left behind. */
#include <dirent.h>
#include <errno.h>
#include <sched.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>

#include "core/component.h"
#include "tests/proc.h"

#define N 64
#define BIG 921600

/* What a subscriber saw, in memory a child process shares. */
typedef struct {
    _Atomic int ready, count;
    _Atomic int order[N];           /* sequence numbers in the order they came */
    _Atomic int intact;             /* messages whose bytes were the ones sent */
    _Atomic int64_t last_at;        /* when the last one came (monotonic us) */
    _Atomic int big, in_ring;       /* 900 KB ones, and those whose pixels were in the ring */
} seen_t;

static uint8_t byte_of(int k, int i) { return (uint8_t)(k * 13 + i * 5 + (i >> 9)); }

static void on_image(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    seen_t *s = marie_component_user(c);
    const marie_image_t *m = msg;
    int k = m->row_stride, ok = 1;
    for (int i = 0; i < m->size; i += 997)
        ok &= m->data[i] == byte_of(k, i);
    if (m->size == BIG) {
        atomic_fetch_add(&s->big, 1);
        atomic_fetch_add(&s->in_ring, test_in_ring(m->data, BIG));
        for (int i = 0; i < m->size; i++)     /* every byte, read where the writer put it */
            ok &= m->data[i] == byte_of(k, i);
    }
    int at = atomic_fetch_add(&s->count, 1);
    if (at < N)
        atomic_store(&s->order[at], k);
    atomic_fetch_add(&s->intact, ok);
    atomic_store(&s->last_at, marie_mono_us());
}

static int rx_init(marie_component_t *c)
{
    int rc = marie_port_on_message(marie_port(c, "in"), on_image);
    atomic_store(&((seen_t *)marie_component_user(c))->ready, 1);   /* subscribed */
    return rc;
}

static const marie_port_spec_t rx_ports[] = {{"in", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "T_CAM"}, {0}};
static const marie_port_spec_t tx_ports[] = {{"out", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "T_CAM"}, {0}};
static const marie_component_def_t rx_def = {.kind = "rx", .ports = rx_ports, .on_init = rx_init};
static const marie_component_def_t tx_def = {.kind = "tx", .ports = tx_ports};

static char sysfile[64];

static marie_component_t *make(const marie_component_def_t *def, const char *name, void *user)
{
    char *argv[] = {(char *)def->kind, "--system", sysfile, "--name", (char *)name};
    marie_errors_t e = {0};
    marie_component_t *c = marie_component_create(def, 5, argv, user, &e);
    marie_errors_print(&e, stderr);
    assert_non_null(c);
    const char *why;
    assert_int_equal(marie_component_command(c, MARIE_CMD_INIT, &why), 0);
    assert_int_equal(marie_component_command(c, MARIE_CMD_START, &why), 0);
    return c;
}

static void run(marie_component_t **cs, int n, int ms)
{
    int64_t end = marie_mono_us() + ms * 1000LL;
    while (marie_mono_us() < end)
        for (int i = 0; i < n; i++)
            marie_loop_run_once(marie_component_loop(cs[i]), 1);
}

static void publish(marie_component_t *tx, int k, int size)
{
    static uint8_t *px;
    if (!px)
        px = malloc(BIG);
    for (int i = 0; i < size; i++)
        px[i] = byte_of(k, i);
    marie_image_t img = {.width = 1, .height = size, .row_stride = k, .format = MARIE_IMAGE_T_FORMAT_GRAY8,
                         .size = size, .data = px};
    assert_int_equal(marie_port_publish(marie_port(tx, "out"), &img), 0);
}

/* What lcm-spy sees: the channel whole, and its notices. */
typedef struct {
    int whole, notices;
} spy_t;

static void on_spy(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    spy_t *s = user;
    if (strcmp(ch, "T_CAM") == 0)
        s->whole++;
    else
        s->notices++;
}

static seen_t *shared_seen(void)
{
    seen_t *s = mmap(NULL, sizeof *s, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
    assert_true(s != MAP_FAILED);
    return s;
}

static int ready(void *user) { return atomic_load(&((seen_t *)user)->ready); }
static int all_came(void *user) { return atomic_load(&((seen_t *)user)->count) >= N; }

/* A subscriber in a process of its own, as on a robot: it sleeps in its loop, and the publisher
 * rings its doorbell. */
static void messages_cross_processes_whole_and_in_order_without_lcm(void **state)
{
    seen_t *seen = shared_seen();
    pid_t pid = fork();
    if (pid == 0)
        _exit(marie_main(&rx_def, 5, (char *[]){"rx", "--system", sysfile, "--name", "rx", NULL}, seen));
    lcm_t *spy = lcm_create(marie_default_url());
    spy_t sp = {0};
    lcm_subscribe(spy, "T_CAM(\\.SHM)?", on_spy, &sp);
    marie_component_t *tx = make(&tx_def, "tx", NULL);
    assert_int_equal(marie_loop_run_until(marie_component_loop(tx), 5000, ready, seen), 1);
    /* Each once the one before came: the ring has four slots, and on a loaded machine a reader
     * may wait longer than four messages take (that loss is the slow reader's test). */
    for (int k = 0; k < N - 1; k++) {
        publish(tx, k, k % 4 == 0 ? BIG : 64 + k);
        for (int64_t end = marie_mono_us() + 2000000; atomic_load(&seen->count) <= k && marie_mono_us() < end;)
            marie_loop_run_until(marie_component_loop(tx), 1, NULL, NULL);
    }
    /* The last one to a subscriber asleep: its doorbell wakes it, not its next timer (its
     * heartbeat, up to a second away). */
    marie_loop_run_until(marie_component_loop(tx), 200, NULL, NULL);
    publish(tx, N - 1, 100);
    int64_t sent = marie_mono_us();
    int all = marie_loop_run_until(marie_component_loop(tx), 5000, all_came, seen);
    int64_t late_us = atomic_load(&seen->last_at) - sent;
    while (lcm_handle_timeout(spy, 50) > 0)
        ;
    kill(pid, SIGTERM);
    waitpid(pid, NULL, 0);
    marie_component_destroy(tx);
    lcm_destroy(spy);
    print_message("the last message came %lld us after it was sent; %d came\n", (long long)late_us, atomic_load(&seen->count));
    assert_int_equal(all, 1);
    assert_true(late_us < 300000);
    assert_int_equal(atomic_load(&seen->count), N);
    assert_int_equal(atomic_load(&seen->intact), N);
    for (int k = 0; k < N; k++)
        assert_int_equal(atomic_load(&seen->order[k]), k);
    /* The 900 KB images' pixels were read in their slot, not copied out of it. */
    assert_int_equal(atomic_load(&seen->big), N / 4);
    assert_int_equal(atomic_load(&seen->in_ring), N / 4);
    /* LCM carried no message, and a notice a second at most (lcm-spy's view of the channel). */
    assert_int_equal(sp.whole, 0);
    assert_in_range(sp.notices, 1, 3);
    munmap(seen, sizeof *seen);
}

/* A publisher that comes after the subscriber is read from its first message; a subscriber that
 * comes after a publisher gets what follows its subscription (even before its loop turned), not
 * what was published before. */
static void late_publishers_and_late_subscribers(void **state)
{
    seen_t a = {0}, b = {0};
    marie_component_t *cs[3] = {make(&rx_def, "rx", &a)};
    cs[1] = make(&tx_def, "tx", NULL);
    publish(cs[1], 0, 100);
    publish(cs[1], 1, 100);
    run(cs, 2, 100);
    assert_int_equal(atomic_load(&a.count), 2);
    cs[2] = make(&rx_def, "rx2", &b);
    publish(cs[1], 2, 100);     /* before rx2's loop has turned once: it subscribed already */
    run(cs, 3, 100);
    assert_int_equal(atomic_load(&a.count), 3);
    assert_int_equal(atomic_load(&b.count), 1);
    assert_int_equal(atomic_load(&b.order[0]), 2);
    for (int i = 0; i < 3; i++)
        marie_component_destroy(cs[i]);
}

/* A reader too slow for the ring loses the messages written over, counted, never torn. */
static void a_slow_reader_loses_counted_never_torn(void **state)
{
    seen_t a = {0};
    marie_component_t *cs[2] = {make(&rx_def, "rx", &a), make(&tx_def, "tx", NULL)};
    run(cs, 2, 20);
    for (int k = 0; k < 10; k++)
        publish(cs[1], k, 1000);     /* the reader does not run meanwhile; the ring has 4 slots */
    run(cs, 2, 100);
    int got = atomic_load(&a.count);
    assert_in_range(got, 1, 4);
    assert_int_equal(atomic_load(&a.intact), got);
    assert_int_equal(atomic_load(&a.order[got - 1]), 9);
    marie_component_heartbeat(cs[0]);
    assert_int_equal(marie_component_counter(cs[0], "shm_overwritten"), 10 - got);
    for (int i = 0; i < 2; i++)
        marie_component_destroy(cs[i]);
}

/* A subscriber on another host finds no ring: it sees the notice, asks, and the messages come
 * whole over LCM; this host's subscriber still reads the ring and gets each one once. */
static void another_host_gets_them_over_lcm(void **state)
{
    seen_t here = {0}, far = {0};
    marie_component_t *cs[3] = {make(&rx_def, "rx", &here)};
    setenv("MARIE_SHM_HOST", "far-away", 1);
    cs[1] = make(&rx_def, "far", &far);
    unsetenv("MARIE_SHM_HOST");
    cs[2] = make(&tx_def, "tx", NULL);
    for (int k = 0; k < 30; k++) {
        publish(cs[2], k, k == 29 ? BIG : 200);
        run(cs, 3, 40);
    }
    run(cs, 3, 200);
    assert_int_equal(atomic_load(&here.count), 30);
    assert_int_equal(atomic_load(&here.intact), 30);
    /* The first notice (and the request) take a moment: after them, every message. */
    int got = atomic_load(&far.count);
    assert_in_range(got, 20, 30);
    assert_int_equal(atomic_load(&far.intact), got);
    assert_int_equal(atomic_load(&far.order[got - 1]), 29);
    for (int i = 0; i < 3; i++)
        marie_component_destroy(cs[i]);
}

/* A publisher killed in the middle leaves its ring and its registration; the one that replaces
 * it is read, and the subscriber goes on. */
static void a_killed_publisher_is_replaced(void **state)
{
    seen_t a = {0};
    marie_component_t *cs[2] = {make(&rx_def, "rx", &a)};
    pid_t pid = fork();
    if (pid == 0) {
        marie_component_t *tx = make(&tx_def, "tx", NULL);
        publish(tx, 0, 100);
        publish(tx, 1, 100);
        pause();
    }
    run(cs, 1, 300);
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
    assert_int_equal(atomic_load(&a.count), 2);
    cs[1] = make(&tx_def, "tx", NULL);
    publish(cs[1], 2, 100);
    run(cs, 2, 100);
    assert_int_equal(atomic_load(&a.count), 3);
    assert_int_equal(atomic_load(&a.order[2]), 2);
    for (int i = 0; i < 2; i++)
        marie_component_destroy(cs[i]);
}

/* ---- waiting for the fast path ---- */

/* An echo in a process of its own: each T_PING back on T_PONG at once. */
static void on_ping(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    marie_port_publish(marie_port(c, "out"), msg);
}

static int echo_init(marie_component_t *c) { return marie_port_on_message(marie_port(c, "in"), on_ping); }

static const marie_port_spec_t echo_ports[] = {{"in", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "T_PING"},
                                               {"out", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "T_PONG"},
                                               {0}};
static const marie_port_spec_t pinger_ports[] = {{"out", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "T_PING"},
                                                 {"in", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "T_PONG"},
                                                 {0}};
static const marie_component_def_t echo_def = {.kind = "echo", .ports = echo_ports, .on_init = echo_init};
static const marie_component_def_t pinger_def = {.kind = "pinger", .ports = pinger_ports, .on_init = rx_init};

/* Times this thread has slept (given up its CPU waiting); being preempted does not count, so
 * other work on the machine does not change it. */
static long thread_sleeps(void)
{
    struct rusage u;
    getrusage(RUSAGE_THREAD, &u);
    return u.ru_nvcsw;
}

static int64_t thread_cpu_us(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (int64_t)t.tv_sec * 1000000 + t.tv_nsec / 1000;
}

static int answered(void *user) { return atomic_load(&((seen_t *)user)->count) > 0; }

/* One ping and its answer (2 s at most); every `gap_us` apart. Returns the answers. */
static int ping_pong(marie_component_t *pinger, seen_t *got, int n, int gap_us)
{
    int back = 0;
    for (int k = 0; k < n; k++) {
        if (gap_us)
            marie_loop_run_until(marie_component_loop(pinger), gap_us / 1000, NULL, NULL);
        atomic_store(&got->count, 0);
        publish(pinger, k, 64);
        back += marie_loop_run_until(marie_component_loop(pinger), 2000, answered, got) == 1;
    }
    return back;
}

/* An echo in another process on CPU `theirs`, this process on `ours`, and a pinger that has
 * had its first answer (the echo is up) and 50 more (the loops learn that answers come
 * quickly). The echo's pid. */
static pid_t start_echo(const cpu_set_t *ours, const cpu_set_t *theirs, seen_t *got, marie_component_t **pinger)
{
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) {
        sched_setaffinity(0, sizeof *theirs, theirs);
        _exit(marie_main(&echo_def, 5, (char *[]){"echo", "--system", sysfile, "--name", "echo", NULL}, NULL));
    }
    sched_setaffinity(0, sizeof *ours, ours);
    *pinger = make(&pinger_def, "pinger", got);
    for (int i = 0; i < 500 && !ping_pong(*pinger, got, 1, 10000); i++)
        ;
    ping_pong(*pinger, got, 50, 0);
    return pid;
}

static void stop_echo(pid_t pid, marie_component_t *pinger, const cpu_set_t *all)
{
    kill(pid, SIGTERM);
    waitpid(pid, NULL, 0);
    marie_component_destroy(pinger);
    sched_setaffinity(0, sizeof *all, all);
}

/* A loop whose answers come back quickly looks at its rings for them before it sleeps: in a
 * ping-pong with an echo in another process, most answers are read without the pinger sleeping
 * (the echo, whose pings come as quickly, does the same). An idle reader costs nothing: with
 * answers 20 ms apart every wait sleeps at once, and the loop takes next to no CPU. */
static void a_reader_spins_while_answers_come_quickly_only(void **state)
{
    /* Each on a CPU of its own, as a robot's busy components are on a computer with cores to
     * spare: woken onto one CPU, two processes that answer each other take turns on it, and the
     * loop sleeps rather than spin (the peer would wait for its CPU). */
    cpu_set_t all, cpus[2];
    assert_int_equal(sched_getaffinity(0, sizeof all, &all), 0);
    int found = 0;
    for (int c = 0; c < CPU_SETSIZE && found < 2; c++)
        if (CPU_ISSET(c, &all)) {
            CPU_ZERO(&cpus[found]);
            CPU_SET(c, &cpus[found++]);
        }
    if (found < 2)
        skip();         /* one CPU: the two take turns on it, and the loop rightly sleeps */
    seen_t got = {0};
    marie_component_t *pinger;
    pid_t pid = start_echo(&cpus[0], &cpus[1], &got, &pinger);
    long slept = thread_sleeps();
    int64_t t0 = marie_mono_us();
    int back = ping_pong(pinger, &got, 400, 0);
    int64_t rtt_ns = (marie_mono_us() - t0) * 1000 / 400;
    slept = thread_sleeps() - slept;
    long idle_slept = thread_sleeps();
    int64_t cpu = thread_cpu_us();
    int idle_back = ping_pong(pinger, &got, 20, 20000);
    cpu = thread_cpu_us() - cpu;
    idle_slept = thread_sleeps() - idle_slept;
    stop_echo(pid, pinger, &all);
    print_message("back to back: %d answers, slept %ld times, %lld ns a round trip; 20 ms apart: %d "
                  "answers, slept %ld times, %lld us of CPU\n", back, slept, (long long)rtt_ns, idle_back,
                  idle_slept, (long long)cpu);
    assert_int_equal(back, 400);
    assert_int_equal(idle_back, 20);
    /* Every answer a wake-up before the loops spun: 400 sleeps or more. */
    assert_true(slept < 200);
    /* Each 20 ms wait sleeps (and each answer may take one more). */
    assert_true(idle_slept >= 20);
    /* 20 rounds of 64 B take well under a millisecond; 50 us of spin each at most adds 1 ms. */
    assert_true(cpu < 20000);
}

/* Two processes that the kernel put on one CPU take turns on it: a loop whose last message came
 * from a writer on its own CPU does not spin for the next (the writer could only answer once the
 * spin ends), it sleeps and is rung. No answer may wait for a ring that never comes: all 400
 * come back, each within its 2 s. bench_rtt measures how fast (`p50_local_one_cpu_*`); the
 * figures are printed: 6-8.5 us a round trip here, 15-16.5 us while the loops spun. */
static void two_on_one_cpu_take_turns_without_spinning(void **state)
{
    cpu_set_t all, one;
    assert_int_equal(sched_getaffinity(0, sizeof all, &all), 0);
    CPU_ZERO(&one);
    for (int c = 0; c < CPU_SETSIZE; c++)
        if (CPU_ISSET(c, &all)) {
            CPU_SET(c, &one);
            break;
        }
    seen_t got = {0};
    marie_component_t *pinger;
    pid_t pid = start_echo(&one, &one, &got, &pinger);
    long slept = thread_sleeps();
    int64_t t0 = marie_mono_us(), cpu = thread_cpu_us();
    int back = ping_pong(pinger, &got, 400, 0);
    int64_t rtt_ns = (marie_mono_us() - t0) * 1000 / 400;
    cpu = thread_cpu_us() - cpu;
    slept = thread_sleeps() - slept;
    stop_echo(pid, pinger, &all);
    print_message("on one CPU: %d answers, slept %ld times, %lld ns a round trip, %lld ns of the pinger's CPU each\n",
                  back, slept, (long long)rtt_ns, (long long)cpu * 1000 / 400);
    assert_int_equal(back, 400);
}

/* Files of this test in /dev/shm: the fast path's doorbells and rings of this process, and the
 * registries of its network namespace. */
static int leftovers(void)
{
    DIR *d = opendir("/dev/shm");
    int n = 0;
    char me[32], link[64], reg[64];
    snprintf(me, sizeof me, ".%d", (int)getpid());
    ssize_t k = readlink("/proc/self/ns/net", link, sizeof link - 1);
    unsigned long ns = 0;
    if (k > 0) {
        link[k] = '\0';
        sscanf(link, "net:[%lu]", &ns);
    }
    snprintf(reg, sizeof reg, "marie-local.%lu.", ns);
    struct dirent *e;
    while (d && (e = readdir(d)))
        if ((strncmp(e->d_name, "marie-bell.", 11) == 0 && strstr(e->d_name, me)) ||
            (strncmp(e->d_name, "marie-shm.T_CAM.", 16) == 0 && strstr(e->d_name, me)) ||
            strncmp(e->d_name, reg, strlen(reg)) == 0) {
            print_message("in /dev/shm: %s\n", e->d_name);
            n++;
        }
    if (d)
        closedir(d);
    return n;
}

static void nothing_is_left_behind(void **state)
{
    seen_t a = {0};
    marie_component_t *cs[2] = {make(&rx_def, "rx", &a), make(&tx_def, "tx", NULL)};
    publish(cs[1], 0, 100);
    run(cs, 2, 50);
    assert_true(leftovers() > 0);
    for (int i = 0; i < 2; i++)
        marie_component_destroy(cs[i]);
    assert_int_equal(leftovers(), 0);
}

int main(void)
{
    marie_log_set_threshold(MARIE_LOG_ERROR);
    snprintf(sysfile, sizeof sysfile, "/tmp/marie-test-local-XXXXXX.yaml");
    if (test_write_temp(sysfile, 5, "system: local\n"
                                    "transports:\n  T_CAM: {kind: local, max_size: 1000000, slots: 4}\n"
                                    "  T_PING: {kind: local, max_size: 4096, slots: 4}\n"
                                    "  T_PONG: {kind: local, max_size: 4096, slots: 4}\n"
                                    "components:\n"
                                    "  tx: {exec: /bin/true}\n  rx: {exec: /bin/true}\n"
                                    "  rx2: {exec: /bin/true}\n  far: {exec: /bin/true}\n"
                                    "  echo: {exec: /bin/true}\n  pinger: {exec: /bin/true}\n") < 0)
        return 1;
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(messages_cross_processes_whole_and_in_order_without_lcm),
        cmocka_unit_test(late_publishers_and_late_subscribers),
        cmocka_unit_test(a_slow_reader_loses_counted_never_torn),
        cmocka_unit_test(another_host_gets_them_over_lcm),
        cmocka_unit_test(a_killed_publisher_is_replaced),
        cmocka_unit_test(a_reader_spins_while_answers_come_quickly_only),
        cmocka_unit_test(two_on_one_cpu_take_turns_without_spinning),
        cmocka_unit_test(nothing_is_left_behind),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    unlink(sysfile);
    return rc;
}
