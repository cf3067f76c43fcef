/* test_drives_ctl: the wheel-drive master against two virtual CiA 402 drives on an in-memory
 * bus: configuration, enabling, velocity, command timeout, e-stop, faults with EMCY or only
 * in the statusword, fault reset, EMCY storms, malformed frames, heartbeat loss and reboot;
 * the drives stopping when the master dies or loses them; CiA 301 objects of the virtual
 * drive and gyro (identity, reset communication, SDO without size, optional objects). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include <sys/socket.h>
#include <unistd.h>

#include "hw/can/can.h"
#include "hw/canopen/co.h"
#include "hw/canopen/emcy.h"
#include "hw/canopen/nmt.h"
#include "hw/canopen/sdo.h"
#include "hw/drives/drives_ctl.h"
#include "hw/drives/vdrive.h"
#include "hw/gyro/vgyro.h"

#define QMAX 256
typedef struct {
    drives_ctl_t *ctl;
    vdrive_t *vd[2];
    int64_t now;
    bool cut[2];                /* drive i disconnected */
    bool mute_sdo[2];           /* drive i's SDO answers are lost */
    bool master_dead;           /* the master neither cycles nor answers */
    struct { struct can_frame f; int src; } q[QMAX];   /* src: -1 master, 0/1 drive */
    int qh, qt;
    int ev[32];                 /* events seen per kind */
    uint32_t last_code[32];
    char last_text[32][400];
    int frames_on_bus;
} rig_t;

static void on_ev(void *user, int axis, drives_ev_t e, uint32_t code)
{
    rig_t *r = user;
    r->ev[e]++;
    r->last_code[e] = code;
    if (r->ctl)
        drives_ctl_event_text(r->ctl, axis, e, code, r->last_text[e], sizeof r->last_text[e]);
}

static void put(rig_t *r, const struct can_frame *f, int n, int src)
{
    for (int i = 0; i < n; i++) {
        if (src >= 0 && r->cut[src])
            continue;
        if (src >= 0 && r->mute_sdo[src] && (f[i].can_id & 0x780) == 0x580)
            continue;
        r->q[r->qt % QMAX].f = f[i];
        r->q[r->qt % QMAX].src = src;
        r->qt++;
    }
}

static void deliver(rig_t *r)
{
    struct can_frame tx[16];
    while (r->qh != r->qt) {
        struct can_frame f = r->q[r->qh % QMAX].f;
        int src = r->q[r->qh % QMAX].src;
        r->qh++;
        r->frames_on_bus++;
        if (src != -1 && !r->master_dead)
            put(r, tx, drives_ctl_feed(r->ctl, &f, r->now, tx, 16), -1);
        for (int i = 0; i < 2; i++)
            if (src != i && !r->cut[i])
                put(r, tx, vdrive_feed(r->vd[i], &f, r->now, tx, 16), i);
    }
}

/* Run for ms milliseconds: drives tick every 1 ms, the master cycles every 20 ms (50 Hz). */
static void run(rig_t *r, int ms, double wl, double wr, bool command)
{
    struct can_frame tx[16];
    for (int k = 0; k < ms; k++) {
        r->now += 1000;
        for (int i = 0; i < 2; i++) {
            vdrive_step(r->vd[i], 0.001);
            if (!r->cut[i])
                put(r, tx, vdrive_poll(r->vd[i], r->now, tx, 16), i);
        }
        if (r->now % 20000 == 0 && !r->master_dead) {
            if (command)
                drives_ctl_set_wheels(r->ctl, wl, wr, r->now);
            put(r, tx, drives_ctl_cycle(r->ctl, r->now, tx, 16), -1);
        }
        deliver(r);
    }
}

static const char *drive_name = "marie vdrive";
static uint16_t rig_rpdo_timeout_ms = 100;
static bool rig_no_consumer, rig_no_deadline, rig_allow_unwatched;
static bool rig_mute_left, rig_cut_right;      /* from power-on */
static int64_t rig_cmd_timeout_us = 500000;

static int setup(void **state)
{
    rig_t *r = calloc(1, sizeof *r);
    drives_cfg_t cfg;
    drives_cfg_default(&cfg);
    cfg.left_node = 1;
    cfg.right_node = 2;
    cfg.right_invert = false;
    cfg.rpdo_timeout = rig_rpdo_timeout_ms / 1000.0;
    cfg.allow_unwatched = rig_allow_unwatched;
    cfg.cmd_timeout = rig_cmd_timeout_us / 1e6;
    r->ctl = drives_ctl_create(&cfg, on_ev, r);
    for (int i = 0; i < 2; i++) {
        vdrive_cfg_t vc;
        vdrive_cfg_default(&vc, (uint8_t)(i + 1));
        vc.name = drive_name;
        vc.opts.no_consumer = rig_no_consumer;
        vc.opts.no_rpdo_deadline = rig_no_deadline;
        r->vd[i] = vdrive_create(&vc);
    }
    r->now = 1000000;
    r->mute_sdo[0] = rig_mute_left;
    r->cut[1] = rig_cut_right;
    struct can_frame tx[16];
    for (int i = 0; i < 2; i++)
        put(r, tx, vdrive_boot(r->vd[i], r->now, tx, 16), i);
    put(r, tx, drives_ctl_start(r->ctl, r->now, tx, 16), -1);
    deliver(r);
    *state = r;
    return 0;
}

static int teardown(void **state)
{
    rig_t *r = *state;
    drives_ctl_destroy(r->ctl);
    vdrive_destroy(r->vd[0]);
    vdrive_destroy(r->vd[1]);
    free(r);
    return 0;
}

static void startup_configures_and_enables(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    assert_int_equal(r->ev[DRIVES_EV_CONFIGURED], 2);
    assert_int_equal(r->ev[DRIVES_EV_CONFIG_FAILED], 0);
    for (int i = 0; i < 2; i++) {
        const drives_axis_t *a = drives_ctl_axis(r->ctl, i);
        assert_int_equal(a->phase, DRIVES_AX_RUN);
        assert_int_equal(a->state, CIA402_OPERATION_ENABLED);
        assert_string_equal(a->name, "marie vdrive");      /* segmented SDO upload */
        assert_int_equal(vdrive_nmt(r->vd[i]), CO_NMT_OPERATIONAL);
        assert_int_equal(vdrive_state(r->vd[i]), CIA402_OPERATION_ENABLED);
        assert_int_equal(a->nmt, CO_NMT_OPERATIONAL);       /* from heartbeats */
    }
    assert_true(drives_ctl_all_enabled(r->ctl));
}

