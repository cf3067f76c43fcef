/* bench_rtt: round trip (ping, wait for the echo, ping again) to an echo process, through marie
 * ports and through the raw LCM C API in the same run, and Cyclone DDS's own ddsperf ping/pong
 * (ROS 2's middleware of Debian 12's generation) measured the same way right after, for 64 B,
 * 8 KB and 900 KB. Each path has an echo process of its own, as ddsperf's pong is one: marie
 * ports; ports read by marie and sent by liblcm's lcm_publish on the same bus both ways (marie's
 * sender against liblcm's, all else equal); ports with both loops spinning (`sched: {spin_us}`,
 * with what it costs in CPU); ports on channels put on shared memory (`transports: {kind:
 * shm}`); ports on the same-host fast path (`kind: local`), plain, spinning, and with the two
 * processes on CPUs of their own (as `sched: {cpus: [N]}` puts components); and a plain liblcm
 * program. The marie echoes are components of a system file, which sets their channels, spin
 * and transports as a robot's file would.
 * `bench_rtt echo|echo-lib --system FILE --name NAME` and `bench_rtt echo-raw` are the echoes.
 * BENCH_RTT_ONLY=NAME[,NAME...] runs those paths alone (names as the echoes': pong, pong-lpin,
 * ..., raw), to profile one; the others' rows are then empty. BENCH_RTT_DDS_PINNED=1 adds
 * ddsperf with its ping and pong pinned as the pinned path's sides. */
#include <poll.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "bench/bench.h"
#include "core/component.h"
#include "tests/proc.h"

/* The raw baseline's bus: plain liblcm instances (lcm_create: liblcm's receive thread reads
 * them) on a port of their own, so neither side's sockets read the other's traffic. */
#define RAW_URL "udpm://239.255.76.67:7668?ttl=0&recv_buf_size=8388608"

/* ---- the echo processes ---- */

static void echo_port(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    marie_port_publish(marie_port(c, "pong"), msg);
}

/* The same echo, sent by liblcm on the port's bus (marie reads it). */
static void echo_lib(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    static uint8_t buf[1 << 20];
    int n = marie_image_t_encode(buf, 0, sizeof buf, msg);
    if (n > 0)
        lcm_publish(marie_component_lcm(c), marie_port_channel(marie_port(c, "pong")), buf, (unsigned)n);
}

static int echo_init(marie_component_t *c) { return marie_port_on_message(marie_port(c, "ping"), echo_port); }
static int echo_lib_init(marie_component_t *c) { return marie_port_on_message(marie_port(c, "ping"), echo_lib); }

/* Channels from the system file. */
static const marie_port_spec_t echo_ports[] = {
    {"ping", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "RTT_ECHO_PING"},
    {"pong", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "RTT_ECHO_PONG"},
    {0},
};
static const marie_component_def_t echo_def = {.kind = "bench-echo", .ports = echo_ports, .on_init = echo_init};
static const marie_component_def_t echo_lib_def = {.kind = "bench-echo-lib", .ports = echo_ports,
                                                   .on_init = echo_lib_init};

/* The raw baseline's echo: a plain liblcm program. */
static void echo_raw(const lcm_recv_buf_t *rb, const char *ch, const marie_image_t *m, void *user)
{
    marie_image_t_publish(user, "RTT_RAW_PONG", m);
}

static int raw_echo_main(void)
{
    lcm_t *lcm = lcm_create(RAW_URL);
    if (!lcm || !marie_image_t_subscribe(lcm, "RTT_RAW_PING", echo_raw, lcm))
        return 1;
    for (;;)
        lcm_handle(lcm);
}

/* How long both spinning loops spin after work: longer than a 64 B or 8 KB round trip under load. */
#define SPIN_US 200

/* ---- the pinging side ---- */

/* The paths, each to an echo of its own; PORTS is the row's value, RAW its baseline. */
enum { PORTS, LIB_SEND, RAW, SPIN, SHM, LOCAL, LOCAL_SPIN, LOCAL_PINNED, LOCAL_ONE_CPU, NPATHS };
static const char *const echo_names[NPATHS] = {"pong", "pong-lib", NULL, "pong-spin", "pong-shm", "pong-local",
                                               "pong-lspin", "pong-lpin", "pong-l1cpu"};
