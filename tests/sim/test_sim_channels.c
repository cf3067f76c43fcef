/* test_sim_channels: marie-sim in channel mode on a real LCM bus (this test's namespace):
 * channels, types and rates; motor commands and the drives' watchdog; the e-stop; lockstep;
 * a component's timers following the sim clock at speed 10; a bad world refused clearly;
 * in device mode, the robot coming to rest when marie-drives is killed or frozen. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include <lcm/lcm.h>

#include "core/component.h"
#include "tests/proc.h"

#define MAX_CH 16
#define WALL_LIMIT_US 30000000      /* a bound on every wait, not a timing assertion */

typedef struct {
    char name[64];
    int64_t hash;
    long count;
    int64_t first_utime, last_utime;
    int64_t gaps[2048];         /* utime steps between consecutive messages */
    int ngaps;
} chan_t;

static struct {
    chan_t ch[MAX_CH];
    int n;
    int64_t clock;              /* last MARIE_CLOCK utime */
    marie_pose_cov_t truth;
    marie_wheel_encoders_t enc;
    marie_estop_t estop;
    int laser_beams;
    int have_heartbeat, failed;
    int64_t collisions;
    uint8_t scans[20][1024];    /* the first LASER payloads, raw */
    int nscans;
    char reason[512];
    long clocks;
} rx;

static pid_t sim_pid;
static pid_t drv_pids[3];

static void start_sim(const char *const *extra)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    static char bin[256];
    snprintf(bin, sizeof(bin), "%s/bin/marie-sim", b);
    const char *argv[40] = { bin, "--world", "test", "--param", "start_x=3.0", "--param", "start_y=2.0" };
    int n = 7;
    for (int i = 0; extra && extra[i] && n < 38; i++)
        argv[n++] = extra[i];
    argv[n] = NULL;
    sim_pid = fork();
    assert_true(sim_pid >= 0);
    if (sim_pid == 0) {
        execv(bin, (char *const *)argv);
        _exit(127);
    }
}

static pid_t spawn(const char *const *argv)
{
    pid_t pid = test_spawn((char *const *)argv, NULL);
    assert_true(pid >= 0);
    return pid;
}

static void stop_drivers(void)
{
    for (int i = 0; i < 3; i++)
        if (drv_pids[i] > 0) {
            kill(drv_pids[i], SIGTERM);
            int st;
            waitpid(drv_pids[i], &st, 0);
            drv_pids[i] = 0;
        }
}

static void stop_sim(void)
{
    if (sim_pid > 0) {
        kill(sim_pid, SIGTERM);
        int st;
        waitpid(sim_pid, &st, 0);
        sim_pid = 0;
    }
}

static int64_t be64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 0; i < 8; i++)
        v = v << 8 | p[i];
    return (int64_t)v;
}

static void on_any(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    if (rb->data_size < 16)
        return;
    const uint8_t *d = rb->data;
    int64_t utime = be64(d + 8);
    chan_t *c = NULL;
    for (int i = 0; i < rx.n; i++)
        if (strcmp(rx.ch[i].name, channel) == 0)
            c = &rx.ch[i];
    if (!c && rx.n < MAX_CH) {
        c = &rx.ch[rx.n++];
        snprintf(c->name, sizeof(c->name), "%s", channel);
        c->hash = be64(d);
        c->first_utime = utime;
    }
    if (c) {
        if (c->count && c->ngaps < 2048)
            c->gaps[c->ngaps++] = utime - c->last_utime;
        c->count++;
        c->last_utime = utime;
    }
    int n = (int)rb->data_size;
    if (strcmp(channel, "MARIE_CLOCK") == 0) {
        marie_sim_clock_t m;
        if (marie_sim_clock_t_decode(d, 0, n, &m) > 0) {
            rx.clock = m.utime;
            rx.clocks++;
            marie_sim_clock_t_decode_cleanup(&m);
        }
    } else if (strcmp(channel, "SIM_TRUTH") == 0) {
        marie_pose_cov_t m;
        if (marie_pose_cov_t_decode(d, 0, n, &m) > 0) {
            rx.truth.pose = m.pose;
            rx.truth.utime = m.utime;
            marie_pose_cov_t_decode_cleanup(&m);
        }
    } else if (strcmp(channel, "WHEEL_ENCODERS") == 0) {
        marie_wheel_encoders_t_decode(d, 0, n, &rx.enc);
    } else if (strcmp(channel, "ESTOP") == 0) {
        marie_estop_t m;
        if (marie_estop_t_decode(d, 0, n, &m) > 0) {
            rx.estop.pressed = m.pressed;
            rx.estop.utime = m.utime;
            marie_estop_t_decode_cleanup(&m);
        }
    } else if (strcmp(channel, "LASER") == 0) {
        if (rx.nscans < 20 && rb->data_size <= sizeof(rx.scans[0]))
            memcpy(rx.scans[rx.nscans++], d, rb->data_size);
        marie_laser_scan_t m;
        if (marie_laser_scan_t_decode(d, 0, n, &m) > 0) {
            rx.laser_beams = m.nranges;
            marie_laser_scan_t_decode_cleanup(&m);
        }
    } else if (strcmp(channel, "MARIE_HEARTBEAT") == 0) {
        marie_heartbeat_t m;
        if (marie_heartbeat_t_decode(d, 0, n, &m) > 0) {
            rx.have_heartbeat = 1;
            for (int i = 0; i < m.ncounters; i++)
                if (strcmp(m.counters[i].name, "collisions") == 0)
                    rx.collisions = m.counters[i].value;
            if (m.state == MARIE_STATE_FAILED) {
                rx.failed = 1;
                snprintf(rx.reason, sizeof(rx.reason), "%s", m.reason);
            }
            marie_heartbeat_t_decode_cleanup(&m);
        }
    }
}

