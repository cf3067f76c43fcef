/* bench_am: marie-am supervision costs: crash-to-respawn latency, heartbeat-loss detection,
 * bring-up of 45 components over 4 managers and on one (on the machine as it is and beside two
 * busy loops of its own, and by managers restarted on their state directory, with the manager's
 * timeline from its log), one component's start from its own entry against the whole file, and
 * the idle CPU and RSS of a manager. BENCH_AM_ONLY=respawn|fast|bringup runs one part,
 * BENCH_AM_KEEP=1 keeps the managers' logs and traces. */
#include <errno.h>
#include <sched.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "bench/bench.h"
#include "core/component.h"
#include "core/file.h"
#include "core/loop.h"
#include "core/time.h"
#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_heartbeat_t.h"
#include "proto/am_proto.h"
#include "core/procstat.h"
#include "core/typeinfo.h"
#include "tests/proc.h"

static char dir[64];
static const char *bin = "build";
static char bin_abs[4096];

static void row(const char *metric, double value, const char *unit)
{
    bench_row("bench_am", metric, value, unit, NAN);
}

/* A manager for host; rt > 0: at that real-time priority (--rt-priority). */
static pid_t spawn_am_rt(const char *host, const char *state, int rt)
{
    char exe[256], log[160], prio[16];
    snprintf(exe, sizeof exe, "%s/bin/marie-am", bin);
    snprintf(log, sizeof log, "%s/%s.log", dir, host);
    snprintf(prio, sizeof prio, "%d", rt);
    pid_t pid = fork();
    if (pid == 0) {
        FILE *f = freopen(log, "a", stderr);
        (void)f;
        if (rt > 0)
            execl(exe, exe, "--host", host, "--state-dir", state, "--rt-priority", prio, (char *)NULL);
        execl(exe, exe, "--host", host, "--state-dir", state, (char *)NULL);
        _exit(127);
    }
    return pid;
}

static pid_t spawn_am(const char *host, const char *state) { return spawn_am_rt(host, state, 0); }

