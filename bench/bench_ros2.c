/* bench_ros2: marie-ros2's cost. One-way latency LCM -> bridge -> DDS -> a ROS 2 reader for
 * LaserScan and Odometry against DDS alone (a writer in another process, same reader, same
 * run); 640x480 RGB frames at 30 Hz through it (lost frames); the bridge's CPU while it carries
 * the Spartacus channel set at its rates. */
#include <math.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "adapters/ros2/ros2_conv.h"
#include "bench/bench.h"
#include "core/lcm.h"
#include "core/procstat.h"
#include "core/time.h"
#include "ros2_types.h"
#include "tests/proc.h"

#define N_LAT 400
#define LAT_HZ 100
#define N_IMG 150

enum { SCAN, ODOM, SCAN_DIRECT, ODOM_DIRECT, IMAGE, NSTREAM };
static const char *const topics[NSTREAM] = {"/scan", "/odom", "/scan_direct", "/odom_direct", "/image"};
static int64_t lat[NSTREAM][N_LAT];
static atomic_int nlat[NSTREAM];
static atomic_int recording;

static int64_t stamp_us(const builtin_interfaces_msg_dds__Time_ *t) { return ros2_utime(t->sec, t->nanosec); }

static void on_data(dds_entity_t rd, void *arg)
{
    int s = (int)(intptr_t)arg;
    void *samples[8] = {NULL};
    dds_sample_info_t info[8];
    int n = dds_take(rd, samples, info, 8, 8);
    int64_t now = marie_wall_us();
    for (int i = 0; i < n; i++) {
        if (!info[i].valid_data || !atomic_load(&recording))
            continue;
        const std_msgs_msg_dds__Header_ *h = samples[i];   /* every stream's message starts with its header */
        int k = atomic_fetch_add(&nlat[s], 1);
        if (k < N_LAT)
            lat[s][k] = now - stamp_us(&h->stamp);
    }
    if (n > 0)
        dds_return_loan(rd, samples, n);
}

static void fill_scan(marie_laser_scan_t *m, float *ranges)
{
    for (int i = 0; i < 181; i++)
        ranges[i] = 2.0f + 0.01f * (float)i;
    *m = (marie_laser_scan_t){marie_wall_us(), -1.5708f, 0.017453f, 0.1f, 8.0f, 181, ranges, 0, NULL};
}

/* DDS alone: a process of its own writes what the bridge would, with its stamp taken at the write. */
static void direct_writer(int go)
{
    char c;
    if (read(go, &c, 1) != 1)
        _exit(1);
    dds_entity_t pp = dds_create_participant(0, NULL, NULL);
    dds_entity_t ws = dds_create_writer(pp, dds_create_topic(pp, &sensor_msgs_msg_dds__LaserScan__desc, "rt/scan_direct", NULL, NULL), NULL, NULL);
    dds_entity_t wo = dds_create_writer(pp, dds_create_topic(pp, &nav_msgs_msg_dds__Odometry__desc, "rt/odom_direct", NULL, NULL), NULL, NULL);
    sleep(2);   /* discovery */
    ros2_ctx_t x = {.frame = "laser", .child = "base_link"};
    float ranges[181];
    for (int i = 0; i < N_LAT; i++) {
        marie_laser_scan_t m;
        fill_scan(&m, ranges);
        sensor_msgs_msg_dds__LaserScan_ s;
        marie_odometry_t o = {.utime = marie_wall_us(), .pose = {1, 2, 0.5}, .v = 0.3};
        nav_msgs_msg_dds__Odometry_ od;
        ros2_arena_rewind(&x.arena);
        if (ros2_kind_find("laser", NULL)->to(&x, &m, &s) == 0)
            dds_write(ws, &s);
        if (ros2_kind_find("odometry", NULL)->to(&x, &o, &od) == 0)
            dds_write(wo, &od);
        usleep(1000000 / LAT_HZ);
    }
    sleep(1);
    dds_delete(pp);
    _exit(0);
}