static void velocity_reaches_the_wheels(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    run(r, 1000, 2.0, -1.0, true);
    assert_true(fabs(vdrive_velocity(r->vd[0]) - 2.0) < 0.01);
    assert_true(fabs(vdrive_velocity(r->vd[1]) + 1.0) < 0.01);
    const drives_axis_t *l = drives_ctl_axis(r->ctl, 0), *rt = drives_ctl_axis(r->ctl, 1);
    assert_true(fabs(drives_ctl_counts_to_rad(r->ctl, l->velocity) - 2.0) < 0.01);
    assert_true(fabs(drives_ctl_counts_to_rad(r->ctl, rt->velocity) + 1.0) < 0.01);
    /* about 1.9 rad turned in the last second (0.1 s ramp): the position TPDO follows */
    double pos = drives_ctl_counts_to_rad(r->ctl, l->position);
    assert_true(pos > 1.7 && pos < 2.1);
    /* limits scale both wheels together */
    run(r, 1500, 100.0, 50.0, true);
    assert_true(fabs(vdrive_velocity(r->vd[0]) - 20.0) < 0.05);
    assert_true(fabs(vdrive_velocity(r->vd[1]) - 10.0) < 0.05);
}

/* A client sending commands far faster than the SYNC cycle (here 100 in one period) puts
 * one RPDO1 per drive on the bus at once, not 100: the drives apply what they latched at
 * the next SYNC, which the cycle's own RPDO1 just before it brings up to the last command.
 * An e-stop in the same period still goes out at once. */
static void command_flood_is_one_rpdo_per_drive_per_cycle(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    run(r, 5, 0, 0, true);                      /* between two cycles */
    struct can_frame tx[4];
    int frames = 0;
    for (int k = 1; k <= 100; k++) {
        drives_ctl_set_wheels(r->ctl, 0.02 * k, -0.02 * k, r->now);
        int n = drives_ctl_rpdo_now(r->ctl, r->now, tx, 4);
        for (int i = 0; i < n; i++)
            assert_int_equal(tx[i].can_id & ~0x7Fu, CO_COB_RPDO1);
        frames += n;
        put(r, tx, n, -1);
    }
    assert_int_equal(frames, 2);
    run(r, 300, 2.0, -2.0, false);              /* cycles go on; no more commands */
    assert_true(fabs(vdrive_command(r->vd[0]) - 2.0) < 0.01);
    assert_true(fabs(vdrive_command(r->vd[1]) + 2.0) < 0.01);
    /* Two commands in the next period, then an e-stop: three early rounds, the last with
     * the quick-stop controlword. */
    run(r, 25, 0, 0, false);
    frames = 0;
    for (int k = 0; k < 2; k++) {
        drives_ctl_set_wheels(r->ctl, 1.0, 1.0, r->now);
        frames += drives_ctl_rpdo_now(r->ctl, r->now, tx, 4);
    }
    assert_int_equal(frames, 2);
    drives_ctl_set_estop(r->ctl, true);
    assert_int_equal(drives_ctl_rpdo_now(r->ctl, r->now, tx, 4), 2);
    assert_int_equal(tx[0].data[0] | tx[0].data[1] << 8, CIA402_CW_QUICK_STOP);
}

static void command_timeout_stops_the_wheels(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    run(r, 200, 3.0, 3.0, true);
    assert_true(vdrive_velocity(r->vd[0]) > 2.5);
    assert_false(drives_ctl_command_stale(r->ctl, r->now));
    run(r, 1000, 0, 0, false);                  /* commands stop arriving */
    assert_true(drives_ctl_command_stale(r->ctl, r->now));
    assert_true(fabs(vdrive_velocity(r->vd[0])) < 1e-9);
    assert_int_equal(drives_ctl_axis(r->ctl, 0)->target, 0);
    assert_int_equal(vdrive_state(r->vd[0]), CIA402_OPERATION_ENABLED);   /* still enabled */
}

static void estop_quick_stops_then_releases(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    run(r, 300, 3.0, 3.0, true);
    drives_ctl_set_estop(r->ctl, true);
    run(r, 300, 3.0, 3.0, true);
    for (int i = 0; i < 2; i++) {
        assert_int_equal(vdrive_state(r->vd[i]), CIA402_QUICK_STOP_ACTIVE);
        assert_true(fabs(vdrive_velocity(r->vd[i])) < 1e-9);
        assert_int_equal(drives_ctl_axis(r->ctl, i)->state, CIA402_QUICK_STOP_ACTIVE);
    }
    assert_false(drives_ctl_all_enabled(r->ctl));
    drives_ctl_set_estop(r->ctl, false);
    run(r, 500, 3.0, 3.0, true);
    assert_int_equal(vdrive_state(r->vd[0]), CIA402_OPERATION_ENABLED);
    assert_true(fabs(vdrive_velocity(r->vd[0]) - 3.0) < 0.01);
}

static void fault_with_emcy_is_reset_and_recovers(void **state)
{
    rig_t *r = *state;
    run(r, 500, 1.0, 1.0, true);
    vdrive_inject_fault(r->vd[0], CO_EMCY_OVERCURRENT);
    run(r, 300, 1.0, 1.0, true);
    const drives_axis_t *a = drives_ctl_axis(r->ctl, 0);
    assert_int_equal(r->ev[DRIVES_EV_EMCY], 1);
    assert_int_equal(r->last_code[DRIVES_EV_EMCY], CO_EMCY_OVERCURRENT);
    assert_int_equal(r->ev[DRIVES_EV_FAULT], 1);
    assert_int_equal(a->state, CIA402_FAULT);
    assert_int_equal(a->faults, 1);
    assert_true(fabs(vdrive_velocity(r->vd[0])) < 1e-9);
    assert_int_equal(r->ev[DRIVES_EV_FAULT_RESET], 0);      /* waits fault_reset_delay */
    run(r, 1500, 1.0, 1.0, true);
    assert_int_equal(r->ev[DRIVES_EV_FAULT_RESET], 1);
    assert_int_equal(r->ev[DRIVES_EV_RECOVERED], 1);
    assert_int_equal(r->ev[DRIVES_EV_EMCY], 2);             /* the drive's "error reset" EMCY */
    assert_int_equal(r->last_code[DRIVES_EV_EMCY], CO_EMCY_NO_ERROR);
    assert_int_equal(a->state, CIA402_OPERATION_ENABLED);
    assert_true(fabs(vdrive_velocity(r->vd[0]) - 1.0) < 0.01);
    assert_int_equal(drives_ctl_axis(r->ctl, 1)->faults, 0);
}

static void statusword_fault_without_emcy(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    vdrive_inject_silent_fault(r->vd[1], CO_EMCY_OVERTEMP_DRIVE);
    run(r, 100, 0, 0, true);
    assert_int_equal(drives_ctl_axis(r->ctl, 1)->state, CIA402_FAULT);
    assert_int_equal(drives_ctl_axis(r->ctl, 1)->faults, 1);
    assert_int_equal(r->ev[DRIVES_EV_EMCY], 0);
    run(r, 1500, 0, 0, true);
    assert_int_equal(drives_ctl_axis(r->ctl, 1)->state, CIA402_OPERATION_ENABLED);
}