static int run_marie(const char *args)
{
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "%s/bin/marie %s >> %s/marie.log 2>&1", bin, args, dir);
    int st = system(cmd);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static void stop_am(pid_t pid)
{
    kill(pid, SIGTERM);
    for (int i = 0; i < 100; i++) {
        if (waitpid(pid, NULL, WNOHANG) == pid)
            return;
        usleep(50000);
    }
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double pct(double *v, int n, double p)
{
    qsort(v, (size_t)n, sizeof *v, cmp_double);
    int i = (int)(p * (n - 1) + 0.5);
    return v[i];
}

/* The newest "exec" or "running" trace line of a component: time and pid. */
static int last_trace(const char *trace, const char *name, const char *what, int64_t *t, int *pid)
{
    FILE *f = fopen(trace, "r");
    if (!f)
        return -1;
    char line[256], n[64], w[32];
    long long tt;
    int p, found = -1;
    while (fgets(line, sizeof line, f))
        if (sscanf(line, "%lld %63s %31s %d", &tt, n, w, &p) == 4 && strcmp(n, name) == 0 && strcmp(w, what) == 0) {
            *t = tt;
            *pid = p;
            found = 0;
        }
    fclose(f);
    return found;
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    if (f) {
        fputs(text, f);
        fclose(f);
    }
}

/* ---- heartbeat-loss detection ---- */
static int64_t last_hb_us, detect_us;
static int victim_pid;

static void on_hb(const lcm_recv_buf_t *rb, const char *ch, const marie_heartbeat_t *hb, void *u)
{
    if (strcmp(hb->component, "victim") == 0 && hb->pid == victim_pid)
        last_hb_us = marie_mono_us();
}

static void on_hb_raw(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    marie_heartbeat_t hb;
    if (marie_decode_checked(&marie_type_heartbeat_t, rb->data, rb->data_size, &hb) < 0)
        return;
    on_hb(rb, ch, &hb, u);
    marie_heartbeat_t_decode_cleanup(&hb);
}

/* How many "exec" (or "running") trace lines a component has. */
static int count_trace(const char *trace, const char *name, const char *what)
{
    FILE *f = fopen(trace, "r");
    char line[256], n[64], w[32];
    long long tt;
    int p, count = 0;
    while (f && fgets(line, sizeof line, f))
        count += sscanf(line, "%lld %63s %31s %d", &tt, n, w, &p) == 4 && !strcmp(n, name) && !strcmp(w, what);
    if (f)
        fclose(f);
    return count;
}

/* The time stamps above are 0 until taken. */
static int stamped(void *user) { return *(int64_t *)user != 0; }

static void on_event(const lcm_recv_buf_t *rb, const char *ch, const marie_event_t *ev, void *u)
{
    if (strcmp(ev->kind, "not_responding") == 0 && !detect_us)
        detect_us = marie_mono_us();
}

static void bench_respawn_and_hang(void)
{
    char sys[128], state[128], trace[128], text[2048];
    snprintf(sys, sizeof sys, "%s/one.yaml", dir);
    snprintf(state, sizeof state, "%s/one", dir);
    snprintf(trace, sizeof trace, "%s/trace", dir);
    snprintf(text, sizeof text,
             "system: one\nhosts: [b1]\ncomponents:\n  victim:\n    exec: %s/tests/bin/marie-test-comp\n"
             "    host: b1\n    heartbeat_timeout: 1.5\n    stop_timeout: 0.2\n"
             "    restart: {policy: always, backoff_min: 0, backoff_max: 0, stable_after: 0, max_failures: 0}\n",
             bin);
    write_text(sys, text);
    setenv("MARIE_TEST_TRACE", trace, 1);
    pid_t am = spawn_am("b1", state);
    usleep(300000);
    char args[256];
    snprintf(args, sizeof args, "up %s", sys);
    if (run_marie(args) != 0) {
        fprintf(stderr, "bench_am: up failed (see %s/marie.log)\n", dir);
        stop_am(am);
        return;
    }
    enum { N = 40 };
    double lat[N];
    int n = 0;
    for (int i = 0; i < N; i++) {
        int64_t t_run, t_exec;
        int pid, pid2;
        /* wait for the current process to be running */
        int64_t end = marie_mono_us() + 5000000;
        int64_t t_e;
        int pe;
        while (marie_mono_us() < end) {
            if (last_trace(trace, "victim", "running", &t_run, &pid) == 0 &&
                last_trace(trace, "victim", "exec", &t_e, &pe) == 0 && pe == pid)
                break;
            usleep(10000);
        }
        usleep(50000);
        int64_t t_kill = marie_mono_us();
        kill(pid, SIGKILL);
        end = marie_mono_us() + 5000000;
        while (marie_mono_us() < end) {
            if (last_trace(trace, "victim", "exec", &t_exec, &pid2) == 0 && pid2 != pid)
                break;
            usleep(2000);
        }
        if (pid2 != pid && t_exec > t_kill)
            lat[n++] = (double)(t_exec - t_kill) / 1000.0;
    }
    if (n > 0) {
        double copy[N];
        memcpy(copy, lat, sizeof lat);
        row("crash_to_respawn_p50", pct(copy, n, 0.5), "ms");
        row("crash_to_respawn_p99", pct(lat, n, 0.99), "ms");
        row("crash_to_respawn_samples", n, "count");
    }

    /* hang: SIGUSR1 stops the victim's loop; detection = manager's not_responding event */
    lcm_t *lcm = lcm_create(marie_default_url());
    marie_loop_t *loop = marie_loop_create();
    if (!lcm || !loop || marie_loop_add_bus(loop, lcm, 1) < 0) {
        fprintf(stderr, "bench_am: no LCM\n");
        exit(1);
    }
    marie_heartbeat_t_subscribe(lcm, MARIE_CH_HEARTBEAT, on_hb, NULL);
    marie_event_t_subscribe(lcm, MARIE_CH_EVENT, on_event, NULL);
    double det[3], over[3];
    int nd = 0;
    for (int i = 0; i < 3; i++) {
        int64_t t_run;
        int pid;
        int64_t end = marie_mono_us() + 5000000;
        while (marie_mono_us() < end && last_trace(trace, "victim", "running", &t_run, &pid) != 0)
            usleep(10000);
        victim_pid = pid;
        last_hb_us = 0;
        /* see one heartbeat, then hang right after it */
        marie_loop_run_until(loop, 3000, stamped, &last_hb_us);
        kill(pid, SIGUSR1);
        detect_us = 0;
        marie_loop_run_until(loop, 6000, stamped, &detect_us);
        if (detect_us && last_hb_us) {
            det[nd] = (double)(detect_us - last_hb_us) / 1000.0;
            over[nd] = det[nd] - 1500.0;
            nd++;
        }
        /* let the respawn settle */
        int64_t t2;
        int p2 = pid;
        end = marie_mono_us() + 5000000;
        while (marie_mono_us() < end && (last_trace(trace, "victim", "running", &t2, &p2) != 0 || p2 == pid))
            usleep(20000);
    }
    if (nd > 0) {
        row("heartbeat_loss_detection", pct(det, nd, 0.5), "ms");
        row("heartbeat_loss_detection_past_timeout", pct(over, nd, 0.5), "ms");
    }
    marie_loop_destroy(loop);
    lcm_destroy(lcm);
    run_marie("down");
    stop_am(am);
    unsetenv("MARIE_TEST_TRACE");
}

/* Heartbeat loss to restart with a short timeout, beside two busy loops: a component whose
 * entry says heartbeat_timeout: 0.15 and stop_timeout: 0.02 is hung right after a heartbeat,
 * HANGS times; the time from the hang to its replacement's exec, and the restarts nobody
 * caused while it ran 6 s beside the loops. rt > 0: the manager at that real-time priority
 * (rows *_rt_am; none where the kernel refuses it, as in a user namespace: run-bench.sh keeps
 * the user for bench_am). */
#define HANGS 10
static void bench_fast_restart(int rt)
{
    char sys[128], state[128], trace[128], text[1024], name[96];
    const char *sfx = rt > 0 ? "_rt_am" : "";
    snprintf(sys, sizeof sys, "%s/fast.yaml", dir);
    snprintf(state, sizeof state, "%s/fast%d", dir, rt);
    snprintf(trace, sizeof trace, "%s/trace-fast%d", dir, rt);
    snprintf(text, sizeof text,
             "system: fast\nhosts: [b1]\ncomponents:\n  victim:\n    exec: %s/tests/bin/marie-test-comp\n"
             "    host: b1\n    heartbeat_timeout: 0.15\n    stop_timeout: 0.02\n"
             "    restart: {policy: always, backoff_min: 0, backoff_max: 0, stable_after: 0, max_failures: 0}\n",
             bin);
    write_text(sys, text);
    setenv("MARIE_TEST_TRACE", trace, 1);
    pid_t busy[2] = {0};
    pid_t am = spawn_am_rt("b1", state, rt);
    usleep(300000);
    if (rt > 0 && (sched_getscheduler(am) & ~SCHED_RESET_ON_FORK) != SCHED_FIFO) {
        fprintf(stderr, "bench_am: marie-am --rt-priority %d refused here: no *_rt_am rows\n", rt);
        stop_am(am);
        unsetenv("MARIE_TEST_TRACE");
        return;
    }
    char args[256];
    snprintf(args, sizeof args, "up %s", sys);
    lcm_t *lcm = marie_bus_create(marie_default_url());
    marie_loop_t *loop = marie_loop_create();
    if (run_marie(args) != 0 || !lcm || !loop || marie_loop_add_bus(loop, lcm, 1) < 0 || test_busy_start(busy, 2) < 0) {
        fprintf(stderr, "bench_am: the fast system did not come up (see %s/marie.log)\n", dir);
        goto out;
    }
    marie_bus_subscribe(lcm, MARIE_CH_HEARTBEAT, on_hb_raw, NULL);
    int64_t t0;
    int pid0 = 0;
    usleep(500000);
    last_trace(trace, "victim", "exec", &t0, &pid0);
    marie_loop_run_until(loop, 6000, NULL, NULL);       /* 6 s beside the busy loops */
    int restarts = count_trace(trace, "victim", "exec") - 1;
    double lat[HANGS];
    int n = 0;
    for (int i = 0; i < HANGS; i++) {
        int64_t t_run, t_exec;
        int pid, pid2 = 0;
        if (last_trace(trace, "victim", "running", &t_run, &pid) != 0)
            break;
        victim_pid = pid;
        last_hb_us = 0;
        marie_loop_run_until(loop, 3000, stamped, &last_hb_us);     /* right after a heartbeat */
        int64_t t_hang = marie_mono_us();
        kill(pid, SIGUSR1);
        for (int64_t end = t_hang + 3000000; marie_mono_us() < end;) {
            if (last_trace(trace, "victim", "exec", &t_exec, &pid2) == 0 && pid2 != pid)
                break;
            usleep(1000);
        }
        if (pid2 != pid && t_exec > t_hang)
            lat[n++] = (double)(t_exec - t_hang) / 1000.0;
        fprintf(stderr, "bench_am: hang of pid %d at %lld: replaced %.1f ms after\n", pid, (long long)t_hang,
                n ? lat[n - 1] : -1.0);
        for (int64_t end = marie_mono_us() + 3000000; marie_mono_us() < end;)     /* the new one runs */
            if (last_trace(trace, "victim", "running", &t_run, &pid2) == 0 && pid2 != pid)
                break;
    }
    if (n > 0) {
        double copy[HANGS];
        memcpy(copy, lat, sizeof lat);
        snprintf(name, sizeof name, "heartbeat_loss_to_restart_p50_timeout_0.15s_busy%s", sfx);
        row(name, pct(copy, n, 0.5), "ms");
        snprintf(name, sizeof name, "heartbeat_loss_to_restart_max_timeout_0.15s_busy%s", sfx);
        row(name, pct(lat, n, 1.0), "ms");
    }
    snprintf(name, sizeof name, "false_restarts_6s_timeout_0.15s_busy%s", sfx);
    row(name, restarts, "count");
out:
    test_busy_stop(busy, 2);
    marie_loop_destroy(loop);
    marie_bus_destroy(lcm);
    run_marie("down");
    stop_am(am);
    unsetenv("MARIE_TEST_TRACE");
}

/* 45 components: a base on each host, the rest depending on their host's base. */
static void write_45(const char *path, int nhosts)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return;
    fprintf(f, "system: bench45\nhosts: [");
    for (int h = 0; h < nhosts; h++)
        fprintf(f, "%sh%d", h ? ", " : "", h + 1);
    fprintf(f, "]\ncomponents:\n");
    for (int i = 0; i < 45; i++) {
        int h = i % nhosts;
        fprintf(f, "  c%02d:\n    exec: %s/tests/bin/marie-test-comp\n    host: h%d\n    stop_timeout: 1\n", i, bin,
                h + 1);
        if (i >= nhosts)
            fprintf(f, "    depends: [c%02d]\n", h);
    }
    fclose(f);
}

