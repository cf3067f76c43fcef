/* test_drives_emu: marie-drives and marie-gyro as processes against marie-vcan-devices on the
 * emulated bus (marie-canbus), observed over LCM and by an independent client on the bus:
 * enabling, kinematics, command timeout, e-stop (and the SYNC period under e-stop messages),
 * the wheels stopping when marie-drives is killed or frozen, EMCY counting, drive fault and
 * reset, gyro bias at standstill, bus-off and the bus daemon going away. */
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include <lcm/lcm.h>

#include "core/config.h"
#include "core/time.h"
#include "hw/can/can.h"
#include "lcmtypes/marie_estop_t.h"
#include "lcmtypes/marie_gyro_t.h"
#include "lcmtypes/marie_heartbeat_t.h"
#include "lcmtypes/marie_lifecycle_command_t.h"
#include "lcmtypes/marie_motor_command_t.h"
#include "lcmtypes/marie_wheel_encoders_t.h"
#include "tests/proc.h"


static char sock[96], url[112], bindir[256], logdir[256];
static pid_t bus_pid, dev_pid, drv_pid, gyr_pid;
static lcm_t *lcm;
static can_bus_t *spy;
static marie_wheel_encoders_t_subscription_t *sub_enc;
static marie_gyro_t_subscription_t *sub_gyro;
static marie_heartbeat_t_subscription_t *sub_hb;
static marie_wheel_encoders_t enc;
static int nenc;
static marie_gyro_t gyr;
static int ngyro;
static struct { int64_t faults, fault_resets, emcy, bus_off, disconnected, connected, bad_input; int n; } hb_drives;
static const char *drives_args[] = { "--param", url, "--param", "fault_reset_delay=0.5", NULL };

static pid_t spawn(const char *name, char *const args[])
{
    char path[512], log[512];
    snprintf(path, sizeof path, "%s/%s", bindir, name);
    snprintf(log, sizeof log, "%s/test_drives_emu.%s.log", logdir, name);
    char *argv[24];
    int n = 0;
    argv[n++] = path;
    for (int i = 0; args[i] && n < 23; i++)
        argv[n++] = args[i];
    argv[n] = NULL;
    return test_spawn(argv, log);
}

static void stop(pid_t *pid)
{
    test_stop(*pid);
    *pid = 0;
}

static void on_enc(const lcm_recv_buf_t *rb, const char *ch, const marie_wheel_encoders_t *m, void *u)
{
    enc = *m;
    nenc++;
}

static void on_gyro(const lcm_recv_buf_t *rb, const char *ch, const marie_gyro_t *m, void *u)
{
    gyr = *m;
    ngyro++;
}

static int64_t counter(const marie_heartbeat_t *m, const char *name)
{
    for (int i = 0; i < m->ncounters; i++)
        if (strcmp(m->counters[i].name, name) == 0)
            return m->counters[i].value;
    return 0;
}

static void on_hb(const lcm_recv_buf_t *rb, const char *ch, const marie_heartbeat_t *m, void *u)
{
    if (strcmp(m->component, "marie-drives") != 0)
        return;
    hb_drives.faults = counter(m, "faults");
    hb_drives.fault_resets = counter(m, "fault_resets");
    hb_drives.emcy = counter(m, "emcy");
    hb_drives.bus_off = counter(m, "bus_off");
    hb_drives.disconnected = counter(m, "disconnected");
    hb_drives.connected = counter(m, "connected");
    hb_drives.bad_input = m->bad_input;
    hb_drives.n++;
}

static double cmd_v, cmd_w;
static bool commanding;
static int64_t last_cmd;