static lcm_t *bus(void)
{
    memset(&rx, 0, sizeof(rx));
    rx.clock = -1;
    lcm_t *l = lcm_create(marie_default_url());   /* 8 MB receive buffer: speed 0 sends bursts */
    assert_non_null(l);
    /* LCM drops past a subscription's queue capacity (30 by default): room for bursts. */
    lcm_subscription_set_queue_capacity(lcm_subscribe(l, ".*", on_any, NULL), 100000);
    return l;
}

/* Handle messages until the sim clock reaches t_us (bounded in wall time). */
static void until_clock(lcm_t *l, int64_t t_us)
{
    int64_t end = marie_mono_us() + WALL_LIMIT_US;
    while (rx.clock < t_us && marie_mono_us() < end)
        lcm_handle_timeout(l, 100);
    if (rx.clock < t_us)
        fprintf(stderr, "waited for sim time %.3f s, clock at %.3f s\n", t_us / 1e6, rx.clock / 1e6);
    assert_true(rx.clock >= t_us);
}

static chan_t *chan(const char *name)
{
    for (int i = 0; i < rx.n; i++)
        if (strcmp(rx.ch[i].name, name) == 0)
            return &rx.ch[i];
    fprintf(stderr, "no messages on %s\n", name);
    fail();
    return NULL;
}

/* Rate in messages per simulated second, from the median spacing of the messages' sim
 * timestamps (a datagram lost on a loaded machine does not change it). */
static int cmp64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return x < y ? -1 : x > y;
}

static double rate(chan_t *c)
{
    if (c->ngaps < 1)
        return 0;
    qsort(c->gaps, (size_t)c->ngaps, sizeof(c->gaps[0]), cmp64);
    return 1e6 / (double)c->gaps[c->ngaps / 2];
}

static void send_cmd(lcm_t *l, double v, double omega)
{
    marie_motor_command_t m = { .utime = rx.clock, .v = v, .omega = omega, .source = "test" };
    marie_motor_command_t_publish(l, "MOTOR_COMMAND", &m);
}

static void test_channels_types_rates(void **state)
{
    lcm_t *l = bus();
    const char *extra[] = { "--speed", "10", NULL };
    start_sim(extra);
    until_clock(l, 5000000);
    stop_sim();
    struct { const char *ch; int64_t hash; double hz; } want[] = {
        { "WHEEL_ENCODERS", __marie_wheel_encoders_t_get_hash(), 20 },
        { "GYRO", __marie_gyro_t_get_hash(), 50 },
        { "LASER", __marie_laser_scan_t_get_hash(), 10 },
        { "ESTOP", __marie_estop_t_get_hash(), 2 },
        { "SIM_TRUTH", __marie_pose_cov_t_get_hash(), 50 },
        { "MARIE_CLOCK", __marie_sim_clock_t_get_hash(), 100 },
    };
    for (size_t i = 0; i < sizeof(want) / sizeof(want[0]); i++) {
        chan_t *c = chan(want[i].ch);
        double hz = rate(c), span = (c->last_utime - c->first_utime) / 1e6;
        fprintf(stderr, "%-16s %5ld msgs over %.2f s, %.2f Hz of sim time\n", c->name, c->count, span, hz);
        assert_true(c->hash == want[i].hash);
        assert_true(fabs(hz - want[i].hz) < 0.01 * want[i].hz);
        assert_true(c->count >= 0.9 * span * want[i].hz);
    }
    assert_int_equal(rx.laser_beams, 181);
    assert_true(rx.have_heartbeat);
    /* Nothing else on the bus besides the heartbeat and events. */
    for (int i = 0; i < rx.n; i++) {
        int known = strncmp(rx.ch[i].name, "MARIE_", 6) == 0 || strncmp(rx.ch[i].name, "LCM_", 4) == 0;
        for (size_t k = 0; k < sizeof(want) / sizeof(want[0]); k++)
            known |= strcmp(rx.ch[i].name, want[k].ch) == 0;
        if (!known)
            fprintf(stderr, "unexpected channel %s\n", rx.ch[i].name);
        assert_true(known);
    }
    lcm_destroy(l);
}