/* The pinging component's ports of each path (LIB_SEND sends with liblcm on ping_lib's channel). */
static const char *const ping_port[NPATHS] = {"ping", "ping_lib", NULL, "spin_ping", "shm_ping", "local_ping",
                                              "lspin_ping", "lpin_ping", "l1cpu_ping"};
static const char *const pong_port[NPATHS] = {"pong", "pong_lib", NULL, "spin_pong", "shm_pong", "local_pong",
                                              "lspin_pong", "lpin_pong", "l1cpu_pong"};
static bool spins(int path) { return path == SPIN || path == LOCAL_SPIN; }

/* The path is run (BENCH_RTT_ONLY unset, or it names the path). */
static bool wanted(int path)
{
    const char *only = getenv("BENCH_RTT_ONLY");
    const char *name = echo_names[path] ? echo_names[path] : "raw";
    if (!only)
        return true;
    for (const char *at = strstr(only, name); at; at = strstr(at + 1, name))
        if ((at == only || at[-1] == ',') && (at[strlen(name)] == ',' || !at[strlen(name)]))
            return true;
    return false;
}

typedef struct {
    int64_t lat[4000];
    int n;
    int32_t want;   /* the sequence number awaited (it rides in row_stride) */
    int back;       /* it came back */
} rtt_t;

typedef struct {
    marie_component_t *c;
    lcm_t *lcm;             /* the raw path's: a plain liblcm instance */
    rtt_t path[NPATHS];
    pid_t echo[NPATHS];
    int64_t cpu_ns[NPATHS]; /* CPU of both sides' main threads in the path's blocks */
    marie_port_t *pong[NPATHS]; /* each path's answers come on this port (found once, not per answer) */
} pinger_t;

/* The monotonic clock in ns: a round trip on one host takes a few us, which whole us would blur.
 * The ping carries it in utime, and its echo brings it back. */
static int64_t mono_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

static void got(rtt_t *r, const marie_image_t *m)
{
    if (m->row_stride != r->want || r->back)
        return;  /* a late echo of an earlier ping */
    r->back = 1;
    if (r->n < (int)(sizeof r->lat / sizeof r->lat[0]))
        r->lat[r->n++] = mono_ns() - m->utime;
}

static void on_pong(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    pinger_t *pg = marie_component_user(c);
    for (int k = 0; k < NPATHS; k++)
        if (pg->pong[k] == p)
            got(&pg->path[k], msg);
}

static void on_raw_pong(const lcm_recv_buf_t *rb, const char *ch, const marie_image_t *m, void *user)
{
    got(user, m);
}

static int ping_init(marie_component_t *c)
{
    pinger_t *pg = marie_component_user(c);
    for (int k = 0; k < NPATHS; k++)
        if (pong_port[k] && (!(pg->pong[k] = marie_port(c, pong_port[k])) ||
                             marie_port_on_message(pg->pong[k], on_pong) < 0))
            return -1;
    return 0;
}

static const marie_port_spec_t ping_ports[] = {
    {"ping", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "RTT_PING"},
    {"pong", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "RTT_PONG"},
    {"ping_lib", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "RTT_PING_LIB"},
    {"pong_lib", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "RTT_PONG_LIB"},
    {"spin_ping", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "RTT_SPIN_PING"},
    {"spin_pong", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "RTT_SPIN_PONG"},
    {"shm_ping", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "RTT_SHM_PING"},
    {"shm_pong", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "RTT_SHM_PONG"},
    {"local_ping", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "RTT_LOCAL_PING"},
    {"local_pong", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "RTT_LOCAL_PONG"},
    {"lspin_ping", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "RTT_LSPIN_PING"},
    {"lspin_pong", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "RTT_LSPIN_PONG"},
    {"lpin_ping", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "RTT_LPIN_PING"},
    {"lpin_pong", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "RTT_LPIN_PONG"},
    {"l1cpu_ping", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "RTT_L1CPU_PING"},
    {"l1cpu_pong", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "RTT_L1CPU_PONG"},
    {0},
};
static const marie_component_def_t ping_def = {.kind = "bench-ping", .ports = ping_ports, .on_init = ping_init};

/* CPU time a process's main thread has had, in ns (the scheduler's own count, to the ns). */
static int64_t thread_cpu_ns(pid_t pid)
{
    char path[64];
    snprintf(path, sizeof path, "/proc/%d/schedstat", (int)pid);
    FILE *f = fopen(path, "r");
    long long ns = 0;
    if (f) {
        if (fscanf(f, "%lld", &ns) != 1)
            ns = 0;
        fclose(f);
    }
    return ns;
}