/* Pump LCM for up to `secs`, sending motor commands at 10 Hz while commanding, until cond(). */
static bool wait_for(bool (*cond)(void), double secs)
{
    int64_t end = marie_mono_us() + (int64_t)(secs * 1e6);
    while (marie_mono_us() < end) {
        if (commanding && marie_mono_us() - last_cmd > 100000) {
            marie_motor_command_t m = { .utime = marie_wall_us(), .v = cmd_v, .omega = cmd_w, .source = "test" };
            marie_motor_command_t_publish(lcm, "MOTOR_COMMAND", &m);
            last_cmd = marie_mono_us();
        }
        lcm_handle_timeout(lcm, 50);
        if (cond && cond())
            return true;
    }
    return cond ? cond() : true;
}

static bool enc_ok(void) { return nenc > 0 && enc.status == MARIE_WHEEL_ENCODERS_T_STATUS_OK; }
static bool wheels_at_command(void)
{
    /* v = 0.5 m/s, omega = 0.4 rad/s, r = 0.1 m, track 0.5 m: 4 and 6 rad/s */
    return enc_ok() && fabs(enc.left_velocity - 4.0) < 0.05 && fabs(enc.right_velocity - 6.0) < 0.05;
}
static bool wheels_stopped(void) { return nenc > 0 && fabs(enc.left_velocity) < 1e-3 && fabs(enc.right_velocity) < 1e-3; }
static bool enc_estop(void) { return enc.status == MARIE_WHEEL_ENCODERS_T_STATUS_ESTOP && wheels_stopped(); }
static bool fault_seen(void) { return hb_drives.faults >= 1; }
static bool recovered(void) { return hb_drives.fault_resets >= 1 && enc_ok(); }
static bool gyro_turning(void) { return ngyro > 0 && gyr.bias_valid && fabs(gyr.yaw_rate - 0.4) < 0.02; }
static bool gyro_bias_learned(void) { return ngyro > 0 && gyr.bias_valid && fabs(gyr.bias - 0.01) < 0.003; }
static bool bus_off_counted(void) { return hb_drives.bus_off >= 1; }
static bool reconnected(void) { return hb_drives.connected >= 1 && enc_ok(); }

static int group_setup(void **state)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    snprintf(bindir, sizeof bindir, "%s/bin", b);
    snprintf(logdir, sizeof logdir, "%s/test-logs", b);
    snprintf(sock, sizeof sock, "/tmp/marie-test-drives-emu-%d.sock", getpid());
    snprintf(url, sizeof url, "can=emu:%s", sock);
    setenv("MARIE_LOG", "info", 0);
    const char *names[] = { "marie-canbus", "marie-vcan-devices", "marie-drives", "marie-gyro" };
    for (int i = 0; i < 4; i++) {
        char log[512];
        snprintf(log, sizeof log, "%s/test_drives_emu.%s.log", logdir, names[i]);
        unlink(log);    /* one run per log; a restarted program appends */
    }
    bus_pid = spawn("marie-canbus", (char *[]){ sock, NULL });
    for (int i = 0; i < 50 && access(sock, F_OK) != 0; i++)
        usleep(100000);
    char devurl[112];
    snprintf(devurl, sizeof devurl, "emu:%s", sock);
    dev_pid = spawn("marie-vcan-devices", (char *[]){ "--can", devurl, "--gyro-noise", "0.0005", NULL });
    drv_pid = spawn("marie-drives", (char **)drives_args);
    gyr_pid = spawn("marie-gyro", (char *[]){ "--param", url, "--param", "standstill_window=0.3", NULL });
    lcm = lcm_create(marie_default_url());
    if (!lcm || bus_pid <= 0 || dev_pid <= 0 || drv_pid <= 0 || gyr_pid <= 0)
        return -1;
    sub_enc = marie_wheel_encoders_t_subscribe(lcm, "WHEEL_ENCODERS", on_enc, NULL);
    sub_gyro = marie_gyro_t_subscribe(lcm, "GYRO", on_gyro, NULL);
    sub_hb = marie_heartbeat_t_subscribe(lcm, "MARIE_HEARTBEAT", on_hb, NULL);
    return 0;
}