static void emcy_storm_is_counted_not_flooded(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    struct can_frame tx[16];
    for (int k = 0; k < 200; k++) {
        co_emcy_t e = { .node = 1, .code = CO_EMCY_UNDERVOLTAGE, .reg = 0x05 };
        struct can_frame f;
        co_emcy_encode(&f, &e);
        put(r, &f, 1, 0);
    }
    deliver(r);
    (void)tx;
    assert_int_equal(drives_ctl_axis(r->ctl, 0)->emcy, 200);
    assert_int_equal(r->ev[DRIVES_EV_EMCY], 10);
    assert_int_equal(r->ev[DRIVES_EV_EMCY_STORM], 1);
    /* every one is counted, past the storm threshold too */
    assert_int_equal(r->ev[DRIVES_EV_EMCY] + r->ev[DRIVES_EV_EMCY_STORM] + r->ev[DRIVES_EV_EMCY_QUIET], 200);
    run(r, 200, 0, 0, true);
    assert_true(drives_ctl_all_enabled(r->ctl));    /* EMCY alone does not stop a healthy drive */
}

static void malformed_and_unexpected_frames(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    struct can_frame tx[16];
    struct can_frame shorttpdo = { .can_id = 0x181, .len = 2 };
    struct can_frame shortemcy = { .can_id = 0x081, .len = 3 };
    struct can_frame rpdo = { .can_id = 0x201, .len = 6 };
    struct can_frame stranger = { .can_id = 0x185, .len = 6 };
    struct can_frame badhb = { .can_id = 0x701, .len = 1, .data = { 0x42 } };
    drives_ctl_feed(r->ctl, &shorttpdo, r->now, tx, 16);
    drives_ctl_feed(r->ctl, &shortemcy, r->now, tx, 16);
    drives_ctl_feed(r->ctl, &badhb, r->now, tx, 16);
    assert_int_equal(r->ev[DRIVES_EV_BAD_FRAME], 3);
    drives_ctl_feed(r->ctl, &rpdo, r->now, tx, 16);
    drives_ctl_feed(r->ctl, &stranger, r->now, tx, 16);
    assert_int_equal(r->ev[DRIVES_EV_UNEXPECTED], 2);
    /* SDO answers nobody asked for: unexpected, or malformed when short */
    struct can_frame sdo = { .can_id = 0x581, .len = 8, .data = { 0x60, 0x17, 0x10, 0 } };
    drives_ctl_feed(r->ctl, &sdo, r->now, tx, 16);
    assert_int_equal(r->ev[DRIVES_EV_UNEXPECTED], 3);
    sdo.len = 3;
    drives_ctl_feed(r->ctl, &sdo, r->now, tx, 16);
    assert_int_equal(r->ev[DRIVES_EV_BAD_FRAME], 4);
    run(r, 100, 0, 0, true);
    assert_true(drives_ctl_all_enabled(r->ctl));
}

static void heartbeat_loss_then_reconnect(void **state)
{
    rig_t *r = *state;
    run(r, 500, 1.0, 1.0, true);
    r->cut[1] = true;
    run(r, 1000, 1.0, 1.0, true);
    const drives_axis_t *a = drives_ctl_axis(r->ctl, 1);
    assert_int_equal(r->ev[DRIVES_EV_HB_TIMEOUT], 1);
    assert_int_equal(a->phase, DRIVES_AX_OFFLINE);
    assert_false(drives_ctl_all_enabled(r->ctl));
    r->cut[1] = false;
    run(r, 3000, 1.0, 1.0, true);
    assert_int_equal(a->phase, DRIVES_AX_RUN);
    assert_int_equal(a->state, CIA402_OPERATION_ENABLED);
    assert_true(r->ev[DRIVES_EV_CONFIGURED] >= 3);
    assert_true(drives_ctl_all_enabled(r->ctl));
}

static void drive_reboot_is_reconfigured(void **state)
{
    rig_t *r = *state;
    run(r, 500, 1.0, 1.0, true);
    struct can_frame tx[16];
    int bootups = r->ev[DRIVES_EV_BOOTUP], configured = r->ev[DRIVES_EV_CONFIGURED];
    vdrive_destroy(r->vd[0]);                   /* power cycle: a fresh drive with defaults */
    vdrive_cfg_t vc;
    vdrive_cfg_default(&vc, 1);
    r->vd[0] = vdrive_create(&vc);
    put(r, tx, vdrive_boot(r->vd[0], r->now, tx, 16), 0);
    deliver(r);
    assert_int_equal(r->ev[DRIVES_EV_BOOTUP], bootups + 1);
    run(r, 500, 1.0, 1.0, true);
    assert_int_equal(r->ev[DRIVES_EV_CONFIGURED], configured + 1);
    assert_int_equal(vdrive_state(r->vd[0]), CIA402_OPERATION_ENABLED);
    assert_true(fabs(vdrive_velocity(r->vd[0]) - 1.0) < 0.01);
}

/* ms until both virtual drives stand still (0x606C == 0), running the drives only. */
static int ms_to_standstill(rig_t *r, int limit)
{
    for (int ms = 0; ms <= limit; ms++) {
        if (fabs(vdrive_velocity(r->vd[0])) < 1e-9 && fabs(vdrive_velocity(r->vd[1])) < 1e-9)
            return ms;
        run(r, 1, 0, 0, false);
    }
    return -1;
}

/* The master dies at 0.5 m/s (5 rad/s at the wheels): no heartbeat, no RPDO, no SYNC. The
 * drives' heartbeat consumer (0x1016, 100 ms) fires, fault reaction on the quick-stop ramp
 * (40 rad/s^2: 125 ms): standing within 300 ms. */
static void master_death_stops_the_drives(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    run(r, 600, 5.0, 5.0, true);
    assert_true(fabs(vdrive_velocity(r->vd[0]) - 5.0) < 0.01);
    r->master_dead = true;
    int ms = ms_to_standstill(r, 2000);
    print_message("standstill %d ms after the master died\n", ms);
    assert_true(ms >= 0 && ms <= 300);
    for (int i = 0; i < 2; i++) {
        assert_int_equal(vdrive_state(r->vd[i]), CIA402_FAULT);
        assert_int_equal(vdrive_nmt(r->vd[i]), CO_NMT_PREOPERATIONAL);   /* 0x1029 default */
        assert_int_equal(vdrive_stats(r->vd[i])->hb_losses, 1);
    }
    /* it comes back: reconfigures, resets the fault and drives again */
    r->master_dead = false;
    run(r, 3000, 2.0, 2.0, true);
    assert_true(drives_ctl_all_enabled(r->ctl));
    assert_true(fabs(vdrive_velocity(r->vd[0]) - 2.0) < 0.01);
}

/* Heartbeat still there but the RPDOs stop (a master stuck in its cycle): the RPDO
 * deadline (0x1400:05, 100 ms) fires, EMCY 0x8250, fault reaction. */