static void test_motor_command_and_watchdog(void **state)
{
    lcm_t *l = bus();
    const char *extra[] = { "--speed", "3", NULL };
    start_sim(extra);
    until_clock(l, 500000);
    double x0 = rx.truth.pose.x;
    int32_t t0 = rx.enc.left_ticks;
    /* 0.4 m/s for 3 s of sim time, a command every 100 ms of sim time */
    int64_t from = rx.clock;
    for (int64_t t = from; t < from + 3000000; t += 100000) {
        send_cmd(l, 0.4, 0.0);
        until_clock(l, t + 100000);
    }
    double moved = rx.truth.pose.x - x0;
    fprintf(stderr, "moved %.3f m in 3 s at 0.4 m/s, %d ticks\n", moved, rx.enc.left_ticks - t0);
    assert_true(moved > 0.4 * 3 * 0.85 && moved < 0.4 * 3 * 1.1);
    assert_true(rx.enc.left_ticks - t0 > 0.85 * moved / (2 * M_PI * 0.1) * 4096);
    /* No more commands: the drives stop after cmd_timeout (0.5 s) and the ramp. */
    until_clock(l, rx.clock + 1500000);
    double x1 = rx.truth.pose.x;
    until_clock(l, rx.clock + 1000000);
    fprintf(stderr, "after the watchdog: %.4f m more\n", rx.truth.pose.x - x1);
    assert_true(fabs(rx.truth.pose.x - x1) < 0.005);
    assert_true(rx.truth.pose.x < 7.0 - 0.25);
    stop_sim();
    lcm_destroy(l);
}

/* Driving into wall A over the bus: the robot stops at the wall and the simulator counts
 * the collision in its heartbeat (what the demo reports). */
static void test_wall_collision_counted(void **state)
{
    lcm_t *l = bus();
    const char *extra[] = { "--speed", "10", NULL };
    start_sim(extra);
    until_clock(l, 200000);
    assert_int_equal(rx.collisions, 0);
    int64_t from = rx.clock;
    for (int64_t t = from; t < from + 11000000; t += 100000) {
        send_cmd(l, 0.5, 0.0);
        until_clock(l, t + 100000);
    }
    double x = rx.truth.pose.x;
    int64_t end = marie_mono_us() + WALL_LIMIT_US;
    while (rx.collisions < 1 && marie_mono_us() < end)
        lcm_handle_timeout(l, 100);
    fprintf(stderr, "stopped at x %.3f; collisions %lld\n", x, (long long)rx.collisions);
    assert_true(x < 7.0 - 0.25 + 0.02 && x > 6.6);
    assert_true(rx.collisions >= 1);
    stop_sim();
    lcm_destroy(l);
}

/* The program is seeded: the same seed gives the same sensor stream, bit for bit. */
static void scans_with_seed(const char *seed, uint8_t out[20][1024])
{
    lcm_t *l = bus();
    const char *extra[] = { "--speed", "10", "--seed", seed, NULL };
    start_sim(extra);
    int64_t end = marie_mono_us() + WALL_LIMIT_US;
    while (rx.nscans < 20 && marie_mono_us() < end)
        lcm_handle_timeout(l, 100);
    stop_sim();
    assert_int_equal(rx.nscans, 20);
    memcpy(out, rx.scans, sizeof(rx.scans));
    lcm_destroy(l);
}