static int group_teardown(void **state)
{
    stop(&gyr_pid);
    stop(&drv_pid);
    stop(&dev_pid);
    stop(&bus_pid);
    can_bus_close(spy);
    if (lcm) {
        marie_wheel_encoders_t_unsubscribe(lcm, sub_enc);
        marie_gyro_t_unsubscribe(lcm, sub_gyro);
        marie_heartbeat_t_unsubscribe(lcm, sub_hb);
        lcm_destroy(lcm);
    }
    unlink(sock);
    return 0;
}

static void drives_enable_and_publish_encoders(void **state)
{
    commanding = true;
    cmd_v = cmd_w = 0;
    assert_true(wait_for(enc_ok, 15));
    int before = nenc;
    wait_for(NULL, 1.0);
    assert_true(nenc - before >= 5);            /* published continuously (20 Hz nominal) */
    assert_int_equal(enc.ticks_per_rev, 4096);
    /* commanded to stand still: the gyro learns its bias (0.01 rad/s in the virtual gyro) */
    assert_true(wait_for(gyro_bias_learned, 10));
}

static void motor_command_turns_wheels_by_kinematics(void **state)
{
    /* an independent client on the bus sees the SYNC and the drives' RPDO1 */
    char u[112];
    snprintf(u, sizeof u, "emu:%s", sock);
    spy = can_bus_open(u);
    assert_non_null(spy);
    cmd_v = 0.5;
    cmd_w = 0.4;
    assert_true(wait_for(wheels_at_command, 10));
    int syncs = 0, rpdo_left = 0;
    int32_t left_target = 0;
    struct can_frame f;
    while (can_bus_read(spy, &f) == 1) {
        if (f.can_id == 0x080 && f.len == 0)
            syncs++;
        if (f.can_id == 0x201 && f.len == 6) {
            rpdo_left++;
            memcpy(&left_target, f.data + 2, 4);
        }
    }
    can_bus_close(spy);
    spy = NULL;
    assert_true(syncs > 10);
    assert_true(rpdo_left > 10);
    /* 4 rad/s * 4096 / 2pi increments/s, little-endian in bytes 2..5 */
    assert_int_equal(left_target, (int32_t)lround(4.0 * 4096 / (2 * M_PI)));
    assert_true(enc.left_ticks != 0);
    /* the gyro sees the yaw rate of the base (omega = 0.4), bias removed */
    assert_true(wait_for(gyro_turning, 15));
}

static void command_timeout_stops_wheels(void **state)
{
    commanding = false;
    assert_true(wait_for(wheels_stopped, 10));
    assert_int_equal(enc.status, MARIE_WHEEL_ENCODERS_T_STATUS_OK);
    /* standing still again: the bias holds and the rate reads zero */
    assert_true(wait_for(gyro_bias_learned, 10));
    assert_true(fabs(gyr.yaw_rate) < 0.01);
}

static void estop_stops_and_release_resumes(void **state)
{
    commanding = true;
    cmd_v = 0.5;
    cmd_w = 0.4;
    assert_true(wait_for(wheels_at_command, 10));
    marie_estop_t e = { .utime = marie_wall_us(), .pressed = 1, .source = "test" };
    marie_estop_t_publish(lcm, "ESTOP", &e);
    assert_true(wait_for(enc_estop, 10));
    e.pressed = 0;
    marie_estop_t_publish(lcm, "ESTOP", &e);
    assert_true(wait_for(wheels_at_command, 10));
}

/* 0x606C of a drive read over SDO by the test, an independent client on the bus; INT32_MIN
 * when the drive does not answer within 100 ms. */