static int64_t self_cpu_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

/* One round trip: 0 when the echo came back within timeout_ms. The raw side waits the way a
 * plain LCM program does (poll the fd, lcm_handle); marie's on its loop. */
static int round_trip(pinger_t *pg, int path, marie_image_t *img, int32_t seq, int timeout_ms)
{
    rtt_t *r = &pg->path[path];
    r->want = seq;
    r->back = 0;
    img->row_stride = seq;
    img->utime = mono_ns();
    if (path == RAW) {
        marie_image_t_publish(pg->lcm, "RTT_RAW_PING", img);
    } else if (path == LIB_SEND) {
        static uint8_t buf[1 << 20];
        int n = marie_image_t_encode(buf, 0, sizeof buf, img);
        lcm_publish(marie_component_lcm(pg->c), marie_port_channel(marie_port(pg->c, "ping_lib")), buf,
                    (unsigned)n);
    } else {
        marie_port_publish(marie_port(pg->c, ping_port[path]), img);
    }
    int64_t end = img->utime + (int64_t)timeout_ms * 1000000;
    while (!r->back && mono_ns() < end) {
        if (path != RAW) {
            marie_loop_run_once(marie_component_loop(pg->c), 5);
        } else {
            struct pollfd p = {lcm_get_fileno(pg->lcm), POLLIN, 0};
            if (poll(&p, 1, 5) > 0)
                lcm_handle(pg->lcm);
        }
    }
    return r->back ? 0 : -1;
}

static void row(const char *metric, const char *label, double v, const char *unit, double base)
{
    char m[64];
    snprintf(m, sizeof m, "%s_%s", metric, label);
    bench_row("rtt", m, v, unit, base);
}

typedef struct {
    double p50, p99;
    long count;
} dds_t;

/* The pinned path's CPUs: the first two this process may use (its echo on the second, the
 * pinging side on the first during its blocks, as `sched: {cpus: [N]}` would put them). */
static cpu_set_t cpus_all, cpus_pin[2];

/* ddsperf ping at `size` for `seconds` against a ddsperf pong, pinned as the pinned path's two
 * sides when `pinned`. It prints a line a second; the first (discovery, warm-up) is dropped and
 * the figures are the medians of the others. */
static int dds_round_trip(size_t size, int seconds, bool pinned, dds_t *out)
{
    char dur[16], cmd[320];
    snprintf(dur, sizeof dur, "%d", seconds + 3);
    char *pong[] = {"ddsperf", "-D", dur, "pong", NULL};
    /* test_spawn takes a path: find ddsperf on PATH the way the shell would. */
    FILE *w = popen("command -v ddsperf", "r");
    char path[256] = "";
    if (!w || !fgets(path, sizeof path, w))
        path[0] = 0;
    if (w)
        pclose(w);
    path[strcspn(path, "\n")] = 0;
    if (!path[0])
        return -1;
    pong[0] = path;
    /* pinned: each side inherits this process's CPU as it starts, with all its threads */
    if (pinned)
        sched_setaffinity(0, sizeof cpus_pin[1], &cpus_pin[1]);
    pid_t pid = test_spawn(pong, "/dev/null");
    snprintf(cmd, sizeof cmd, "%s -D %d ping size %zu 2>&1", path, seconds + 1, size);
    if (pinned)
        sched_setaffinity(0, sizeof cpus_pin[0], &cpus_pin[0]);
    FILE *f = popen(cmd, "r");
    if (pinned)
        sched_setaffinity(0, sizeof cpus_all, &cpus_all);
    int64_t p50[64], p99[64];
    int n = 0, lines = 0;
    out->count = 0;
    char line[512];
    while (f && fgets(line, sizeof line, f)) {
        const char *a = strstr(line, " 50% "), *b = strstr(line, " 99% "), *c = strstr(line, " cnt ");
        if (!a || !b || !c || !strstr(line, " size "))
            continue;
        if (lines++ == 0 || n == 64)
            continue;
        p50[n] = (int64_t)(strtod(a + 5, NULL) * 1000);  /* ns, to keep the decimals */
        p99[n] = (int64_t)(strtod(b + 5, NULL) * 1000);
        out->count += strtol(c + 5, NULL, 10);
        n++;
    }
    if (f)
        pclose(f);
    test_stop(pid);
    out->p50 = bench_percentile(p50, n, 0.5) / 1000;
    out->p99 = bench_percentile(p99, n, 0.5) / 1000;
    return n ? 0 : -1;
}