/* A bring-up as marie-am's debug log tells it, in ms of the log's clock (-1: not seen): the
 * order, the first and the last "spawned pid", the last "starting -> running". */
typedef struct {
    long order, first_spawn, last_spawn, last_running;
} timeline_t;

static long log_ms(const char *line, long since)
{
    int h, m, sec, ms;
    if (sscanf(line, "%d:%d:%d.%d", &h, &m, &sec, &ms) != 4)
        return -1;
    long t = ((h * 60L + m) * 60 + sec) * 1000 + ms;
    return since >= 0 && t < since ? t + 86400000L : t;      /* past midnight */
}

static timeline_t read_timeline(const char *log)
{
    timeline_t tl = {-1, -1, -1, -1};
    FILE *f = fopen(log, "r");
    char line[512];
    while (f && fgets(line, sizeof line, f)) {
        long t = log_ms(line, tl.order);
        if (t < 0)
            continue;
        if (strstr(line, "order up from") && tl.order < 0)
            tl.order = t;
        else if (strstr(line, "spawned pid")) {
            if (tl.first_spawn < 0)
                tl.first_spawn = t;
            tl.last_spawn = t;
        } else if (strstr(line, "starting -> running"))
            tl.last_running = t;
    }
    if (f)
        fclose(f);
    return tl;
}