static void report_latency(const char *what, int s, int base)
{
    int n = nlat[s] < N_LAT ? nlat[s] : N_LAT, nb = nlat[base] < N_LAT ? nlat[base] : N_LAT;
    double p50 = bench_percentile(lat[s], n, 0.5), p99 = bench_percentile(lat[s], n, 0.99);
    double b50 = bench_percentile(lat[base], nb, 0.5), b99 = bench_percentile(lat[base], nb, 0.99);
    char m[64];
    snprintf(m, sizeof m, "%s_p50", what);
    bench_row("bench_ros2", m, p50, "us", b50);
    snprintf(m, sizeof m, "%s_p99", what);
    bench_row("bench_ros2", m, p99, "us", b99);
    snprintf(m, sizeof m, "%s_added_p50", what);
    bench_row("bench_ros2", m, p50 - b50, "us", 0);
    fprintf(stderr, "%s: %d via the bridge, %d direct\n", what, n, nb);
}

static void publish_scan_odom(lcm_t *lcm)
{
    float ranges[181];
    for (int i = 0; i < N_LAT; i++) {
        marie_laser_scan_t m;
        fill_scan(&m, ranges);
        marie_lcm_publish_msg(lcm, "LASER", &marie_type_laser_scan_t, &m);
        marie_odometry_t o = {.utime = marie_wall_us(), .pose = {1, 2, 0.5}, .v = 0.3};
        marie_lcm_publish_msg(lcm, "ODOMETRY", &marie_type_odometry_t, &o);
        usleep(1000000 / LAT_HZ);
    }
    usleep(500000);
}

static int publish_images(lcm_t *lcm)
{
    size_t size = 640 * 480 * 3;
    uint8_t *px = malloc(size);
    for (size_t i = 0; i < size; i++)
        px[i] = (uint8_t)(i * 7);
    int sent = 0;
    int64_t t0 = marie_mono_us();
    for (int i = 0; i < N_IMG; i++) {
        marie_image_t im = {marie_wall_us(), 640, 480, 640 * 3, MARIE_IMAGE_T_FORMAT_RGB8, (int32_t)size, px};
        sent += marie_lcm_publish_msg(lcm, "CAMERA_IMAGE", &marie_type_image_t, &im) == 0;
        int64_t next = t0 + (int64_t)(i + 1) * 1000000 / 30 - marie_mono_us();
        if (next > 0)
            usleep((useconds_t)next);
    }
    usleep(500000);
    free(px);
    return sent;
}

/* The Spartacus set as the robot runs it: scans, odometry, poses at 10 Hz, the clock at 50 Hz,
 * 12 heartbeats a second, motor commands at 5 Hz, a 100-pose path every 2 s. */
static double spartacus_cpu(lcm_t *lcm, pid_t bridge, double seconds)
{
    int64_t cpu0, cpu1, rss, t0 = marie_mono_us();
    float ranges[181];
    marie_pose2d_t poses[100] = {{0}};
    marie_counter_t counters[4] = {{"a", 1}, {"b", 2}, {"c", 3}, {"d", 4}};
    marie_proc_usage(bridge, &cpu0, &rss);
    for (int tick = 0; tick < (int)(seconds * 50); tick++) {
        int64_t now = marie_wall_us();
        marie_sim_clock_t clk = {now, 1.0};
        marie_lcm_publish_msg(lcm, "MARIE_CLOCK", &marie_type_sim_clock_t, &clk);
        if (tick % 5 == 0) {
            marie_laser_scan_t m;
            fill_scan(&m, ranges);
            marie_odometry_t o = {.utime = now, .pose = {1, 2, 0.5}, .v = 0.3};
            marie_pose_cov_t p = {.utime = now, .frame = "map", .pose = {3, 4, 0.5}};
            marie_lcm_publish_msg(lcm, "LASER", &marie_type_laser_scan_t, &m);
            marie_lcm_publish_msg(lcm, "ODOMETRY", &marie_type_odometry_t, &o);
            marie_lcm_publish_msg(lcm, "POSE", &marie_type_pose_cov_t, &p);
        }
        if (tick % 10 == 0) {
            marie_motor_command_t mc = {now, 0.3, 0.1, "follow_path"};
            marie_lcm_publish_msg(lcm, "MOTOR_COMMAND", &marie_type_motor_command_t, &mc);
        }
        if (tick % 4 == 0 || tick % 25 == 1) {      /* 12.5 + 2 heartbeats a second */
            marie_heartbeat_t hb = {.utime = now, .component = "localizer", .host = "onboard2", .state = 2,
                                    .reason = "", .ncounters = 4, .counters = counters};
            marie_lcm_publish_msg(lcm, "MARIE_HEARTBEAT", &marie_type_heartbeat_t, &hb);
        }
        if (tick % 100 == 0) {
            marie_path_t path = {now, 1, 0, 100, poses};
            marie_lcm_publish_msg(lcm, "PATH", &marie_type_path_t, &path);
        }
        int64_t next = t0 + (int64_t)(tick + 1) * 20000 - marie_mono_us();
        if (next > 0)
            usleep((useconds_t)next);
    }
    marie_proc_usage(bridge, &cpu1, &rss);
    return 100.0 * (double)(cpu1 - cpu0) / (double)(marie_mono_us() - t0);
}