static void test_seeded_runs_repeat(void **state)
{
    static uint8_t a[20][1024], b[20][1024], c[20][1024];
    scans_with_seed("7", a);
    scans_with_seed("7", b);
    scans_with_seed("8", c);
    assert_memory_equal(a, b, sizeof(a));
    assert_memory_not_equal(a, c, sizeof(a));
}

static void test_estop(void **state)
{
    lcm_t *l = bus();
    const char *extra[] = { "--speed", "10", NULL };
    start_sim(extra);
    until_clock(l, 300000);
    assert_false(rx.estop.pressed);
    marie_estop_t e = { .utime = 0, .pressed = 1, .source = "test" };
    marie_estop_t_publish(l, "SIM_ESTOP", &e);
    int64_t from = rx.clock;
    for (int64_t t = from; t < from + 1000000; t += 100000) {
        send_cmd(l, 0.5, 0.0);              /* ignored while pressed */
        until_clock(l, t + 100000);
    }
    assert_true(rx.estop.pressed);
    assert_int_equal(rx.enc.status, MARIE_WHEEL_ENCODERS_T_STATUS_ESTOP);
    double x0 = rx.truth.pose.x;
    send_cmd(l, 0.5, 0.0);
    until_clock(l, rx.clock + 400000);
    assert_true(fabs(rx.truth.pose.x - x0) < 0.002);
    e.pressed = 0;
    marie_estop_t_publish(l, "SIM_ESTOP", &e);
    from = rx.clock;
    for (int64_t t = from; t < from + 1000000; t += 100000) {
        send_cmd(l, 0.5, 0.0);
        until_clock(l, t + 100000);
    }
    assert_false(rx.estop.pressed);
    assert_int_equal(rx.enc.status, MARIE_WHEEL_ENCODERS_T_STATUS_OK);
    assert_true(rx.truth.pose.x - x0 > 0.2);
    stop_sim();
    lcm_destroy(l);
}

/* Lockstep: the simulator never runs more than `lockstep` of sim time past the last
 * motor command, and goes on as soon as the next command arrives. */
static void test_lockstep(void **state)
{
    lcm_t *l = bus();
    const char *extra[] = { "--speed", "0", "--lockstep", "0.25", "--param", "lockstep_timeout=60", NULL };
    start_sim(extra);
    until_clock(l, 10000);
    /* A 5 Hz controller on the sim clock: answer each 200 ms boundary. */
    int64_t next = rx.clock + 200000, last_cmd = 0;
    send_cmd(l, 0.1, 0.0);
    for (int i = 0; i < 25; i++) {
        until_clock(l, next);
        last_cmd = rx.clock;
        send_cmd(l, 0.1, 0.0);
        next += 200000;
    }
    /* Now silence: the clock must stop within lockstep (plus one clock period) of the last
     * command, however long we wait. */
    int64_t end = marie_mono_us() + WALL_LIMIT_US;
    while (rx.clock < last_cmd + 250000 && marie_mono_us() < end)
        lcm_handle_timeout(l, 50);
    end = marie_mono_us() + 500000;     /* and it stays there */
    while (marie_mono_us() < end)
        lcm_handle_timeout(l, 50);
    fprintf(stderr, "last command at %.3f s, clock held at %.3f s\n", last_cmd / 1e6, rx.clock / 1e6);
    assert_true(rx.clock <= last_cmd + 250000 + 20000);
    assert_true(rx.clock >= last_cmd + 200000);
    int64_t held = rx.clock;
    send_cmd(l, 0.1, 0.0);
    until_clock(l, held + 100000);
    stop_sim();
    lcm_destroy(l);
}

/* ---- the clock test: a component with a 10 Hz timer on --clock sim ---- */
static struct {
    long ticks;
    int64_t first, last;
    int64_t max_gap, min_gap;
    int64_t overruns;
} ck;

static void on_tick(marie_component_t *c, int64_t overruns)
{
    int64_t now = marie_component_now(c);
    ck.overruns += overruns;
    if (ck.ticks) {
        int64_t gap = now - ck.last;
        if (gap > ck.max_gap) ck.max_gap = gap;
        if (gap < ck.min_gap) ck.min_gap = gap;
    } else {
        ck.first = now;
    }
    ck.last = now;
    ck.ticks++;
}

static int clock_init(marie_component_t *c)
{
    return marie_component_every(c, 10.0, on_tick) ? 0 : -1;
}