/* One start of a component of the 45-component file (c17, marie-test-comp), from before the
 * fork to its on_start: ms, -1 on failure. spec NULL: it reads the whole file, as before
 * marie-am passed MARIE_SYSTEM_ENTRY. */
static double one_start(const char *sys, const char *spec, const char *trace, double *cpu_ms)
{
    char exe[4200];
    snprintf(exe, sizeof exe, "%s/tests/bin/marie-test-comp", bin);
    unlink(trace);
    int64_t t0 = marie_mono_us();
    pid_t pid = fork();
    if (pid == 0) {
        setenv("MARIE_SYSTEM", sys, 1);
        setenv("MARIE_NAME", "c17", 1);
        setenv("MARIE_HOST", "h1", 1);
        setenv("MARIE_STATE_DIR", dir, 1);
        setenv("MARIE_TEST_TRACE", trace, 1);
        if (spec)
            setenv("MARIE_SYSTEM_ENTRY", spec, 1);
        else
            unsetenv("MARIE_SYSTEM_ENTRY");
        execl(exe, exe, (char *)NULL);
        _exit(127);
    }
    int64_t t = 0;
    int p = 0;
    for (int64_t end = t0 + 5000000; marie_mono_us() < end && last_trace(trace, "c17", "running", &t, &p) != 0;)
        usleep(500);
    kill(pid, SIGKILL);
    struct rusage ru;
    if (wait4(pid, NULL, 0, &ru) == pid)     /* its CPU time until killed (mostly its start) */
        *cpu_ms = (ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) * 1e3 + (ru.ru_utime.tv_usec + ru.ru_stime.tv_usec) / 1e3;
    return p == pid ? (double)(t - t0) / 1000.0 : -1;
}