static int32_t drive_velocity(can_bus_t *bus, uint8_t node)
{
    struct can_frame req = { .can_id = 0x600u + node, .len = 8, .data = { 0x40, 0x6C, 0x60, 0 } }, f;
    can_bus_write(bus, &req);
    int64_t end = marie_mono_us() + 100000;
    for (int64_t now = marie_mono_us(); now < end; now = marie_mono_us()) {
        struct pollfd p = { .fd = can_bus_fd(bus), .events = POLLIN };
        if (poll(&p, 1, (int)((end - now) / 1000) + 1) <= 0)
            continue;
        while (can_bus_read(bus, &f) == 1)
            if (f.can_id == 0x580u + node && f.len == 8 && f.data[0] == 0x43 && f.data[1] == 0x6C && f.data[2] == 0x60)
                return (int32_t)(f.data[4] | f.data[5] << 8 | f.data[6] << 16 | (uint32_t)f.data[7] << 24);
    }
    return INT32_MIN;
}

/* Drive at 0.5 m/s, send marie-drives `sig`, and return the ms until both drives report
 * 0x606C == 0 (-1: not within 2 s). */
static int ms_to_standstill_after(int sig)
{
    assert_true(drv_pid > 0);                   /* never signal a process group */
    commanding = true;
    cmd_v = 0.5;
    cmd_w = 0;
    assert_true(wait_for(enc_ok, 15));
    wait_for(NULL, 1.0);                         /* at speed: 5 rad/s at each wheel */
    char u[112];
    snprintf(u, sizeof u, "emu:%s", sock);
    can_bus_t *bus = can_bus_open(u);
    assert_non_null(bus);
    bool at_speed = false;                      /* 5 rad/s = 3260 increments/s */
    for (int64_t end = marie_mono_us() + 10000000; !at_speed && marie_mono_us() < end;) {
        at_speed = drive_velocity(bus, 1) > 3000 && drive_velocity(bus, 2) > 3000;
        wait_for(NULL, 0.05);
    }
    if (!at_speed)
        can_bus_close(bus);
    assert_true(at_speed);
    int64_t t0 = marie_mono_us();
    kill(drv_pid, sig);
    int ms = -1;
    while (marie_mono_us() - t0 < 2000000) {
        int32_t l = drive_velocity(bus, 1), r = drive_velocity(bus, 2);
        if (l == 0 && r == 0) {
            ms = (int)((marie_mono_us() - t0) / 1000);
            break;
        }
    }
    can_bus_close(bus);
    return ms;
}

/* The drives watch marie-drives' heartbeat (0x1016): killed at speed, the wheels stop. */
static void killed_master_stops_the_wheels(void **state)
{
    int ms = ms_to_standstill_after(SIGKILL);
    waitpid(drv_pid, NULL, 0);
    /* a new marie-drives takes them over: reset communication, fault reset, driving again */
    drv_pid = spawn("marie-drives", (char **)drives_args);
    print_message("drives at 0x606C = 0 %d ms after SIGKILL of marie-drives\n", ms);
    assert_true(ms >= 0 && ms <= 300);
    cmd_w = 0.4;
    assert_true(wait_for(wheels_at_command, 20));
}

/* Frozen (SIGSTOP) is dead to the drives too; thawed, it takes them over again. */
static void frozen_master_stops_the_wheels(void **state)
{
    int ms = ms_to_standstill_after(SIGSTOP);
    kill(drv_pid, SIGCONT);
    print_message("drives at 0x606C = 0 %d ms after SIGSTOP of marie-drives\n", ms);
    assert_true(ms >= 0 && ms <= 300);
    cmd_w = 0.4;
    assert_true(wait_for(wheels_at_command, 20));
}