/* Round trips at the start of each block that are not counted, on every path: the echo has
 * waited through the other paths' blocks, and their traffic has taken the caches (at 900 KB a
 * shared-memory channel's first lap of its 8 slots came 2-3x slower than the rest), as
 * ddsperf's first second is dropped. */
#define WARMUP 8

/* A block ends after BLOCK_MAX_US of round trips (a quarter of it in the first, warming pass),
 * with BLOCK_MIN_KEPT of them at least: beside
 * busy loops the spinning paths' sched_yield() hands a whole slice away (2-16 ms a round trip),
 * and without the bound their blocks alone took 20-50 s of the run. Their rows then hold fewer
 * samples (a p99 near their largest); the others never come near it. */
#define BLOCK_MAX_US 150000
#define BLOCK_MIN_KEPT 10

static int pin_setup(void)
{
    if (sched_getaffinity(0, sizeof cpus_all, &cpus_all) < 0)
        return -1;
    int found = 0;
    for (int c = 0; c < CPU_SETSIZE && found < 2; c++)
        if (CPU_ISSET(c, &cpus_all)) {
            CPU_ZERO(&cpus_pin[found]);
            CPU_SET(c, &cpus_pin[found++]);
        }
    if (found == 1)
        cpus_pin[1] = cpus_pin[0];
    return found ? 0 : -1;
}

/* n round trips on one path (fewer past BLOCK_MAX_US), after WARMUP more; the CPU both sides' main threads took for the n. */
static int block(pinger_t *pg, int path, marie_image_t *img, int32_t *seq, int n, int64_t max_us)
{
    int lost = 0;
    rtt_t *r = &pg->path[path];
    if (!wanted(path))
        return 0;
    if (path == LOCAL_PINNED || path == LOCAL_ONE_CPU)
        sched_setaffinity(0, sizeof cpus_pin[0], &cpus_pin[0]);
    marie_loop_set_spin(marie_component_loop(pg->c), spins(path) ? SPIN_US : 0);
    int kept = r->n;
    for (int i = 0; i < WARMUP; i++)
        lost += round_trip(pg, path, img, (*seq)++, 200) < 0;
    r->n = kept;
    int64_t cpu = self_cpu_ns() + thread_cpu_ns(pg->echo[path]), t0 = marie_mono_us();
    for (int i = 0; i < n && (i < BLOCK_MIN_KEPT || marie_mono_us() - t0 < max_us); i++)
        lost += round_trip(pg, path, img, (*seq)++, 200) < 0;
    marie_loop_set_spin(marie_component_loop(pg->c), 0);
    pg->cpu_ns[path] += self_cpu_ns() + thread_cpu_ns(pg->echo[path]) - cpu;
    if (path == LOCAL_PINNED || path == LOCAL_ONE_CPU)
        sched_setaffinity(0, sizeof cpus_all, &cpus_all);
    return lost;
}

/* A percentile of r's samples in us (it sorts them). */
static double pct(rtt_t *r, double p) { return bench_percentile(r->lat, r->n, p) / 1000; }