/* A component's start reading its own entry against reading the whole 45-component file,
 * alternating, in the same run (the ratio is the figure; the times follow the load). */
static void bench_component_start(const char *sys)
{
    marie_errors_t errs = {0};
    marie_system_t *s = marie_system_load(sys, NULL, &errs);
    size_t len;
    char *text = marie_file_read(sys, 1 << 20, &len), spec[96], trace[128];
    snprintf(trace, sizeof trace, "%s/trace-start", dir);
    if (!s || !text || marie_system_entry_spec(s, "c17", marie_text_hash(text, len), spec, sizeof spec) < 0) {
        fprintf(stderr, "bench_am: no entry spec for the 45-component file\n");
        marie_errors_print(&errs, stderr);
        goto out;
    }
    enum { RUNS = 20 };
    double own[RUNS], whole[RUNS], own_cpu[RUNS], whole_cpu[RUNS];
    int n = 0;
    for (int i = 0; i < RUNS; i++) {
        double ca = 0, cb = 0, a = one_start(sys, NULL, trace, &ca), b = one_start(sys, spec, trace, &cb);
        if (a > 0 && b > 0) {
            whole[n] = a;
            whole_cpu[n] = ca;
            own_cpu[n] = cb;
            own[n++] = b;
        }
    }
    if (n > 0) {
        double w = pct(whole, n, 0.5), o = pct(own, n, 0.5);
        bench_row("bench_am", "component_start_p50_45_component_file", o, "ms", w);
        /* CPU time counts what the start does, whatever else runs */
        bench_row("bench_am", "component_start_cpu_p50_45_component_file", pct(own_cpu, n, 0.5), "ms",
                  pct(whole_cpu, n, 0.5));
        fprintf(stderr, "bench_am: one start, own entry %.2f ms, whole file %.2f ms (medians of %d)\n", o, w, n);
    }
out:
    marie_errors_clear(&errs);
    marie_system_destroy(s);
    free(text);
}