static const char system_text[] =
    "system: bench-ros2\n"
    "ros2:\n"
    "  topics:\n"
    "    - {channel: LASER, topic: /scan}\n"
    "    - {channel: ODOMETRY, topic: /odom}\n"
    "    - {channel: POSE, topic: /amcl_pose}\n"
    "    - {channel: PATH, topic: /plan}\n"
    "    - {channel: MOTOR_COMMAND, topic: /marie/motor_command}\n"
    "    - {channel: MARIE_CLOCK, topic: /clock}\n"
    "    - {channel: MARIE_HEARTBEAT, topic: /diagnostics}\n"
    "    - {channel: CAMERA_IMAGE, topic: /image, qos: default}\n"
    "components:\n"
    "  ros2: {exec: marie-ros2}\n";

int main(int argc, char **argv)
{
    int go[2];
    if (pipe(go) < 0)
        return 1;
    pid_t child = fork();
    if (child == 0) {
        close(go[1]);
        direct_writer(go[0]);
    }
    close(go[0]);
    char sys[] = "/tmp/bench_ros2_XXXXXX.yaml", bin[512];
    snprintf(bin, sizeof bin, "%s/bin/marie-ros2", getenv("B") ? getenv("B") : "build");
    if (test_write_temp(sys, 5, system_text) < 0)
        return 1;
    char *const args[] = {bin, "--system", sys, "--name", "ros2", NULL};
    pid_t bridge = test_spawn(args, "/dev/null");
    lcm_t *lcm = marie_lcm_create(NULL);
    dds_entity_t pp = dds_create_participant(0, NULL, NULL);
    dds_listener_t *l[NSTREAM];
    const dds_topic_descriptor_t *desc[NSTREAM] = {&sensor_msgs_msg_dds__LaserScan__desc, &nav_msgs_msg_dds__Odometry__desc,
                                                  &sensor_msgs_msg_dds__LaserScan__desc, &nav_msgs_msg_dds__Odometry__desc,
                                                  &sensor_msgs_msg_dds__Image__desc};
    dds_qos_t *qos = dds_create_qos();
    dds_qset_reliability(qos, DDS_RELIABILITY_BEST_EFFORT, 0);
    dds_qset_history(qos, DDS_HISTORY_KEEP_LAST, 5);
    /* frames that must all arrive go reliably (the entry's qos: default), as a recorder asks */
    dds_qos_t *reliable = dds_create_qos();
    dds_qset_reliability(reliable, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    dds_qset_history(reliable, DDS_HISTORY_KEEP_LAST, 10);
    for (int s = 0; s < NSTREAM; s++) {
        char name[64];
        snprintf(name, sizeof name, "rt%s", topics[s]);
        l[s] = dds_create_listener((void *)(intptr_t)s);
        dds_lset_data_available(l[s], on_data);
        dds_create_reader(pp, dds_create_topic(pp, desc[s], name, NULL, NULL), s == IMAGE ? reliable : qos, l[s]);
    }
    if (bridge < 0 || !lcm || pp < 0)
        return 1;
    sleep(3);   /* the bridge up, discovery done */
    atomic_store(&recording, 1);
    if (write(go[1], "g", 1) != 1)
        return 1;
    waitpid(child, NULL, 0);
    publish_scan_odom(lcm);
    report_latency("scan_latency", SCAN, SCAN_DIRECT);
    report_latency("odom_latency", ODOM, ODOM_DIRECT);
    int sent = publish_images(lcm);
    bench_row("bench_ros2", "rgb640x480_30hz_received", nlat[IMAGE], "frames", sent);
    bench_row("bench_ros2", "rgb640x480_30hz_lost", sent - nlat[IMAGE], "frames", 0);
    atomic_store(&recording, 0);
    double cpu = spartacus_cpu(lcm, bridge, 10.0);
    bench_row("bench_ros2", "spartacus_set_cpu", cpu, "%core", 5.0);
    test_stop(bridge);
    unlink(sys);
    dds_delete(pp);
    marie_lcm_destroy(lcm);
    return 0;
}