static void run_size(pinger_t *pg, const char *label, size_t size, int n)
{
    marie_image_t img = {.width = 1, .height = (int32_t)size, .size = (int32_t)size,
                         .format = MARIE_IMAGE_T_FORMAT_GRAY8};
    img.data = calloc(1, size);
    int lost[NPATHS];
    /* the first pass, a quarter as long, warms caches and sockets; the second is counted */
    for (int pass = 0; pass < 2; pass++) {
        for (int k = 0; k < NPATHS; k++) {
            pg->path[k].n = lost[k] = 0;
            pg->cpu_ns[k] = 0;
        }
        int32_t seq = 1000000 * (pass + 1);
        /* Interleaved in blocks of a tenth, so that drift hits all alike, each block starting
         * with the next path (a block's first round trips, after another path's, are slower:
         * with a fixed order the p99s followed the order, not the path). */
        for (int blk = 0; blk < 10; blk++)
            for (int k = 0; k < NPATHS; k++) {
                int path = (blk + k) % NPATHS;
                int64_t max_us = pass ? BLOCK_MAX_US : BLOCK_MAX_US / 4;
                lost[path] += block(pg, path, &img, &seq, pass ? n / 10 : n / 40, max_us);
            }
    }
    free(img.data);
    rtt_t *m = &pg->path[PORTS], *raw = &pg->path[RAW], *lib = &pg->path[LIB_SEND];
    rtt_t *spin = &pg->path[SPIN], *shm = &pg->path[SHM];
    row("p50", label, pct(m, 0.5), "us", pct(raw, 0.5));
    row("p99", label, pct(m, 0.99), "us", pct(raw, 0.99));
    row("lost", label, lost[PORTS], "msgs", lost[RAW]);
    row("p50_vs_liblcm_send", label, pct(m, 0.5), "us", pct(lib, 0.5));
    row("p99_vs_liblcm_send", label, pct(m, 0.99), "us", pct(lib, 0.99));
    row("lost_liblcm_send", label, lost[LIB_SEND], "msgs", NAN);
    row("p50_spin", label, pct(spin, 0.5), "us", pct(m, 0.5));
    row("p99_spin", label, pct(spin, 0.99), "us", pct(m, 0.99));
    row("lost_spin", label, lost[SPIN], "msgs", NAN);
    /* What a round trip costs both sides in CPU, spinning against not (baseline). */
    row("cpu_per_rtt_spin", label, spin->n ? pg->cpu_ns[SPIN] / 1000.0 / spin->n : NAN, "us",
        m->n ? pg->cpu_ns[PORTS] / 1000.0 / m->n : NAN);
    row("p50_shm", label, pct(shm, 0.5), "us", pct(m, 0.5));
    row("p99_shm", label, pct(shm, 0.99), "us", pct(m, 0.99));
    row("lost_shm", label, lost[SHM], "msgs", NAN);
    rtt_t *loc = &pg->path[LOCAL], *lspin = &pg->path[LOCAL_SPIN];
    row("p50_local", label, pct(loc, 0.5), "us", pct(m, 0.5));
    row("p99_local", label, pct(loc, 0.99), "us", pct(m, 0.99));
    row("lost_local", label, lost[LOCAL], "msgs", NAN);
    row("p50_local_spin", label, pct(lspin, 0.5), "us", pct(m, 0.5));
    row("p99_local_spin", label, pct(lspin, 0.99), "us", pct(m, 0.99));
    row("lost_local_spin", label, lost[LOCAL_SPIN], "msgs", NAN);
    row("cpu_per_rtt_local_spin", label, lspin->n ? pg->cpu_ns[LOCAL_SPIN] / 1000.0 / lspin->n : NAN, "us",
        loc->n ? pg->cpu_ns[LOCAL] / 1000.0 / loc->n : NAN);
    rtt_t *lpin = &pg->path[LOCAL_PINNED];
    row("p50_local_pinned", label, pct(lpin, 0.5), "us", pct(loc, 0.5));
    row("p99_local_pinned", label, pct(lpin, 0.99), "us", pct(loc, 0.99));
    row("lost_local_pinned", label, lost[LOCAL_PINNED], "msgs", NAN);
    row("cpu_per_rtt_local_pinned", label, lpin->n ? pg->cpu_ns[LOCAL_PINNED] / 1000.0 / lpin->n : NAN, "us",
        loc->n ? pg->cpu_ns[LOCAL] / 1000.0 / loc->n : NAN);
    /* Both sides on one CPU, where the kernel sometimes puts them: they take turns on it. */
    rtt_t *l1 = &pg->path[LOCAL_ONE_CPU];
    row("p50_local_one_cpu", label, pct(l1, 0.5), "us", pct(lpin, 0.5));
    row("p99_local_one_cpu", label, pct(l1, 0.99), "us", pct(lpin, 0.99));
    row("lost_local_one_cpu", label, lost[LOCAL_ONE_CPU], "msgs", NAN);
    dds_t d;
    if (dds_round_trip(size, 3, false, &d) < 0) {
        printf("# rtt: no ddsperf figures for %s (scripts/install-deps.sh bench installs "
               "cyclonedds-tools)\n", label);
        return;
    }
    row("p50_vs_dds", label, pct(m, 0.5), "us", d.p50);
    row("p99_vs_dds", label, pct(m, 0.99), "us", d.p99);
    row("p50_spin_vs_dds", label, pct(spin, 0.5), "us", d.p50);
    row("p99_spin_vs_dds", label, pct(spin, 0.99), "us", d.p99);
    row("p50_shm_vs_dds", label, pct(shm, 0.5), "us", d.p50);
    row("p99_shm_vs_dds", label, pct(shm, 0.99), "us", d.p99);
    row("p50_local_vs_dds", label, pct(loc, 0.5), "us", d.p50);
    row("p99_local_vs_dds", label, pct(loc, 0.99), "us", d.p99);
    row("p50_local_spin_vs_dds", label, pct(lspin, 0.5), "us", d.p50);
    row("p99_local_spin_vs_dds", label, pct(lspin, 0.99), "us", d.p99);
    row("p50_local_pinned_vs_dds", label, pct(lpin, 0.5), "us", d.p50);
    row("p99_local_pinned_vs_dds", label, pct(lpin, 0.99), "us", d.p99);
    row("p50_local_one_cpu_vs_dds", label, pct(l1, 0.5), "us", d.p50);
    /* ddsperf pinned as the pinned path is (BENCH_RTT_DDS_PINNED=1, not in the default run):
     * whether the pinned rows' baseline favours marie (docs/transport.md, "Where it stands"). */
    dds_t dp;
    const char *dpin = getenv("BENCH_RTT_DDS_PINNED");
    if (dpin && !strcmp(dpin, "1") && dds_round_trip(size, 3, true, &dp) == 0) {
        row("p50_dds_pinned", label, dp.p50, "us", d.p50);
        row("p50_local_pinned_vs_dds_pinned", label, pct(lpin, 0.5), "us", dp.p50);
    }
    fprintf(stderr, "bench_rtt: ddsperf %s: %ld round trips\n", label, d.count);
}