/* BRINGUPS bring-ups of the 45 components on one manager, each by a fresh one (*a: the last, left
 * running). Rows bringup_45_*_1_host<sfx>: `marie up` until all 45 run; from the manager's
 * debug log, its first to last spawn (c00, c00 running, the 44 that wait for it), the order to
 * the last spawn (what procman's deputy reports as started: a pid), and the last spawn to the
 * last "running" (the 44 programs' own start-ups, as the manager sees them). warm: each manager
 * starts on the state directory of the one before (a robot's managers restarted: the programs'
 * descriptions cached), after one bring-up that is not counted; else each on a new one, so each
 * checks the programs as a first `up` does. The number of bring-ups that came up. */
#define BRINGUPS 3
static int bringup_1_host(const char *sys, const char *sfx, bool warm, pid_t *a)
{
    char state[128], args[256], log[160], name[96];
    snprintf(log, sizeof log, "%s/h1.log", dir);
    snprintf(args, sizeof args, "up %s --wait-timeout 30", sys);
    double up[BRINGUPS], spawns[BRINGUPS], to_spawn[BRINGUPS], to_run[BRINGUPS];
    int nup = 0, nlog = 0;
    for (int r = warm ? -1 : 0; r < BRINGUPS; r++) {
        if (*a > 0) {
            run_marie("down");
            stop_am(*a);
        }
        snprintf(state, sizeof state, "%s/up%s%d", dir, sfx, warm ? 0 : r);
        write_text(log, "");
        setenv("MARIE_LOG", "debug", 1);
        *a = spawn_am("h1", state);
        unsetenv("MARIE_LOG");
        usleep(300000);
        int64_t u0 = marie_mono_us();
        if (run_marie(args) != 0 || r < 0)
            continue;
        up[nup++] = (double)(marie_mono_us() - u0) / 1000.0;
        fprintf(stderr, "bench_am: marie up (45 components, 1 host%s): %.1f ms\n", sfx, up[nup - 1]);
        timeline_t tl = read_timeline(log);
        if (tl.order >= 0 && tl.first_spawn >= 0 && tl.last_spawn > tl.first_spawn && tl.last_running >= 0) {
            spawns[nlog] = (double)(tl.last_spawn - tl.first_spawn);
            to_spawn[nlog] = (double)(tl.last_spawn - tl.order);
            to_run[nlog++] = (double)(tl.last_running - tl.last_spawn);
        }
    }
    if (nup == BRINGUPS) {
        snprintf(name, sizeof name, "bringup_45_components_1_host%s", sfx);
        row(name, pct(up, nup, 0.5), "ms");
    }
    if (nlog > 0) {
        snprintf(name, sizeof name, "bringup_45_first_to_last_spawn_1_host%s", sfx);
        row(name, pct(spawns, nlog, 0.5), "ms");
        snprintf(name, sizeof name, "bringup_45_order_to_last_spawn_1_host%s", sfx);
        row(name, pct(to_spawn, nlog, 0.5), "ms");
        snprintf(name, sizeof name, "bringup_45_last_spawn_to_all_running_1_host%s", sfx);
        row(name, pct(to_run, nlog, 0.5), "ms");
    }
    return nup;
}

