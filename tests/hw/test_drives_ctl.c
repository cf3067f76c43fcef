/* test_drives_ctl: the wheel-drive master against two virtual CiA 402 drives on an in-memory
 * bus: configuration, enabling, velocity, command timeout, e-stop, faults with EMCY or only
 * in the statusword, fault reset, EMCY storms, malformed frames, heartbeat loss and reboot. */
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

#define QMAX 256
typedef struct {
    drives_ctl_t *ctl;
    vdrive_t *vd[2];
    int64_t now;
    bool cut[2];                /* drive i disconnected */
    struct { struct can_frame f; int src; } q[QMAX];   /* src: -1 master, 0/1 drive */
    int qh, qt;
    int ev[16];                 /* events seen per kind */
    uint32_t last_code[16];
    int frames_on_bus;
} rig_t;

static void on_ev(void *user, int axis, drives_ev_t e, uint32_t code)
{
    rig_t *r = user;
    r->ev[e]++;
    r->last_code[e] = code;
}

static void put(rig_t *r, const struct can_frame *f, int n, int src)
{
    for (int i = 0; i < n; i++) {
        if (src >= 0 && r->cut[src])
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
        if (src != -1)
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
        if (r->now % 20000 == 0) {
            if (command)
                drives_ctl_set_wheels(r->ctl, wl, wr, r->now);
            put(r, tx, drives_ctl_cycle(r->ctl, r->now, tx, 16), -1);
        }
        deliver(r);
    }
}

static int setup(void **state)
{
    rig_t *r = calloc(1, sizeof *r);
    drives_cfg_t cfg;
    drives_cfg_default(&cfg);
    cfg.node[0] = 1;
    cfg.node[1] = 2;
    cfg.invert[1] = false;
    r->ctl = drives_ctl_create(&cfg, on_ev, r);
    for (int i = 0; i < 2; i++) {
        vdrive_cfg_t vc;
        vdrive_cfg_default(&vc, (uint8_t)(i + 1));
        r->vd[i] = vdrive_create(&vc);
    }
    r->now = 1000000;
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
        T(command_timeout_stops_the_wheels),
        T(estop_quick_stops_then_releases),
        T(fault_with_emcy_is_reset_and_recovers),
        T(statusword_fault_without_emcy),
        T(emcy_storm_is_counted_not_flooded),
        T(malformed_and_unexpected_frames),
        T(heartbeat_loss_then_reconnect),
        T(drive_reboot_is_reconfigured),
        T(disable_brings_drives_down),
        cmocka_unit_test(vdrive_automatic_transitions),
        cmocka_unit_test(master_and_drives_over_socketpair),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