static void test_timers_follow_sim_clock(void **state)
{
    memset(&ck, 0, sizeof(ck));
    ck.min_gap = INT64_MAX;
    static const marie_port_spec_t no_ports[] = { { NULL } };
    static const marie_param_spec_t no_params[] = { { NULL } };
    static const marie_component_def_t def = { .kind = "clocktest", .ports = no_ports,
                                               .params = no_params, .on_init = clock_init };
    char *argv[] = { "clocktest", "--clock", "sim", "--name", "clocktest", NULL };
    marie_errors_t errs = { 0 };
    marie_component_t *c = marie_component_create(&def, 5, argv, NULL, &errs);
    marie_errors_print(&errs, stderr);
    assert_non_null(c);
    const char *why;
    assert_int_equal(marie_component_command(c, MARIE_CMD_INIT, &why), 0);
    assert_int_equal(marie_component_command(c, MARIE_CMD_START, &why), 0);
    const char *extra[] = { "--speed", "10", NULL };
    start_sim(extra);
    int64_t w0 = marie_mono_us(), end = w0 + WALL_LIMIT_US;
    while (marie_component_now(c) < 6000000 && marie_mono_us() < end)
        marie_loop_run_once(marie_component_loop(c), 100);
    double wall = (marie_mono_us() - w0) / 1e6;
    stop_sim();
    double sim = (ck.last - ck.first) / 1e6;
    fprintf(stderr, "%ld ticks (%lld overruns) over %.2f s of sim time (%.2f s of wall time); gaps %.3f..%.3f s\n",
            ck.ticks, (long long)ck.overruns, sim, wall, ck.min_gap / 1e6, ck.max_gap / 1e6);
    assert_true(marie_component_now(c) >= 6000000);
    /* 10 Hz of simulated time: one tick per 100 ms of sim time, to the clock's 10 ms step. */
    assert_true(ck.ticks >= 55);
    assert_true(labs(lround(sim * 10) + 1 - (ck.ticks + ck.overruns)) <= 1);
    assert_true(ck.overruns <= 3);
    /* (Single gaps vary: a burst of clock messages read in one go on a loaded machine makes
     * one tick late and the next early; the count is what must hold.) */
    marie_component_destroy(c);
}

/* The simulator given `extra` refuses to start, with both needles in its heartbeat's reason. */
static void expect_refused(const char *const *extra, const char *needle1, const char *needle2)
{
    lcm_t *l = bus();
    start_sim(extra);
    int64_t end = marie_mono_us() + WALL_LIMIT_US;
    while (!rx.failed && marie_mono_us() < end)
        lcm_handle_timeout(l, 100);
    stop_sim();
    fprintf(stderr, "refused: %s\n", rx.reason);
    assert_true(rx.failed);
    assert_non_null(strstr(rx.reason, needle1));
    assert_non_null(strstr(rx.reason, needle2));
    lcm_destroy(l);
}

static void test_bad_world_refused(void **state)
{
    const char *extra[] = { "--world", "tests/data/map/zero_resolution.yaml", NULL };
    expect_refused(extra, "zero_resolution.yaml:2:", "resolution");
}

/* A start the robot cannot take is refused with the reason in the heartbeat. */
static void expect_start_refused(const char *x, const char *y, const char *why)
{
    const char *extra[] = { "--param", x, "--param", y, NULL };
    expect_refused(extra, why, "start: auto");
}

static void test_start_in_a_wall_refused(void **state)
{
    expect_start_refused("start_x=7.1", "start_y=2.0", "in an occupied cell");        /* wall A */
}

static void test_start_touching_a_wall_refused(void **state)
{
    expect_start_refused("start_x=6.9", "start_y=2.0", "with a wall under the robot"); /* chassis over wall A */
}

static void test_start_off_the_map_refused(void **state)
{
    expect_start_refused("start_x=-5", "start_y=2.0", "outside the map");
}

/* start: auto puts the robot at the nearest spot with room for it, and it stays there. */
static void test_start_auto_finds_room(void **state)
{
    lcm_t *l = bus();
    const char *extra[] = { "--param", "start_x=7.1", "--param", "start_y=2.0", "--param", "start=auto", NULL };
    start_sim(extra);
    int64_t end = marie_mono_us() + WALL_LIMIT_US;
    while (rx.truth.utime < 1000000 && !rx.failed && marie_mono_us() < end)
        lcm_handle_timeout(l, 100);
    stop_sim();
    double x = rx.truth.pose.x, y = rx.truth.pose.y;
    fprintf(stderr, "start auto: (%.3f, %.3f) after %.2f s\n", x, y, rx.truth.utime / 1e6);
    assert_false(rx.failed);
    assert_true(rx.truth.utime >= 1000000);
    /* Wall A spans x 7.0-7.2: the chassis' circle (0.30 m) plus margin fits only beside it,
     * and nearest means beside it, not far away; the physics did not throw it. */
    assert_true((x < 7.0 - 0.30 && x > 6.4) || (x > 7.2 + 0.30 && x < 7.9));
    assert_true(fabs(y - 2.0) < 0.1);
    lcm_destroy(l);
}