static void rpdo_deadline_stops_the_drives(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    run(r, 600, 5.0, 5.0, true);
    struct can_frame tx[16];
    int ms;
    for (ms = 0; ms < 2000; ms++) {
        if (fabs(vdrive_velocity(r->vd[0])) < 1e-9)
            break;
        r->now += 1000;
        for (int i = 0; i < 2; i++) {
            vdrive_step(r->vd[i], 0.001);
            put(r, tx, vdrive_poll(r->vd[i], r->now, tx, 16), i);
        }
        if (ms % 20 == 0) {         /* only the master's heartbeat */
            struct can_frame hb;
            co_hb_encode(&hb, 127, CO_NMT_OPERATIONAL);
            put(r, &hb, 1, -1);
        }
        deliver(r);
    }
    assert_true(ms <= 300);
    assert_int_equal(vdrive_stats(r->vd[0])->rpdo_timeouts, 1);
    assert_int_equal(vdrive_stats(r->vd[0])->hb_losses, 0);
    assert_int_equal(r->last_code[DRIVES_EV_EMCY], CO_EMCY_RPDO_TIMEOUT);
}

/* Drives without RPDO deadline monitoring: only the master's own reactions stop them. */
static int setup_no_deadline(void **state)
{
    rig_rpdo_timeout_ms = 0;
    int rc = setup(state);
    rig_rpdo_timeout_ms = 100;
    return rc;
}

/* A forged boot-up while driving, then a configuration that fails (SDO answers lost): the
 * master takes the drive out of operational first, and it stops (no RPDO deadline here to
 * do it for the master). */
static void forged_bootup_and_failed_config_stop_the_drive(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    run(r, 600, 5.0, 5.0, true);
    struct can_frame boot;
    co_hb_encode(&boot, 1, CO_NMT_BOOTUP);
    r->mute_sdo[0] = true;
    put(r, &boot, 1, 0);
    deliver(r);
    int ms;
    for (ms = 0; ms < 2000 && fabs(vdrive_velocity(r->vd[0])) > 1e-9; ms++)
        run(r, 1, 5.0, 5.0, true);
    assert_true(ms <= 300);
    run(r, 1500, 5.0, 5.0, true);               /* until the next configuration attempt */
    assert_true(r->ev[DRIVES_EV_CONFIG_FAILED] >= 1);
    assert_true(fabs(vdrive_velocity(r->vd[0])) < 1e-9);
    assert_false(cia402_state_powered(vdrive_state(r->vd[0])));
    r->mute_sdo[0] = false;
    run(r, 4000, 5.0, 5.0, true);
    assert_true(drives_ctl_all_enabled(r->ctl));
}

/* The master's own leaving: disabled with a last SYNC, then NMT stopped, no fault. */
static void shutdown_leaves_drives_disabled_and_stopped(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    run(r, 300, 3.0, 3.0, true);
    struct can_frame tx[16];
    put(r, tx, drives_ctl_shutdown(r->ctl, r->now, tx, 16), -1);
    deliver(r);
    r->master_dead = true;
    run(r, 500, 0, 0, false);
    for (int i = 0; i < 2; i++) {
        assert_int_equal(vdrive_state(r->vd[i]), CIA402_SWITCH_ON_DISABLED);
        assert_int_equal(vdrive_nmt(r->vd[i]), CO_NMT_STOPPED);
        assert_true(fabs(vdrive_velocity(r->vd[i])) < 1e-9);
    }
}

static void disable_brings_drives_down(void **state)
{
    rig_t *r = *state;
    run(r, 500, 1.0, 1.0, true);
    drives_ctl_enable(r->ctl, false);
    run(r, 200, 1.0, 1.0, true);
    assert_int_equal(vdrive_state(r->vd[0]), CIA402_SWITCH_ON_DISABLED);
    assert_int_equal(vdrive_state(r->vd[1]), CIA402_SWITCH_ON_DISABLED);
    drives_ctl_enable(r->ctl, true);
    run(r, 200, 1.0, 1.0, true);
    assert_true(drives_ctl_all_enabled(r->ctl));
}

/* A drive without the optional 0x1008 comes up all the same. */
static int setup_nameless(void **state)
{
    drive_name = "";
    int rc = setup(state);
    drive_name = "marie vdrive";
    return rc;
}

static void drive_without_name_comes_up(void **state)
{
    rig_t *r = *state;
    run(r, 1000, 0, 0, true);
    assert_int_equal(r->ev[DRIVES_EV_CONFIGURED], 2);
    assert_int_equal(r->ev[DRIVES_EV_CONFIG_FAILED], 0);
    assert_int_equal(r->ev[DRIVES_EV_HB_TIMEOUT], 0);
    assert_int_equal(r->ev[DRIVES_EV_OPTIONAL_MISSING], 2);
    assert_int_equal(r->last_code[DRIVES_EV_OPTIONAL_MISSING], 0x100800);
    assert_string_equal(drives_ctl_axis(r->ctl, 0)->name, "");
    assert_true(drives_ctl_all_enabled(r->ctl));
}

/* ---- drives without optional objects, the restart interlock, what events say ---- */

/* 0x1016 is optional in CiA 301. A drive without it is configured, driven, and stopped by its
 * RPDO deadline when the master dies (it used to be refused its configuration forever, the
 * event naming no object). */
static int setup_no_consumer(void **state)
{
    rig_no_consumer = true;
    int rc = setup(state);
    rig_no_consumer = false;
    return rc;
}

static void drive_without_0x1016_relies_on_its_rpdo_deadline(void **state)
{
    rig_t *r = *state;
    run(r, 1000, 0, 0, true);
    assert_int_equal(r->ev[DRIVES_EV_CONFIG_FAILED], 0);
    assert_int_equal(r->ev[DRIVES_EV_CONFIGURED], 2);
    assert_int_equal(r->ev[DRIVES_EV_WATCH], 2);
    assert_int_equal(r->last_code[DRIVES_EV_WATCH], DRIVES_WATCH_RPDO_ONLY);
    assert_non_null(strstr(r->last_text[DRIVES_EV_WATCH], "RPDO deadline alone (0x1400:05, 100 ms)"));
    assert_non_null(strstr(r->last_text[DRIVES_EV_OPTIONAL_MISSING], "0x1016:01 (consumer heartbeat time"));
    const drives_axis_t *a = drives_ctl_axis(r->ctl, 0);
    assert_true(a->lacks_consumer && !a->watches_hb && a->watches_rpdo && !a->refused);
    assert_int_equal(a->identity[1], VDRIVE_PRODUCT_CODE);          /* 0x1018 read */
    assert_int_equal(a->identity[3], 1);
    assert_non_null(strstr(r->last_text[DRIVES_EV_CONFIGURED], "serial 2"));
    run(r, 600, 5.0, 5.0, true);
    assert_true(fabs(vdrive_velocity(r->vd[0]) - 5.0) < 0.01);
    r->master_dead = true;
    int ms = ms_to_standstill(r, 2000);
    print_message("standstill %d ms after the master died (RPDO deadline only)\n", ms);
    assert_true(ms >= 0 && ms <= 300);
    assert_int_equal(vdrive_stats(r->vd[0])->rpdo_timeouts, 1);
    assert_int_equal(vdrive_stats(r->vd[0])->hb_losses, 0);
}

