/* marie-test-comp: a component for the manager tests that can be told to hang (SIGUSR1),
 * crash (SIGUSR2), print, exit, burn CPU, leak memory or hold files open, and that records when
 * it started. */
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <time.h>
#include <unistd.h>

#include "core/component.h"

/* A hang (SIGUSR1): at once, in the handler, so the loop stops between two heartbeats and not
 * at its next 10 Hz tick (which left it beating up to 100 ms after the signal). The process
 * stays alive; what the loop would do on a signal (SIGTERM) is never done. */
static void on_usr1(int s)
{
    for (;;)
        pause();
}

/* A crash (SIGUSR2). */
static void on_usr2(int s) { abort(); }

static void trace(const char *what)
{
    const char *path = getenv("MARIE_TEST_TRACE");
    if (!path || !*path)
        return;
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    FILE *f = fopen(path, "a");
    if (!f)
        return;
    const char *name = getenv("MARIE_NAME");
    fprintf(f, "%lld %s %s %d\n", (long long)ts.tv_sec * 1000000 + ts.tv_nsec / 1000, name ? name : "?", what,
            (int)getpid());
    fclose(f);
}

static int64_t cpu_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (int64_t)ts.tv_sec * 1000000 + ts.tv_nsec / 1000;
}

static void tick(marie_component_t *c, int64_t overruns)
{
    double hz = marie_param_double(c, "print_hz");
    if (hz > 0) {
        static int64_t n;
        printf("line %lld from %s\n", (long long)++n, marie_component_name(c));
        if (n % 5 == 0)
            fprintf(stderr, "warning %lld from %s\n", (long long)n, marie_component_name(c));
        fflush(stdout);
    }
    /* a CPU load: this fraction of each 100 ms tick, counted in CPU time so that a machine
     * busy with other work stretches the spin instead of shrinking the load */
    double busy = marie_param_double(c, "busy");
    if (busy > 0) {
        int64_t until = cpu_us() + (int64_t)(busy * 100000);
        while (cpu_us() < until)
            ;
    }
    /* a leak: memory taken and written (so it is resident) at each tick, never given back */
    double leak = marie_param_double(c, "leak_mb_s");
    static void *volatile kept;                 /* a chain of the blocks: none is ever unreachable */
    if (leak > 0) {
        size_t n = (size_t)(leak * 1e5);       /* a tenth of a second's worth, in bytes */
        void **p = n >= sizeof *p ? malloc(n) : NULL;
        if (p) {
            memset(p, 0x5a, n);
            *p = kept;
            kept = p;
        }
    }
    double exit_after = marie_param_double(c, "exit_after_s");
    static int64_t started;
    int64_t now = marie_mono_us();
    if (!started)
        started = now;
    if (exit_after > 0 && now - started > (int64_t)(exit_after * 1e6))
        exit((int)marie_param_int(c, "exit_code"));
}

static int on_init(marie_component_t *c)
{
    int64_t ms = marie_param_int(c, "init_delay_ms");
    if (ms > 0)
        usleep((useconds_t)(ms * 1000));
    double hz = marie_param_double(c, "print_hz");
    marie_component_every(c, hz > 10 ? hz : 10, tick);   /* busy assumes 10 Hz */
    return 0;
}

static int on_start(marie_component_t *c)
{
    trace("running");
    /* files held open (a leak of descriptors, or a component that needs many) */
    for (int64_t i = 0, n = marie_param_int(c, "open_files"); i < n; i++)
        if (open("/dev/null", O_RDONLY) < 0) {
            fprintf(stderr, "open_files: only %lld opened: %s\n", (long long)i, strerror(errno));
            break;
        }
    return 0;
}

static const marie_param_spec_t params[] = {
    {"init_delay_ms", MARIE_PARAM_INT, "0", "sleep this long in init (slow start)"},
    {"print_hz", MARIE_PARAM_DOUBLE, "0", "print a line on stdout this often"},
    {"exit_after_s", MARIE_PARAM_DOUBLE, "0", "exit after this long (0: never)"},
    {"exit_code", MARIE_PARAM_INT, "1", "status for exit_after_s"},
    {"busy", MARIE_PARAM_DOUBLE, "0", "fraction of one core to burn (a CPU-hungry component)"},
    {"leak_mb_s", MARIE_PARAM_DOUBLE, "0", "MB of memory taken, written and kept each second (a leak)"},
    {"open_files", MARIE_PARAM_INT, "0", "files opened at start and held"},
    {NULL, 0, NULL, NULL},
};

static const marie_port_spec_t ports[] = {{NULL, NULL, 0, 0, NULL}};

static const marie_component_def_t def = {
    .kind = "test_comp", .ports = ports, .params = params, .on_init = on_init, .on_start = on_start,
};

/* the end of a clean quit (SIGTERM, marie down), so a test can see the order of stops */
static void on_exit_trace(void) { trace("exit"); }

/* A program that computes before it joins the bus and beats (an interpreter and its imports, a
 * map loaded before the component is made): MARIE_TEST_START_BUSY_MS, by the clock. */
static void start_busy(void)
{
    const char *ms = getenv("MARIE_TEST_START_BUSY_MS");
    int64_t until = marie_mono_us() + (ms ? atoll(ms) : 0) * 1000;
    while (marie_mono_us() < until)
        ;
}

/* A program that starts a process of its own as it starts (MARIE_TEST_START_CHILD): the child
 * writes "child" to the trace and waits, gone with the component. */
static void start_child(void)
{
    if (!getenv("MARIE_TEST_START_CHILD") || fork() != 0)
        return;
    prctl(PR_SET_PDEATHSIG, SIGKILL);
    trace("child");
    for (;;)
        pause();
}

int main(int argc, char **argv)
{
    trace("exec");
    start_child();
    start_busy();
    atexit(on_exit_trace);
    struct sigaction sa = {.sa_handler = on_usr1};
    sigaction(SIGUSR1, &sa, NULL);
    sa.sa_handler = on_usr2;
    sigaction(SIGUSR2, &sa, NULL);
    return marie_main(&def, argc, argv, NULL);
}