static void bench_bringup_and_idle(void)
{
    char sys[128], state[128], args[256];
    snprintf(sys, sizeof sys, "%s/four.yaml", dir);
    write_45(sys, 4);
    pid_t am[4];
    for (int h = 0; h < 4; h++) {
        char host[16];
        snprintf(host, sizeof host, "h%d", h + 1);
        snprintf(state, sizeof state, "%s/%s", dir, host);
        am[h] = spawn_am(host, state);
    }
    usleep(500000);
    double t[3];
    int n = 0;
    for (int r = 0; r < 3; r++) {
        snprintf(args, sizeof args, "up %s --wait-timeout 30", sys);
        int64_t t0 = marie_mono_us();
        int rc = run_marie(args);
        int64_t t1 = marie_mono_us();
        fprintf(stderr, "bench_am: marie up (45 components, 4 hosts): %.1f ms, exit %d\n", (t1 - t0) / 1e3, rc);
        if (rc == 0)
            t[n++] = (double)(t1 - t0) / 1000.0;
        run_marie("down");
    }
    if (n > 0)
        row("bringup_45_components_4_hosts", pct(t, n, 0.5), "ms");
    for (int h = 0; h < 4; h++)
        stop_am(am[h]);

    /* One manager, three bring-ups of all 45 beside two busy loops of the bench's own, three
     * with the programs' descriptions cached, then three on the machine as it is (the medians),
     * then idle with the last one running. */
    snprintf(sys, sizeof sys, "%s/one45.yaml", dir);
    write_45(sys, 1);
    bench_component_start(sys);
    pid_t busy[2] = {0};
    pid_t a = 0;
    if (test_busy_start(busy, 2) == 0)
        bringup_1_host(sys, "_busy", false, &a);
    test_busy_stop(busy, 2);
    bringup_1_host(sys, "_warm", true, &a);
    if (bringup_1_host(sys, "", false, &a) == BRINGUPS) {
        sleep(2);
        int64_t c0, r0, c1, r1;
        int64_t t0 = marie_mono_us();
        marie_proc_usage(a, &c0, &r0);
        sleep(10);
        marie_proc_usage(a, &c1, &r1);
        int64_t t1 = marie_mono_us();
        row("am_idle_cpu_45_components", 100.0 * (double)(c1 - c0) / (double)(t1 - t0), "%core");
        row("am_idle_rss_45_components", (double)r1 / (1 << 20), "MiB");
        row("am_idle_rss_anon_45_components", (double)marie_proc_field_bytes(a, "status", "RssAnon") / (1 << 20), "MiB");
        /* shared library pages divided among the processes that map them */
        row("am_idle_pss_45_components", (double)marie_proc_field_bytes(a, "smaps_rollup", "Pss") / (1 << 20), "MiB");
    } else {
        fprintf(stderr, "bench_am: 45-component up failed\n");
    }
    run_marie("down");
    stop_am(a);
}

int main(void)
{
    if (getenv("B"))
        bin = getenv("B");
    /* the system files' exec lines are read from their own folder, under dir */
    if (realpath(bin, bin_abs))
        bin = bin_abs;
    snprintf(dir, sizeof dir, "/tmp/marie-bench-am-XXXXXX");
    if (!mkdtemp(dir))
        return 1;
    char key[128], seq[128];
    snprintf(key, sizeof key, "%s/key", dir);
    snprintf(seq, sizeof seq, "%s/seq", dir);
    setenv("MARIE_KEY", key, 1);
    setenv("MARIE_SEQ_FILE", seq, 1);
    char args[256];
    snprintf(args, sizeof args, "keygen %s", key);
    if (run_marie(args) != 0)
        return 1;
    /* BENCH_AM_ONLY=respawn|fast|bringup runs one part (while working on one) */
    const char *only = getenv("BENCH_AM_ONLY");
    if (!only || strcmp(only, "respawn") == 0)
        bench_respawn_and_hang();
    if (!only || strcmp(only, "fast") == 0) {
        bench_fast_restart(0);
        bench_fast_restart(10);
    }
    if (!only || strcmp(only, "bringup") == 0)
        bench_bringup_and_idle();
    if (getenv("BENCH_AM_KEEP")) {       /* the managers' logs and traces, to read */
        fprintf(stderr, "bench_am: kept %s\n", dir);
        return 0;
    }
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    return system(cmd) == 0 ? 0 : 1;
}