/* Neither 0x1016 nor 0x1400:05: nothing would stop the drive if the master died. Refused (kept
 * disabled, told as an error), unless the system file allows it. */
static int setup_unwatched(void **state)
{
    rig_no_consumer = rig_no_deadline = true;
    int rc = setup(state);
    rig_no_consumer = rig_no_deadline = false;
    return rc;
}

static int setup_unwatched_allowed(void **state)
{
    rig_allow_unwatched = true;
    int rc = setup_unwatched(state);
    rig_allow_unwatched = false;
    return rc;
}

static void drive_watching_nothing_is_refused(void **state)
{
    rig_t *r = *state;
    run(r, 1000, 3.0, 3.0, true);
    assert_int_equal(r->ev[DRIVES_EV_CONFIGURED], 2);
    assert_int_equal(r->last_code[DRIVES_EV_WATCH], DRIVES_WATCH_NONE_REFUSED);
    assert_non_null(strstr(r->last_text[DRIVES_EV_WATCH], "kept disabled"));
    for (int i = 0; i < 2; i++) {
        assert_true(drives_ctl_axis(r->ctl, i)->refused);
        assert_int_equal(vdrive_state(r->vd[i]), CIA402_SWITCH_ON_DISABLED);
        assert_true(fabs(vdrive_velocity(r->vd[i])) < 1e-9);
    }
    assert_false(drives_ctl_all_enabled(r->ctl));
}

static void drive_watching_nothing_is_driven_where_allowed(void **state)
{
    rig_t *r = *state;
    run(r, 1000, 3.0, 3.0, true);
    assert_int_equal(r->last_code[DRIVES_EV_WATCH], DRIVES_WATCH_NONE_ALLOWED);
    assert_true(drives_ctl_all_enabled(r->ctl));
    assert_true(fabs(vdrive_velocity(r->vd[0]) - 3.0) < 0.01);
}

/* A drive that reboots mid-run is reconfigured and enabled with target 0, and turns only for a
 * command newer than its enabling: it used to resume the last one at once, at full speed until
 * cmd_timeout. Here the last command stays fresh (cmd_timeout 5 s) for the whole reboot. */
static int setup_long_cmd_timeout(void **state)
{
    rig_cmd_timeout_us = 5000000;
    int rc = setup(state);
    rig_cmd_timeout_us = 500000;
    return rc;
}

static void rebooted_drive_waits_for_a_new_command(void **state)
{
    rig_t *r = *state;
    run(r, 500, 4.0, 4.0, true);
    run(r, 500, 4.0, 4.0, true);
    assert_true(fabs(vdrive_velocity(r->vd[0]) - 4.0) < 0.01);
    struct can_frame tx[16];
    vdrive_destroy(r->vd[0]);                   /* power cycle, no new command after it */
    vdrive_cfg_t vc;
    vdrive_cfg_default(&vc, 1);
    r->vd[0] = vdrive_create(&vc);
    put(r, tx, vdrive_boot(r->vd[0], r->now, tx, 16), 0);
    deliver(r);
    run(r, 1500, 0, 0, false);
    assert_int_equal(vdrive_state(r->vd[0]), CIA402_OPERATION_ENABLED);
    assert_false(drives_ctl_command_stale(r->ctl, r->now));
    assert_true(fabs(vdrive_velocity(r->vd[0])) < 1e-9);       /* held at 0 */
    assert_true(fabs(vdrive_velocity(r->vd[1]) - 4.0) < 0.01);  /* the other one was never restarted */
    assert_int_equal(r->ev[DRIVES_EV_HOLD], 1);
    assert_non_null(strstr(r->last_text[DRIVES_EV_HOLD], "left drive enabled again"));
    run(r, 300, 2.0, 2.0, true);                /* a new command */
    assert_true(fabs(vdrive_velocity(r->vd[0]) - 2.0) < 0.01);
}

/* The same after a fault reset: the drive comes back at 0 until commanded anew. */
static void recovered_drive_waits_for_a_new_command(void **state)
{
    rig_t *r = *state;
    run(r, 600, 4.0, 4.0, true);
    vdrive_inject_fault(r->vd[0], CO_EMCY_OVERCURRENT);
    run(r, 2000, 4.0, 4.0, false);
    assert_int_equal(r->ev[DRIVES_EV_RECOVERED], 1);
    assert_true(fabs(vdrive_velocity(r->vd[0])) < 1e-9);
    run(r, 300, 4.0, 4.0, true);
    assert_true(fabs(vdrive_velocity(r->vd[0]) - 4.0) < 0.01);
}

/* A configuration that fails before 0x1017 is written (the drive's SDO answers lost from the
 * start) is no heartbeat loss: the drive sends none yet. It used to be followed by a false
 * "heartbeat lost" 0.35 s later. The failure names the object, and a drive that never boots
 * is told once. */
static int setup_mute(void **state)
{
    rig_mute_left = rig_cut_right = true;
    int rc = setup(state);
    rig_mute_left = rig_cut_right = false;
    return rc;
}

static void early_config_failure_is_no_heartbeat_loss(void **state)
{
    rig_t *r = *state;
    run(r, 4500, 0, 0, true);
    assert_int_equal(r->ev[DRIVES_EV_HB_TIMEOUT], 0);
    assert_true(r->ev[DRIVES_EV_CONFIG_FAILED] >= 2);
    const drives_axis_t *a = drives_ctl_axis(r->ctl, 0);
    assert_int_equal(a->fail.index, 0x1000);
    assert_int_equal(a->fail.abort, CO_SDO_ABORT_TIMEOUT);
    assert_true(a->fail.repeats >= 1);
    assert_string_equal(r->last_text[DRIVES_EV_CONFIG_FAILED],
                        "left drive: configuration failed at 0x1000:00 (device type, read): SDO protocol timed out "
                        "(0x05040000); stopped, again in 2 s (failed alike before)");
    assert_int_equal(r->ev[DRIVES_EV_NOT_FOUND], 1);    /* the right one, silent */
    assert_non_null(strstr(r->last_text[DRIVES_EV_NOT_FOUND], "right drive (node 2): no boot-up"));
    /* once answers come, it comes up */
    r->mute_sdo[0] = r->cut[1] = false;
    run(r, 4500, 0, 0, true);
    assert_true(drives_ctl_all_enabled(r->ctl));
    assert_int_equal(r->ev[DRIVES_EV_HB_TIMEOUT], 0);
}

/* A fault told by the statusword alone says so: not "last EMCY 0x0000 error reset" (the
 * default of a drive that never sent one, or the reset EMCY that cleared an earlier fault). */