int main(int argc, char **argv)
{
    if (argc > 1 && !strcmp(argv[1], "echo"))
        return marie_main(&echo_def, argc - 1, argv + 1, NULL);
    if (argc > 1 && !strcmp(argv[1], "echo-lib"))
        return marie_main(&echo_lib_def, argc - 1, argv + 1, NULL);
    if (argc > 1 && !strcmp(argv[1], "echo-raw"))
        return raw_echo_main();
    marie_log_set_threshold(MARIE_LOG_ERROR);
    /* ddsperf on loopback only, like every LCM socket here (the benchmarks run in a namespace
     * with nothing but lo). */
    setenv("CYCLONEDDS_URI", "<CycloneDDS><Domain><General><Interfaces><NetworkInterface name=\"lo\"/>"
           "</Interfaces></General></Domain></CycloneDDS>", 1);
    char self[512];
    ssize_t k = readlink("/proc/self/exe", self, sizeof self - 1);
    if (k <= 0)
        return 1;
    self[k] = 0;
    /* The echoes and the pinging side are components of one system file (channels, spin,
     * transports), as a robot's are. */
    char sys[] = "/tmp/bench-rtt-XXXXXX.yaml", text[4096];
    snprintf(text, sizeof text, "system: bench-rtt\nlcm_url: \"%s\"\n"
             "transports:\n"
             "  RTT_SHM_PING: {kind: shm, max_size: 1000000, slots: 8}\n"
             "  RTT_SHM_PONG: {kind: shm, max_size: 1000000, slots: 8}\n"
             "  RTT_LOCAL_PING: {kind: local, max_size: 1000000, slots: 8}\n"
             "  RTT_LOCAL_PONG: {kind: local, max_size: 1000000, slots: 8}\n"
             "  RTT_LSPIN_PING: {kind: local, max_size: 1000000, slots: 8}\n"
             "  RTT_LSPIN_PONG: {kind: local, max_size: 1000000, slots: 8}\n"
             "  RTT_LPIN_PING: {kind: local, max_size: 1000000, slots: 8}\n"
             "  RTT_LPIN_PONG: {kind: local, max_size: 1000000, slots: 8}\n"
             "  RTT_L1CPU_PING: {kind: local, max_size: 1000000, slots: 8}\n"
             "  RTT_L1CPU_PONG: {kind: local, max_size: 1000000, slots: 8}\n"
             "components:\n"
             "  ping: {exec: /bin/true}\n"
             "  pong: {exec: /bin/true, ports: {ping: RTT_PING, pong: RTT_PONG}}\n"
             "  pong-lib: {exec: /bin/true, ports: {ping: RTT_PING_LIB, pong: RTT_PONG_LIB}}\n"
             "  pong-spin: {exec: /bin/true, sched: {spin_us: %d}, ports: {ping: RTT_SPIN_PING, pong: RTT_SPIN_PONG}}\n"
             "  pong-shm: {exec: /bin/true, ports: {ping: RTT_SHM_PING, pong: RTT_SHM_PONG}}\n"
             "  pong-local: {exec: /bin/true, ports: {ping: RTT_LOCAL_PING, pong: RTT_LOCAL_PONG}}\n"
             "  pong-lspin: {exec: /bin/true, sched: {spin_us: %d}, ports: {ping: RTT_LSPIN_PING, pong: RTT_LSPIN_PONG}}\n"
             "  pong-lpin: {exec: /bin/true, ports: {ping: RTT_LPIN_PING, pong: RTT_LPIN_PONG}}\n"
             "  pong-l1cpu: {exec: /bin/true, ports: {ping: RTT_L1CPU_PING, pong: RTT_L1CPU_PONG}}\n",
             marie_default_url(), SPIN_US, SPIN_US);
    if (test_write_temp(sys, 5, text) < 0)
        return 1;
    static pinger_t pg;
    if (pin_setup() < 0)
        return 1;
    for (int p = 0; p < NPATHS; p++) {
        char *argv_echo[] = {self, p == LIB_SEND ? "echo-lib" : "echo", "--system", sys, "--name",
                             (char *)echo_names[p], NULL};
        char *argv_raw[] = {self, "echo-raw", NULL};
        pg.echo[p] = test_spawn(p == RAW ? argv_raw : argv_echo, NULL);
        if ((p == LOCAL_PINNED || p == LOCAL_ONE_CPU) && pg.echo[p] > 0)
            sched_setaffinity(pg.echo[p], sizeof cpus_pin[p == LOCAL_PINNED], &cpus_pin[p == LOCAL_PINNED]);
    }
    char *av[] = {"bench-ping", "--system", sys, "--name", "ping"};
    marie_errors_t e = {0};
    pg.c = marie_component_create(&ping_def, 5, av, &pg, &e);
    const char *why;
    int rc = 1;
    if (!pg.c || marie_component_command(pg.c, MARIE_CMD_INIT, &why) < 0 ||
        marie_component_command(pg.c, MARIE_CMD_START, &why) < 0) {
        marie_errors_print(&e, stderr);
        goto out;
    }
    pg.lcm = lcm_create(RAW_URL);     /* the baseline: a plain liblcm program */
    if (!pg.lcm || !marie_image_t_subscribe(pg.lcm, "RTT_RAW_PONG", on_raw_pong, &pg.path[RAW]))
        goto out;
    /* Wait for the echo processes: ping each until one comes back (5 s at most). */
    marie_image_t probe = {.width = 1, .height = 1, .size = 1, .format = MARIE_IMAGE_T_FORMAT_GRAY8};
    uint8_t byte = 0;
    probe.data = &byte;
    for (int p = 0; p < NPATHS; p++) {
        int up = 0;
        for (int i = 0; i < 100 && !up; i++)
            up = round_trip(&pg, p, &probe, -1 - i, 50) == 0;
        if (!up) {
            fprintf(stderr, "bench_rtt: the echo %s did not answer\n", echo_names[p] ? echo_names[p] : "raw");
            goto out;
        }
    }
    printf("# bench\tmetric\tvalue (marie ports)\tunit\tbaseline (raw LCM, or ddsperf for _vs_dds)\tratio\n");
    /* Fewer round trips than the samples' room: nine paths in two CPU states (a p99 of 1000
     * is its tenth-largest; 900 KB's of 200 its second). */
    run_size(&pg, "64B", 64, 1000);
    run_size(&pg, "8KB", 8192, 600);
    run_size(&pg, "900KB", 921600, 200);
    /* The same beside two busy loops of the bench's own, ddsperf too: with every CPU busy the
     * kernel's wake-ups are cheap (no CPU comes out of its idle state), and the paths compare
     * differently (docs/transport.md). */
    pid_t busy[2] = {0};
    if (test_busy_start(busy, 2) == 0) {
        run_size(&pg, "64B_busy", 64, 1000);
        run_size(&pg, "8KB_busy", 8192, 600);
        run_size(&pg, "900KB_busy", 921600, 200);
    }
    test_busy_stop(busy, 2);
    rc = 0;
out:
    marie_component_destroy(pg.c);
    if (pg.lcm)
        lcm_destroy(pg.lcm);
    for (int p = 0; p < NPATHS; p++)
        test_stop(pg.echo[p]);
    unlink(sys);
    return rc;
}