/* What the rest of the system sees: per non-MARIE channel, its type and rate. */
typedef struct {
    int n;
    char name[MAX_CH][64];
    int64_t hash[MAX_CH];
    double hz[MAX_CH];
} view_t;

static void snapshot(view_t *v)
{
    memset(v, 0, sizeof(*v));
    for (int i = 0; i < rx.n; i++) {
        if (strncmp(rx.ch[i].name, "MARIE_HEARTBEAT", 15) == 0 || strncmp(rx.ch[i].name, "MARIE_EVENT", 11) == 0 ||
            strncmp(rx.ch[i].name, "LCM_", 4) == 0 || strncmp(rx.ch[i].name, "MARIE_LIFECYCLE", 15) == 0 ||
            strcmp(rx.ch[i].name, "MOTOR_COMMAND") == 0)     /* the test's own */
            continue;
        snprintf(v->name[v->n], sizeof(v->name[0]), "%s", rx.ch[i].name);
        v->hash[v->n] = rx.ch[i].hash;
        v->hz[v->n] = rate(&rx.ch[i]);
        v->n++;
    }
}

/* Forget counts so far (start-up), keep the channel table. */
static void restart_counts(void)
{
    for (int i = 0; i < rx.n; i++) {
        rx.ch[i].count = 0;
        rx.ch[i].ngaps = 0;
    }
}

static int has(const char *ch)
{
    for (int i = 0; i < rx.n; i++)
        if (strcmp(rx.ch[i].name, ch) == 0 && rx.ch[i].count > 0)
            return 1;
    return 0;
}

/* Channel mode and device mode (marie-sim playing the devices, the real marie-drives,
 * marie-gyro and marie-lms200 reading them) give the system the same channels, types and
 * rates; and in device mode a motor command goes through CAN to the simulated wheels. */