static void fault_without_emcy_says_no_emcy(void **state)
{
    rig_t *r = *state;
    run(r, 500, 0, 0, true);
    vdrive_inject_fault(r->vd[1], CO_EMCY_OVERCURRENT);    /* an earlier fault, reset by its EMCY 0x0000 */
    run(r, 2000, 0, 0, true);
    assert_int_equal(r->last_code[DRIVES_EV_EMCY], CO_EMCY_NO_ERROR);
    assert_non_null(strstr(r->last_text[DRIVES_EV_FAULT], "last EMCY 0x2310"));
    vdrive_inject_silent_fault(r->vd[1], CO_EMCY_OVERTEMP_DRIVE);
    run(r, 100, 0, 0, true);
    assert_int_equal(r->ev[DRIVES_EV_FAULT], 2);
    assert_string_equal(r->last_text[DRIVES_EV_FAULT], "right drive in fault (no EMCY told why; statusword 0x1608)");
}

/* ---- CiA 301 objects of the virtual devices, through their SDO servers ---- */

struct sdo_res { bool done; uint32_t abort; uint8_t data[CO_SDO_MAX]; size_t len; };
static void sdo_done_cb(void *user, co_sdo_client_t *c, uint16_t idx, uint8_t sub, uint32_t abort,
                        const uint8_t *data, size_t len)
{
    struct sdo_res *res = user;
    res->done = true;
    res->abort = abort;
    res->len = len < sizeof res->data ? len : sizeof res->data;
    if (data)
        memcpy(res->data, data, res->len);
}

typedef int (*feed_fn)(void *dev, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max);
static int feed_vd(void *d, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max)
{
    return vdrive_feed(d, rx, now, tx, max);
}
static int feed_vg(void *d, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max)
{
    return vgyro_feed(d, rx, now, tx, max);
}

/* Feed one request frame; the device's SDO answer (1) or none (0). */
static int sdo_answer(feed_fn feed, void *dev, const struct can_frame *req, struct can_frame *ans)
{
    struct can_frame tx[8];
    int n = feed(dev, req, 0, tx, 8);
    for (int j = 0; j < n; j++)
        if ((tx[j].can_id & 0x780) == 0x580) {
            *ans = tx[j];
            return 1;
        }
    return 0;
}

/* One SDO transfer (upload, or download of len bytes of val); the abort code, 0 when done,
 * the uploaded value in *out. */
static uint32_t sdo_with(feed_fn feed, void *dev, uint8_t node, bool up, uint16_t idx, uint8_t sub,
                         uint32_t val, size_t len, uint32_t *out)
{
    co_sdo_client_t c;
    struct sdo_res res = { 0 };
    co_sdo_client_init(&c, node, 100000, sdo_done_cb, &res);
    struct can_frame req, ans;
    uint8_t b[4];
    co_put_u32(b, val);
    if (up)
        co_sdo_client_upload(&c, idx, sub, 0, &req);
    else
        co_sdo_client_download(&c, idx, sub, b, len, 0, &req);
    for (int k = 0; k < 100 && !res.done; k++) {
        bool ready = false;
        if (!sdo_answer(feed, dev, &req, &ans))
            return 0xFFFFFFFFu;
        co_sdo_client_feed(&c, &ans, 0, &req, &ready);
    }
    if (out)
        *out = res.len >= 4 ? co_get_u32(res.data) : res.len == 2 ? co_get_u16(res.data) : res.len ? res.data[0] : 0;
    return res.abort;
}

static uint32_t vd_up(vdrive_t *v, uint16_t idx, uint8_t sub)
{
    uint32_t x = 0xDEADBEEF;
    assert_int_equal(sdo_with(feed_vd, v, vdrive_node(v), true, idx, sub, 0, 0, &x), 0);
    return x;
}
static void vd_down(vdrive_t *v, uint16_t idx, uint8_t sub, uint32_t val, size_t len)
{
    assert_int_equal(sdo_with(feed_vd, v, vdrive_node(v), false, idx, sub, val, len, NULL), 0);
}

static void identity_object_in_drive_and_gyro(void **state)
{
    vdrive_cfg_t vc;
    vdrive_cfg_default(&vc, 7);
    vdrive_t *v = vdrive_create(&vc);
    struct can_frame tx[8];
    vdrive_boot(v, 0, tx, 8);
    assert_int_equal(vd_up(v, 0x1018, 0), 4);
    assert_int_equal(vd_up(v, 0x1018, 1), VDRIVE_VENDOR_ID);
    assert_int_equal(vd_up(v, 0x1018, 2), VDRIVE_PRODUCT_CODE);
    assert_int_equal(vd_up(v, 0x1018, 3), VDRIVE_REVISION);
    assert_int_equal(vd_up(v, 0x1018, 4), 7);
    assert_int_equal(sdo_with(feed_vd, v, 7, false, 0x1018, 1, 1, 4, NULL), CO_SDO_ABORT_READ_ONLY);
    assert_int_equal(sdo_with(feed_vd, v, 7, true, 0x1018, 5, 0, 0, NULL), CO_SDO_ABORT_NO_SUB);
    vdrive_destroy(v);
    vgyro_cfg_t gc;
    vgyro_cfg_default(&gc, 0x20);
    vgyro_t *g = vgyro_create(&gc);
    vgyro_boot(g, 0, tx, 8);
    uint32_t x = 0;
    assert_int_equal(sdo_with(feed_vg, g, 0x20, true, 0x1018, 0, 0, 0, &x), 0);
    assert_int_equal(x, 4);
    assert_int_equal(sdo_with(feed_vg, g, 0x20, true, 0x1018, 4, 0, 0, &x), 0);
    assert_int_equal(x, 0x20);
    vgyro_destroy(g);
}

/* Reset communication: 0x1000-0x1FFF back to power-on values, application objects kept;
 * reset node resets both. */