/* An e-stop source repeating "pressed" at 20 Hz must not add SYNCs: 0x1006 is 20 ms. */
static void estop_messages_keep_the_sync_period(void **state)
{
    char u[112];
    snprintf(u, sizeof u, "emu:%s", sock);
    spy = can_bus_open(u);
    assert_non_null(spy);
    marie_estop_t e = { .utime = marie_wall_us(), .pressed = 1, .source = "test" };
    int64_t last_sync = 0, min_gap = INT64_MAX, t0 = marie_mono_us();
    int syncs = 0;
    for (int k = 0; k < 30; k++) {
        marie_estop_t_publish(lcm, "ESTOP", &e);
        int64_t end = marie_mono_us() + 50000;
        while (marie_mono_us() < end) {
            lcm_handle_timeout(lcm, 5);
            struct can_frame f;
            while (can_bus_read(spy, &f) == 1) {
                if (f.can_id != 0x080)
                    continue;
                int64_t now = marie_mono_us();
                if (last_sync && now - last_sync < min_gap)
                    min_gap = now - last_sync;
                last_sync = now;
                syncs++;
            }
        }
    }
    double secs = (marie_mono_us() - t0) / 1e6;
    can_bus_close(spy);
    spy = NULL;
    e.pressed = 0;
    marie_estop_t_publish(lcm, "ESTOP", &e);
    print_message("%d SYNCs in %.2f s under 30 e-stop messages (50 Hz: %.0f), shortest gap as read %.1f ms\n",
                  syncs, secs, secs * 50, min_gap / 1000.0);
    /* Counted, not timed: a loaded host makes the spy read SYNCs in batches, but never adds
     * any. An extra SYNC per e-stop message would add 30 to about 75. */
    assert_true(syncs > 20);
    assert_true(syncs <= secs * 50 * 1.1 + 3);
    assert_true(wait_for(enc_ok, 10));
}

/* Every EMCY counts in the heartbeat's "emcy", past the storm threshold (10/s) too. */
static void every_emcy_is_counted(void **state)
{
    assert_true(wait_for(enc_ok, 10));
    int n0 = hb_drives.n;
    assert_true(wait_for(NULL, 1.5) && hb_drives.n > n0);
    int64_t before = hb_drives.emcy;
    char u[112];
    snprintf(u, sizeof u, "emu:%s", sock);
    can_bus_t *bus = can_bus_open(u);
    assert_non_null(bus);
    struct can_frame f = { .can_id = 0x081, .len = 8, .data = { 0x20, 0x32, 0x05 } };  /* 0x3220 */
    for (int k = 0; k < 30; k++) {
        assert_int_equal(can_bus_write(bus, &f), 0);
        usleep(2000);
    }
    can_bus_close(bus);
    bool ok = false;
    for (int k = 0; k < 40 && !ok; k++) {
        wait_for(NULL, 0.25);
        ok = hb_drives.emcy - before >= 30;     /* the drives may add their own */
    }
    print_message("emcy counter +%lld for 30 EMCY\n", (long long)(hb_drives.emcy - before));
    assert_true(ok);
}

static void drive_fault_is_counted_and_reset(void **state)
{
    kill(dev_pid, SIGUSR1);                     /* left drive: over-current */
    assert_true(wait_for(fault_seen, 10));
    assert_true(hb_drives.emcy >= 1);
    assert_true(wait_for(recovered, 15));
    assert_true(wait_for(wheels_at_command, 10));
}

static void bus_off_is_detected_and_recovered(void **state)
{
    kill(bus_pid, SIGUSR1);                     /* the bus injects a bus-off error frame */
    assert_true(wait_for(bus_off_counted, 10));
    assert_true(wait_for(wheels_at_command, 10));
}

static bool gyro_fault(void) { return ngyro > 0 && gyr.status == 2; }
static bool gyro_ok(void) { return ngyro > 0 && gyr.status == 0; }

/* A gyro sensor fault: EMCY 0x7300 and status 2 in every sample, until it clears. */
static void gyro_fault_reported_in_samples(void **state)
{
    kill(dev_pid, SIGUSR2);
    assert_true(wait_for(gyro_fault, 10));
    kill(dev_pid, SIGUSR2);
    assert_true(wait_for(gyro_ok, 10));
}