static void test_channel_and_device_mode_agree(void **state)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    char bin[4][256];
    snprintf(bin[0], sizeof(bin[0]), "%s/bin/marie-drives", b);
    snprintf(bin[1], sizeof(bin[1]), "%s/bin/marie-gyro", b);
    snprintf(bin[2], sizeof(bin[2]), "%s/bin/marie-lms200", b);
    for (int i = 0; i < 3; i++)
        if (access(bin[i], X_OK) != 0) {
            fprintf(stderr, "%s is not built: build it first (make %s)\n", bin[i], bin[i]);
            fail();
        }

    /* Channel mode. */
    lcm_t *l = bus();
    const char *chan_args[] = { "--speed", "4", NULL };
    start_sim(chan_args);
    until_clock(l, 1000000);
    restart_counts();
    until_clock(l, 6000000);
    stop_sim();
    view_t a;
    snapshot(&a);
    lcm_destroy(l);

    /* Device mode. */
    char dir[] = "/tmp/marie-sim-test.XXXXXX";
    assert_non_null(mkdtemp(dir));
    char can[128], can_url[160], link[128], p_can[200], p_dev[200];
    snprintf(can, sizeof(can), "%s/can", dir);
    snprintf(can_url, sizeof(can_url), "emu:%s", can);
    snprintf(link, sizeof(link), "%s/lms200", dir);
    snprintf(p_can, sizeof(p_can), "can=%s", can_url);
    snprintf(p_dev, sizeof(p_dev), "device=%s", link);
    char p_can_sim[200], p_link_sim[200];
    snprintf(p_can_sim, sizeof(p_can_sim), "can=%s", can_url);
    snprintf(p_link_sim, sizeof(p_link_sim), "laser_link=%s", link);
    l = bus();
    const char *dev_args[] = { "--mode", "device", "--speed", "1", "--param", p_can_sim, "--param", p_link_sim, NULL };
    start_sim(dev_args);
    until_clock(l, 100000);             /* the bus and the pty exist now */
    const char *drives[] = { bin[0], "--clock", "sim", "--param", p_can, "--param", "track_width=0.4", NULL };
    const char *gyro[] = { bin[1], "--clock", "sim", "--param", p_can, NULL };
    const char *lms[] = { bin[2], "--clock", "sim", "--param", p_dev, "--param", "resolution=1", NULL };
    drv_pids[0] = spawn(drives);
    drv_pids[1] = spawn(gyro);
    drv_pids[2] = spawn(lms);
    /* Wait (bounded) for the drivers to bring their devices up. */
    int64_t end = marie_mono_us() + WALL_LIMIT_US;
    while (!(has("WHEEL_ENCODERS") && has("GYRO") && has("LASER")) && marie_mono_us() < end)
        lcm_handle_timeout(l, 100);
    assert_true(has("WHEEL_ENCODERS") && has("GYRO") && has("LASER"));
    until_clock(l, rx.clock + 500000);
    restart_counts();
    int64_t from = rx.clock;
    double x0 = rx.truth.pose.x;
    int32_t t0 = rx.enc.left_ticks;
    int beams = rx.laser_beams;
    until_clock(l, from + 2000000);
    /* Drive: MOTOR_COMMAND -> marie-drives -> CAN -> virtual drives -> simulated wheels. */
    for (int64_t t = rx.clock; t < from + 5000000; t += 100000) {
        send_cmd(l, 0.3, 0.0);
        until_clock(l, t + 100000);
    }
    view_t d;
    snapshot(&d);
    double moved = rx.truth.pose.x - x0;
    int32_t ticks = rx.enc.left_ticks - t0;
    stop_drivers();
    stop_sim();
    lcm_destroy(l);
    unlink(link);
    unlink(can);
    rmdir(dir);

    fprintf(stderr, "device mode: moved %.3f m, %d ticks, %d beams\n", moved, ticks, beams);
    fprintf(stderr, "%-16s %-18s %-10s %-18s %s\n", "channel", "type (channel)", "Hz", "type (device)", "Hz");
    for (int i = 0; i < a.n; i++) {
        int k = -1;
        for (int j = 0; j < d.n; j++)
            if (strcmp(a.name[i], d.name[j]) == 0)
                k = j;
        fprintf(stderr, "%-16s %016llx   %-10.2f %016llx   %.2f\n", a.name[i], (unsigned long long)a.hash[i], a.hz[i],
                k >= 0 ? (unsigned long long)d.hash[k] : 0ULL, k >= 0 ? d.hz[k] : 0.0);
        assert_true(k >= 0);
        assert_true(a.hash[i] == d.hash[k]);
        assert_true(fabs(a.hz[i] - d.hz[k]) < 0.05 * a.hz[i]);
    }
    assert_int_equal(a.n, d.n);
    assert_int_equal(beams, 181);
    assert_true(moved > 0.3 * 3 * 0.7 && moved < 0.3 * 3 * 1.2);
    assert_true(ticks > 0.7 * moved / (2 * M_PI * 0.1) * 4096);
}

/* Sim ms from `t0` (sim us) until the true robot speed, over 50 ms of sim time, is under
 * 1 cm/s; the robot keeps being commanded (0.5 m/s on a 1 m circle that keeps it clear of the
 * walls), as a live behaviour layer would. -1 if not within 5 s of wall time. */
static int sim_ms_to_rest(lcm_t *l, int64_t t0)
{
    struct { int64_t t; double x, y; } ring[64];
    int n = 0;
    int64_t last = -1, end = marie_mono_us() + 5000000, next_cmd = 0;
    while (marie_mono_us() < end) {
        if (marie_mono_us() >= next_cmd) {
            send_cmd(l, 0.5, 0.5);
            next_cmd = marie_mono_us() + 100000;
        }
        lcm_handle_timeout(l, 10);
        if (rx.truth.utime == last)
            continue;
        last = rx.truth.utime;
        ring[n % 64].t = last;
        ring[n % 64].x = rx.truth.pose.x;
        ring[n % 64].y = rx.truth.pose.y;
        n++;
        for (int k = 1; k < 64 && k < n; k++) {
            int j = (n - 1 - k) % 64;
            if (last - ring[j].t < 50000)
                continue;
            double v = hypot(rx.truth.pose.x - ring[j].x, rx.truth.pose.y - ring[j].y) / ((last - ring[j].t) / 1e6);
            if (v < 0.01 && ring[j].t >= t0)
                return (int)((ring[j].t - t0) / 1000);
            break;
        }
    }
    return -1;
}