static void reset_communication_restores_communication_objects(void **state)
{
    vdrive_cfg_t vc;
    vdrive_cfg_default(&vc, 7);
    vdrive_t *v = vdrive_create(&vc);
    struct can_frame tx[8], f;
    vdrive_boot(v, 0, tx, 8);
    uint32_t tpdo1 = vd_up(v, 0x1800, 1), rtmo = vd_up(v, 0x1400, 5);
    vd_down(v, 0x1017, 0, 50, 2);
    vd_down(v, 0x1800, 1, 0x80000000u | tpdo1, 4);
    vd_down(v, 0x1400, 5, 250, 2);
    vd_down(v, 0x1016, 1, 0x7F0064, 4);
    vd_down(v, CIA402_OBJ_MODE, 0, 3, 1);
    vd_down(v, CIA402_OBJ_ABORT_CONN, 0, 3, 2);
    /* two active consumer entries for one node: refused */
    assert_int_equal(sdo_with(feed_vd, v, 7, false, 0x1016, 2, 0x7F0050, 4, NULL), CO_SDO_ABORT_PARAM_INCOMPAT);
    co_nmt_encode(&f, CO_NMT_CMD_RESET_COMM, 7);
    assert_true(vdrive_feed(v, &f, 0, tx, 8) >= 1);
    assert_int_equal(tx[0].can_id, 0x707);                   /* boot-up */
    assert_int_equal(vd_up(v, 0x1017, 0), 0);
    assert_int_equal(vd_up(v, 0x1800, 1), tpdo1);
    assert_int_equal(vd_up(v, 0x1400, 5), rtmo);
    assert_int_equal(vd_up(v, 0x1016, 1), 0);
    assert_int_equal(vd_up(v, CIA402_OBJ_MODE, 0), 3);       /* application: kept */
    assert_int_equal(vd_up(v, CIA402_OBJ_ABORT_CONN, 0), 3);
    co_nmt_encode(&f, CO_NMT_CMD_RESET_NODE, 7);
    vdrive_feed(v, &f, 0, tx, 8);
    assert_int_equal(vd_up(v, CIA402_OBJ_MODE, 0), 0);
    assert_int_equal(vd_up(v, CIA402_OBJ_ABORT_CONN, 0), 1);
    vdrive_destroy(v);
}

/* Expedited download without size indication (command 0x22): the object's size applies. */
static void expedited_download_without_size(void **state)
{
    vdrive_cfg_t vc;
    vdrive_cfg_default(&vc, 7);
    vdrive_t *v = vdrive_create(&vc);
    struct can_frame tx[8], ans;
    vdrive_boot(v, 0, tx, 8);
    struct { uint16_t idx; uint8_t sub; uint32_t val; } w[] = {
        { CIA402_OBJ_MODE, 0, 3 }, { 0x1017, 0, 50 }, { CIA402_OBJ_PROFILE_ACC, 0, 12345 }, { 0x1400, 5, 70 },
    };
    for (size_t k = 0; k < sizeof w / sizeof w[0]; k++) {
        struct can_frame req = { .can_id = 0x607, .len = 8, .data = { 0x22, (uint8_t)w[k].idx, (uint8_t)(w[k].idx >> 8), w[k].sub } };
        co_put_u32(req.data + 4, w[k].val);
        assert_int_equal(sdo_answer(feed_vd, v, &req, &ans), 1);
        assert_int_equal(ans.data[0], 0x60);                 /* download response, no abort */
        assert_int_equal(vd_up(v, w[k].idx, w[k].sub), w[k].val);
    }
    vdrive_destroy(v);
}

/* 0x6007 chooses the reaction to a lost master: 2 disable voltage (at once), 3 quick stop
 * (ramp, hold), 0 none. */
static void abort_connection_option_code(void **state)
{
    int16_t opts[] = { 0, 2, 3 };
    cia402_state_t want[] = { CIA402_OPERATION_ENABLED, CIA402_SWITCH_ON_DISABLED, CIA402_QUICK_STOP_ACTIVE };
    for (int k = 0; k < 3; k++) {
        vdrive_cfg_t vc;
        vdrive_cfg_default(&vc, 7);
        vdrive_t *v = vdrive_create(&vc);
        struct can_frame tx[8], f;
        vdrive_boot(v, 0, tx, 8);
        vd_down(v, CIA402_OBJ_ABORT_CONN, 0, (uint16_t)opts[k], 2);
        vd_down(v, 0x1016, 1, 0x7E0064, 4);             /* node 0x7E, 100 ms */
        vd_down(v, CIA402_OBJ_MODE, 0, 3, 1);
        vd_down(v, CIA402_OBJ_TARGET_VEL, 0, 4096, 4);
        co_nmt_encode(&f, CO_NMT_CMD_START, 7);
        vdrive_feed(v, &f, 0, tx, 8);
        for (int i = 0; i < 3; i++)
            vd_down(v, CIA402_OBJ_CONTROLWORD, 0, (uint16_t[]){ 0x06, 0x07, 0x0F }[i], 2);
        struct can_frame hb;
        co_hb_encode(&hb, 0x7E, CO_NMT_OPERATIONAL);
        int64_t now = 0;
        for (; now < 1000000; now += 1000) {       /* heard every 20 ms: keeps turning */
            if (now % 20000 == 0)
                vdrive_feed(v, &hb, now, tx, 8);
            vdrive_step(v, 0.001);
            vdrive_poll(v, now, tx, 8);
        }
        assert_true(fabs(vdrive_velocity(v) - 2 * M_PI) < 0.01);
        for (; now < 1400000; now += 1000) {       /* silent */
            vdrive_step(v, 0.001);
            vdrive_poll(v, now, tx, 8);
        }
        assert_int_equal(vdrive_state(v), want[k]);
        assert_int_equal(vdrive_stats(v)->hb_losses, 1);
        if (opts[k])
            assert_true(fabs(vdrive_velocity(v)) < 1e-9);
        vdrive_destroy(v);
    }
}

/* The same master and drives talking through real fds: one end of a SOCK_SEQPACKET
 * socketpair each, through the CAN layer's frame I/O. */