static int64_t hb_state = -1;
static void on_hb_state(const lcm_recv_buf_t *rb, const char *ch, const marie_heartbeat_t *m, void *u)
{
    if (strcmp(m->component, "marie-drives") == 0)
        hb_state = m->state;
}
static bool drives_paused(void) { return hb_state == MARIE_LIFECYCLE_COMMAND_T_STATE_PAUSED; }
static bool drives_running(void) { return hb_state == MARIE_LIFECYCLE_COMMAND_T_STATE_RUNNING; }

static void lifecycle(int8_t cmd)
{
    static int64_t id = 100;
    marie_lifecycle_command_t m = { .utime = marie_wall_us(), .request_id = id++, .sender = "test",
                                    .target = "marie-drives", .command = cmd };
    marie_lifecycle_command_t_publish(lcm, "MARIE_LIFECYCLE", &m);
}

/* Paused, the driver runs no cycle: it must power the drives down rather than leave them at
 * the last target. The encoder publisher is paused too, so the spy watches RPDO1. */
static void pause_powers_down_and_resume_restores(void **state)
{
    marie_heartbeat_t_subscription_t *s = marie_heartbeat_t_subscribe(lcm, "MARIE_HEARTBEAT", on_hb_state, NULL);
    assert_true(wait_for(wheels_at_command, 10));
    char u[112];
    snprintf(u, sizeof u, "emu:%s", sock);
    spy = can_bus_open(u);
    assert_non_null(spy);
    lifecycle(MARIE_LIFECYCLE_COMMAND_T_CMD_PAUSE);
    bool paused = wait_for(drives_paused, 10);
    wait_for(NULL, 0.5);
    uint16_t last_cw = 0xFFFF;
    struct can_frame f;
    while (can_bus_read(spy, &f) == 1)
        if (f.can_id == 0x201 && f.len == 6)
            last_cw = (uint16_t)(f.data[0] | f.data[1] << 8);
    can_bus_close(spy);
    spy = NULL;
    lifecycle(MARIE_LIFECYCLE_COMMAND_T_CMD_RESUME);
    bool running = wait_for(drives_running, 10);
    marie_heartbeat_t_unsubscribe(lcm, s);
    assert_true(paused);
    assert_int_equal(last_cw, 0x0000);             /* disable voltage */
    assert_true(running);
    assert_true(wait_for(wheels_at_command, 10));
}

static void bus_daemon_restart_reconnects(void **state)
{
    stop(&bus_pid);
    stop(&dev_pid);
    bus_pid = spawn("marie-canbus", (char *[]){ sock, NULL });
    for (int i = 0; i < 50 && access(sock, F_OK) != 0; i++)
        usleep(100000);
    char devurl[112];
    snprintf(devurl, sizeof devurl, "emu:%s", sock);
    dev_pid = spawn("marie-vcan-devices", (char *[]){ "--can", devurl, NULL });
    assert_true(wait_for(reconnected, 20));
    assert_true(hb_drives.disconnected >= 1);
    assert_true(wait_for(wheels_at_command, 10));
    commanding = false;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(drives_enable_and_publish_encoders),
        cmocka_unit_test(motor_command_turns_wheels_by_kinematics),
        cmocka_unit_test(command_timeout_stops_wheels),
        cmocka_unit_test(estop_stops_and_release_resumes),
        cmocka_unit_test(estop_messages_keep_the_sync_period),
        cmocka_unit_test(killed_master_stops_the_wheels),
        cmocka_unit_test(frozen_master_stops_the_wheels),
        cmocka_unit_test(every_emcy_is_counted),
        cmocka_unit_test(drive_fault_is_counted_and_reset),
        cmocka_unit_test(bus_off_is_detected_and_recovered),
        cmocka_unit_test(gyro_fault_reported_in_samples),
        cmocka_unit_test(pause_powers_down_and_resume_restores),
        cmocka_unit_test(bus_daemon_restart_reconnects),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