static bool at_speed(void)
{
    return rx.enc.status == MARIE_WHEEL_ENCODERS_T_STATUS_OK && (rx.enc.left_velocity + rx.enc.right_velocity) / 2 > 4.5;
}

/* Drive at 0.5 m/s for 2 s of sim time (the drives enabled first), then send marie-drives `sig`. */
static int sim_rest_after(lcm_t *l, pid_t drives, int sig)
{
    assert_true(drives > 0);                    /* never signal a process group */
    int64_t end = marie_mono_us() + WALL_LIMIT_US;
    while (!at_speed() && marie_mono_us() < end) {
        send_cmd(l, 0.5, 0.5);
        int64_t t = rx.clock;
        until_clock(l, t + 100000);
    }
    assert_true(at_speed());
    for (int64_t t = rx.clock, from = rx.clock; t < from + 2000000; t += 100000) {
        send_cmd(l, 0.5, 0.5);
        until_clock(l, t + 100000);
    }
    /* The sim time of the kill: the newest clock the bus holds for us (a test that was slow to
     * read it would count the time it lagged as the robot's). */
    while (lcm_handle_timeout(l, 0) > 0)
        ;
    int64_t t0 = rx.clock;
    kill(drives, sig);
    return sim_ms_to_rest(l, t0);
}

/* Device mode at real-time speed: the virtual drives watch marie-drives' heartbeat, so the
 * simulated robot stops when marie-drives is killed, or frozen, at 0.5 m/s. */
static void test_device_mode_robot_stops_when_drives_die(void **state)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    char bin[256];
    snprintf(bin, sizeof(bin), "%s/bin/marie-drives", b);
    char dir[] = "/tmp/marie-sim-test.XXXXXX";
    assert_non_null(mkdtemp(dir));
    char can[128], p_can[200], p_link[200], link[128];
    snprintf(can, sizeof(can), "%s/can", dir);
    snprintf(link, sizeof(link), "%s/lms200", dir);
    snprintf(p_can, sizeof(p_can), "can=emu:%s", can);
    snprintf(p_link, sizeof(p_link), "laser_link=%s", link);
    lcm_t *l = bus();
    const char *dev_args[] = { "--mode", "device", "--speed", "1", "--param", p_can, "--param", p_link, NULL };
    start_sim(dev_args);
    until_clock(l, 100000);
    const char *drives[] = { bin, "--clock", "sim", "--param", p_can, "--param", "fault_reset_delay=0.3", NULL };
    drv_pids[0] = spawn(drives);
    int killed = sim_rest_after(l, drv_pids[0], SIGKILL);
    waitpid(drv_pids[0], NULL, 0);
    drv_pids[0] = spawn(drives);                 /* takes the faulted drives over again */
    int frozen = sim_rest_after(l, drv_pids[0], SIGSTOP);
    kill(drv_pids[0], SIGCONT);
    stop_drivers();
    stop_sim();
    lcm_destroy(l);
    unlink(link);
    unlink(can);
    rmdir(dir);
    fprintf(stderr, "device mode: robot at rest %d ms (sim) after SIGKILL, %d ms after SIGSTOP of marie-drives\n",
            killed, frozen);
    assert_int_equal(rx.collisions, 0);         /* at rest by itself, not against a wall */
    assert_true(killed >= 0 && killed <= 300);
    assert_true(frozen >= 0 && frozen <= 300);
}

static int teardown(void **state)
{
    stop_drivers();
    stop_sim();
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_channels_types_rates, teardown),
        cmocka_unit_test_teardown(test_motor_command_and_watchdog, teardown),
        cmocka_unit_test_teardown(test_estop, teardown),
        cmocka_unit_test_teardown(test_seeded_runs_repeat, teardown),
        cmocka_unit_test_teardown(test_wall_collision_counted, teardown),
        cmocka_unit_test_teardown(test_lockstep, teardown),
        cmocka_unit_test_teardown(test_timers_follow_sim_clock, teardown),
        cmocka_unit_test_teardown(test_bad_world_refused, teardown),
        cmocka_unit_test_teardown(test_start_in_a_wall_refused, teardown),
        cmocka_unit_test_teardown(test_start_touching_a_wall_refused, teardown),
        cmocka_unit_test_teardown(test_start_off_the_map_refused, teardown),
        cmocka_unit_test_teardown(test_start_auto_finds_room, teardown),
        cmocka_unit_test_teardown(test_channel_and_device_mode_agree, teardown),
        cmocka_unit_test_teardown(test_device_mode_robot_stops_when_drives_die, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