static void master_and_drives_over_socketpair(void **state)
{
    int sv[2];
    assert_int_equal(socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    can_bus_t *mb = can_bus_from_fd(sv[0]), *db = can_bus_from_fd(sv[1]);
    assert_non_null(mb);
    assert_non_null(db);
    drives_cfg_t cfg;
    drives_cfg_default(&cfg);
    rig_t ev = { 0 };
    drives_ctl_t *ctl = drives_ctl_create(&cfg, on_ev, &ev);
    vdrive_t *vd[2];
    for (int i = 0; i < 2; i++) {
        vdrive_cfg_t vc;
        vdrive_cfg_default(&vc, (uint8_t)(i + 1));
        vd[i] = vdrive_create(&vc);
    }
    struct can_frame tx[16], f;
    int64_t now = 1000000;
    for (int i = 0; i < 2; i++) {
        int n = vdrive_boot(vd[i], now, tx, 16);
        for (int k = 0; k < n; k++)
            assert_int_equal(can_bus_write(db, &tx[k]), 0);
    }
    int n = drives_ctl_start(ctl, now, tx, 16);
    for (int k = 0; k < n; k++)
        can_bus_write(mb, &tx[k]);
    for (int ms = 0; ms < 1500; ms++) {
        now += 1000;
        /* drain both ends until quiet: the configuration is many SDO round trips */
        for (int round = 0; round < 64; round++) {
            int moved = 0;
            while (can_bus_read(db, &f) == 1) {
                moved++;
                for (int i = 0; i < 2; i++) {
                    n = vdrive_feed(vd[i], &f, now, tx, 16);
                    for (int k = 0; k < n; k++)
                        can_bus_write(db, &tx[k]);
                }
            }
            while (can_bus_read(mb, &f) == 1) {
                moved++;
                n = drives_ctl_feed(ctl, &f, now, tx, 16);
                for (int k = 0; k < n; k++)
                    can_bus_write(mb, &tx[k]);
            }
            if (!moved)
                break;
        }
        for (int i = 0; i < 2; i++) {
            vdrive_step(vd[i], 0.001);
            n = vdrive_poll(vd[i], now, tx, 16);
            for (int k = 0; k < n; k++)
                can_bus_write(db, &tx[k]);
        }
        if (ms % 20 == 0) {
            drives_ctl_set_wheels(ctl, 1.5, -1.5, now);
            n = drives_ctl_cycle(ctl, now, tx, 16);
            for (int k = 0; k < n; k++)
                can_bus_write(mb, &tx[k]);
        }
    }
    assert_true(drives_ctl_all_enabled(ctl));
    assert_true(fabs(vdrive_velocity(vd[0]) - 1.5) < 0.01);
    assert_true(fabs(vdrive_velocity(vd[1]) + 1.5) < 0.01);
    assert_int_equal(can_bus_stats(mb)->rx_bad, 0);
    assert_true(can_bus_stats(mb)->tx > 100);
    drives_ctl_destroy(ctl);
    vdrive_destroy(vd[0]);
    vdrive_destroy(vd[1]);
    can_bus_close(mb);
    can_bus_close(db);
}

/* The automatic transitions of the virtual drive: 1 (self test), 13 and 14 (fault reaction). */
static void vdrive_automatic_transitions(void **state)
{
    vdrive_cfg_t vc;
    vdrive_cfg_default(&vc, 7);
    vdrive_t *v = vdrive_create(&vc);
    struct can_frame tx[8], f;
    assert_int_equal(vdrive_state(v), CIA402_NOT_READY);
    assert_int_equal(vdrive_boot(v, 0, tx, 8), 1);
    assert_int_equal(vdrive_state(v), CIA402_SWITCH_ON_DISABLED);              /* 1 */
    co_sdo_client_t c;
    co_sdo_client_init(&c, 7, 100000, NULL, NULL);
    int8_t mode = CIA402_MODE_PROFILE_VELOCITY;
    co_sdo_client_download(&c, CIA402_OBJ_MODE, 0, &mode, 1, 0, &f);
    assert_int_equal(vdrive_feed(v, &f, 0, tx, 8), 1);
    assert_int_equal(tx[0].data[0], 0x60);
    co_nmt_encode(&f, CO_NMT_CMD_START, 7);
    vdrive_feed(v, &f, 0, tx, 8);
    uint16_t cws[] = { 0x06, 0x07, 0x0F };
    for (int i = 0; i < 3; i++) {
        struct can_frame r = { .can_id = 0x207, .len = 6, .data = { (uint8_t)cws[i], 0, 0x00, 0x10, 0, 0 } };
        vdrive_feed(v, &r, 0, tx, 8);
        co_sync_encode(&f, 0);
        vdrive_feed(v, &f, 0, tx, 8);
    }
    assert_int_equal(vdrive_state(v), CIA402_OPERATION_ENABLED);
    vdrive_step(v, 0.5);
    assert_true(vdrive_velocity(v) > 1.0);
    vdrive_inject_fault(v, CO_EMCY_OVERVOLTAGE);
    assert_int_equal(vdrive_state(v), CIA402_FAULT_REACTION_ACTIVE);          /* 13 */
    assert_int_equal(cia402_state_from_sw(vdrive_statusword(v)), CIA402_FAULT_REACTION_ACTIVE);
    int n = vdrive_poll(v, 0, tx, 8);
    assert_int_equal(n, 1);
    assert_int_equal(tx[0].can_id, 0x87);
    assert_int_equal(co_get_u16(tx[0].data), CO_EMCY_OVERVOLTAGE);
    for (int i = 0; i < 100 && vdrive_state(v) != CIA402_FAULT; i++)
        vdrive_step(v, 0.01);
    assert_int_equal(vdrive_state(v), CIA402_FAULT);                          /* 14 */
    assert_true(fabs(vdrive_velocity(v)) < 1e-9);
    /* SDO: only profile velocity mode is accepted */
    co_sdo_client_init(&c, 7, 100000, NULL, NULL);
    mode = 1;
    co_sdo_client_download(&c, CIA402_OBJ_MODE, 0, &mode, 1, 0, &f);
    assert_int_equal(vdrive_feed(v, &f, 0, tx, 8), 1);
    assert_int_equal(tx[0].data[0], 0x80);
    assert_int_equal(co_get_u32(tx[0].data + 4), CO_SDO_ABORT_RANGE);
    vdrive_destroy(v);
}

int main(void)
{
#define T(x) cmocka_unit_test_setup_teardown(x, setup, teardown)
    const struct CMUnitTest tests[] = {
        T(startup_configures_and_enables),
        T(velocity_reaches_the_wheels),
        T(command_flood_is_one_rpdo_per_drive_per_cycle),
        T(command_timeout_stops_the_wheels),
        T(estop_quick_stops_then_releases),
        T(fault_with_emcy_is_reset_and_recovers),
        T(statusword_fault_without_emcy),
        T(emcy_storm_is_counted_not_flooded),
        T(malformed_and_unexpected_frames),
        T(heartbeat_loss_then_reconnect),
        T(drive_reboot_is_reconfigured),
        T(disable_brings_drives_down),
        T(master_death_stops_the_drives),
        T(rpdo_deadline_stops_the_drives),
        cmocka_unit_test_setup_teardown(forged_bootup_and_failed_config_stop_the_drive, setup_no_deadline, teardown),
        T(shutdown_leaves_drives_disabled_and_stopped),
        cmocka_unit_test_setup_teardown(drive_without_name_comes_up, setup_nameless, teardown),
        cmocka_unit_test_setup_teardown(drive_without_0x1016_relies_on_its_rpdo_deadline, setup_no_consumer, teardown),
        cmocka_unit_test_setup_teardown(drive_watching_nothing_is_refused, setup_unwatched, teardown),
        cmocka_unit_test_setup_teardown(drive_watching_nothing_is_driven_where_allowed, setup_unwatched_allowed, teardown),
        cmocka_unit_test_setup_teardown(rebooted_drive_waits_for_a_new_command, setup_long_cmd_timeout, teardown),
        cmocka_unit_test_setup_teardown(recovered_drive_waits_for_a_new_command, setup_long_cmd_timeout, teardown),
        cmocka_unit_test_setup_teardown(early_config_failure_is_no_heartbeat_loss, setup_mute, teardown),
        T(fault_without_emcy_says_no_emcy),
        cmocka_unit_test(identity_object_in_drive_and_gyro),
        cmocka_unit_test(reset_communication_restores_communication_objects),
        cmocka_unit_test(expedited_download_without_size),
        cmocka_unit_test(abort_connection_option_code),
        cmocka_unit_test(vdrive_automatic_transitions),
        cmocka_unit_test(master_and_drives_over_socketpair),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
