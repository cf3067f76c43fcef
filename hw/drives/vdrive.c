/* vdrive: virtual CiA 402 drive on the generic CANopen device of hw/canopen. */
#include "hw/drives/vdrive.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"
#include "hw/canopen/co.h"
#include "hw/canopen/emcy.h"

#define OUTBOX 8

struct vdrive {
    vdrive_cfg_t cfg;
    char name[32];
    co_dev_t dev;
    co_od_entry_t od[16];
    /* object values */
    uint32_t device_type;
    uint16_t error_code, controlword, statusword;
    int8_t mode, mode_display;
    int16_t abort_opt;          /* 0x6007 abort connection option code */
    int32_t position, velocity, target;
    uint32_t acc, qs_dec;
    /* drive */
    cia402_state_t state;
    uint16_t prev_cw;
    double setpoint;            /* rad/s, ramped */
    double pos_rad, vel_rad;
    bool external;
    int64_t now_us;
    struct can_frame outbox[OUTBOX];
    int nout;
};

void vdrive_cfg_default(vdrive_cfg_t *cfg, uint8_t node)
{
    *cfg = (vdrive_cfg_t)VDRIVE_DEFAULTS;
    cfg->node = node;
}

static double counts_to_rad(const vdrive_t *v, double c) { return c * 2 * M_PI / v->cfg.ticks_per_rev; }
static double rad_to_counts(const vdrive_t *v, double r) { return r * v->cfg.ticks_per_rev / (2 * M_PI); }

static void queue(vdrive_t *v, const struct can_frame *f)
{
    if (v->nout < OUTBOX)
        v->outbox[v->nout++] = *f;
}

static void queue_emcy(vdrive_t *v, uint16_t code)
{
    struct can_frame f;
    uint8_t reg = code ? 0x01 : 0x00;           /* generic error bit */
    if ((code >> 12) == 2) reg |= 0x02;         /* current */
    if ((code >> 12) == 3) reg |= 0x04;         /* voltage */
    if ((code >> 12) == 4) reg |= 0x08;         /* temperature */
    if ((code >> 12) == 8) reg |= 0x10;         /* communication */
    uint8_t vendor[5] = { 0 };
    co_put_u16(vendor, v->statusword);
    if (co_dev_emcy(&v->dev, code, reg, vendor, &f))
        queue(v, &f);
}

static void update_sw(vdrive_t *v)
{
    uint16_t sw = cia402_sw_from_state(v->state) | CIA402_SW_REMOTE;
    double target = v->state == CIA402_OPERATION_ENABLED ? counts_to_rad(v, v->target) : 0;
    if (fabs(v->vel_rad - target) < 0.05)
        sw |= CIA402_SW_TARGET_REACHED;
    if (fabs(v->vel_rad) < 0.01)
        sw |= CIA402_SW_SPEED_ZERO;
    v->statusword = sw;
    v->mode_display = v->mode;
    /* Position wraps as the i32 object does. */
    v->position = (int32_t)(uint32_t)(int64_t)llround(rad_to_counts(v, v->pos_rad));
    v->velocity = (int32_t)lround(rad_to_counts(v, v->vel_rad));
}

static void apply_controlword(vdrive_t *v)
{
    cia402_cmd_t cmd = cia402_decode_controlword(v->state, v->controlword, v->prev_cw);
    v->prev_cw = v->controlword;
    cia402_state_t ns = cia402_transition(v->state, cmd);
    if (ns == v->state)
        return;
    if (v->state == CIA402_FAULT && ns == CIA402_SWITCH_ON_DISABLED) {
        v->error_code = 0;
        queue_emcy(v, CO_EMCY_NO_ERROR);        /* the fault is gone */
        v->dev.err_reg = 0;
    }
    if (!cia402_state_powered(ns))
        v->setpoint = 0;                        /* power stage off: the wheel coasts */
    v->state = ns;
    update_sw(v);
}

static void on_rpdo(void *user, co_dev_t *d, int pdo)
{
    vdrive_t *v = user;
    apply_controlword(v);
}

static void on_sync(void *user, co_dev_t *d) { update_sw(user); }

static uint32_t on_write(void *user, co_dev_t *d, uint16_t index, uint8_t sub)
{
    vdrive_t *v = user;
    if (index == CIA402_OBJ_MODE && v->mode != CIA402_MODE_PROFILE_VELOCITY && v->mode != 0)
        return CO_SDO_ABORT_RANGE;              /* only profile velocity is implemented */
    if (index == CIA402_OBJ_ABORT_CONN && (v->abort_opt < 0 || v->abort_opt > 3))
        return CO_SDO_ABORT_RANGE;              /* no manufacturer-specific reactions */
    if (index == CIA402_OBJ_CONTROLWORD)
        apply_controlword(v);
    update_sw(v);
    return 0;
}

static void reset_app(vdrive_t *v)
{
    v->state = v->state == CIA402_FAULT ? CIA402_FAULT : CIA402_SWITCH_ON_DISABLED;
    v->controlword = v->prev_cw = 0;
    v->target = 0;
    v->setpoint = 0;
    v->mode = 0;
    v->abort_opt = 1;
    update_sw(v);
}

/* CiA 402: a communication error (heartbeat or RPDO lost, NMT out of operational) while the
 * power stage drives the motor is answered per 0x6007: 1 fault (fault reaction: quick-stop
 * ramp, then power off), 2 disable voltage, 3 quick stop; 0 nothing. `emcy`: the node has
 * not told the master yet. */
static void comm_abort(vdrive_t *v, uint16_t code, bool emcy)
{
    if (!cia402_state_powered(v->state) || v->state == CIA402_FAULT_REACTION_ACTIVE)
        return;
    switch (v->abort_opt) {
    case 1:
        v->state = CIA402_FAULT_REACTION_ACTIVE;
        v->error_code = code;
        if (emcy)
            queue_emcy(v, code);
        break;
    case 2:
        v->state = CIA402_SWITCH_ON_DISABLED;
        v->setpoint = 0;
        break;
    case 3:
        v->state = CIA402_QUICK_STOP_ACTIVE;
        break;
    default:
        return;
    }
    update_sw(v);
}

static void on_comm_error(void *user, co_dev_t *d, uint16_t code) { comm_abort(user, code, false); }

static void on_nmt(void *user, co_dev_t *d, co_nmt_state_t s, bool reset)
{
    vdrive_t *v = user;
    if (reset) {
        reset_app(v);
        return;
    }
    if (s != CO_NMT_OPERATIONAL)
        comm_abort(v, CO_EMCY_HB_ERROR, true);
}

vdrive_t *vdrive_create(const vdrive_cfg_t *cfg)
{
    if (cfg->ticks_per_rev <= 0 || cfg->ticks_per_rev > INT32_MAX)
        return marie_fail_null(EINVAL);
    vdrive_t *v = calloc(1, sizeof *v);
    if (!v)
        return NULL;
    v->cfg = *cfg;
    snprintf(v->name, sizeof v->name, "%s", cfg->name ? cfg->name : "marie vdrive");
    v->device_type = CIA402_DEVICE_TYPE;
    v->acc = (uint32_t)rad_to_counts(v, cfg->accel);
    v->qs_dec = (uint32_t)rad_to_counts(v, cfg->quickstop_decel);
    co_od_entry_t od[] = {
        { 0x1000, 0, 4, CO_OD_RO, &v->device_type },
        { 0x1008, 0, 0, CO_OD_RO, v->name },
        { CIA402_OBJ_ERROR_CODE, 0, 2, CO_OD_RO, &v->error_code },
        { CIA402_OBJ_CONTROLWORD, 0, 2, CO_OD_RW, &v->controlword },
        { CIA402_OBJ_STATUSWORD, 0, 2, CO_OD_RO, &v->statusword },
        { CIA402_OBJ_MODE, 0, 1, CO_OD_RW, &v->mode },
        { CIA402_OBJ_MODE_DISPLAY, 0, 1, CO_OD_RO, &v->mode_display },
        { CIA402_OBJ_POSITION, 0, 4, CO_OD_RO, &v->position },
        { CIA402_OBJ_VELOCITY, 0, 4, CO_OD_RO, &v->velocity },
        { CIA402_OBJ_PROFILE_ACC, 0, 4, CO_OD_RW, &v->acc },
        { CIA402_OBJ_QUICKSTOP_DEC, 0, 4, CO_OD_RW, &v->qs_dec },
        { CIA402_OBJ_TARGET_VEL, 0, 4, CO_OD_RW, &v->target },
        { CIA402_OBJ_ABORT_CONN, 0, 2, CO_OD_RW, &v->abort_opt },
    };
    memcpy(v->od, od, sizeof od);
    size_t nod = sizeof od / sizeof od[0];
    if (!v->name[0]) {
        /* an empty name: a drive without the optional 0x1008 (entry 1) */
        memmove(&v->od[1], &v->od[2], (nod - 2) * sizeof v->od[0]);
        nod--;
    }
    static const co_dev_hooks_t hooks = { on_nmt, on_rpdo, on_sync, on_write, on_comm_error };
    co_dev_init(&v->dev, cfg->node, v->od, nod, &hooks, v);
    v->dev.opts = cfg->opts;
    co_dev_set_identity(&v->dev, VDRIVE_VENDOR_ID, VDRIVE_PRODUCT_CODE, VDRIVE_REVISION, cfg->node);
    v->abort_opt = 1;
    /* Defaults that marie-drives also writes at configuration (see docs/hw/drives.md). */
    uint32_t rmap[] = { 0x60400010, 0x60FF0020 };
    uint32_t t1map[] = { 0x60410010, 0x60640020 };
    uint32_t t2map[] = { 0x606C0020 };
    int64_t tmo_us = (int64_t)(cfg->rpdo_timeout * 1e6);
    int64_t tmo_ms = tmo_us > 0 && !cfg->opts.no_rpdo_deadline ? (tmo_us + 999) / 1000 : 0;
    co_dev_set_pdo(&v->dev, false, 1, CO_COB_RPDO1 + cfg->node, 1, (uint16_t)(tmo_ms > 65535 ? 65535 : tmo_ms),
                   rmap, 2);
    co_dev_set_pdo(&v->dev, true, 1, CO_COB_TPDO1 + cfg->node, 1, 0, t1map, 2);
    co_dev_set_pdo(&v->dev, true, 2, CO_COB_TPDO2 + cfg->node, 1, 0, t2map, 1);
    v->state = CIA402_NOT_READY;
    update_sw(v);
    return v;
}

void vdrive_destroy(vdrive_t *v) { free(v); }

static int flush(vdrive_t *v, struct can_frame *tx, int n, int max)
{
    int k = 0;
    while (k < v->nout && n < max)
        tx[n++] = v->outbox[k++];
    memmove(v->outbox, v->outbox + k, (size_t)(v->nout - k) * sizeof v->outbox[0]);
    v->nout -= k;
    return n;
}

int vdrive_boot(vdrive_t *v, int64_t now, struct can_frame *tx, int max)
{
    if (max <= 0)
        return 0;
    v->now_us = now;
    v->state = CIA402_NOT_READY;
    reset_app(v);                   /* transition 1: self test passed */
    v->state = CIA402_SWITCH_ON_DISABLED;
    update_sw(v);
    return co_dev_boot(&v->dev, now, tx);
}

int vdrive_feed(vdrive_t *v, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max)
{
    v->now_us = now;
    int n = co_dev_feed(&v->dev, rx, now, tx, max);
    return flush(v, tx, n, max);
}

int vdrive_poll(vdrive_t *v, int64_t now, struct can_frame *tx, int max)
{
    v->now_us = now;
    int n = co_dev_poll(&v->dev, now, tx, max);
    return flush(v, tx, n, max);
}

static double ramp(double from, double to, double rate, double dt)
{
    double step = rate * dt;
    if (to > from + step) return from + step;
    if (to < from - step) return from - step;
    return to;
}

void vdrive_step(vdrive_t *v, double dt)
{
    double acc = counts_to_rad(v, v->acc), dec = counts_to_rad(v, v->qs_dec);
    switch (v->state) {
    case CIA402_OPERATION_ENABLED: {
        double t = v->mode == CIA402_MODE_PROFILE_VELOCITY ? counts_to_rad(v, v->target) : 0;
        if (t > v->cfg.max_velocity) t = v->cfg.max_velocity;
        if (t < -v->cfg.max_velocity) t = -v->cfg.max_velocity;
        v->setpoint = ramp(v->setpoint, t, acc, dt);
        break;
    }
    case CIA402_QUICK_STOP_ACTIVE:
        v->setpoint = ramp(v->setpoint, 0, dec, dt);
        break;
    case CIA402_FAULT_REACTION_ACTIVE:
        v->setpoint = ramp(v->setpoint, 0, dec, dt);
        if (v->setpoint == 0)
            v->state = CIA402_FAULT;            /* transition 14 */
        break;
    default:
        v->setpoint = 0;
        break;
    }
    if (!v->external) {
        v->vel_rad = v->setpoint;
        v->pos_rad += v->vel_rad * dt;
    }
    update_sw(v);
}

double vdrive_command(const vdrive_t *v) { return v->setpoint; }

void vdrive_set_feedback(vdrive_t *v, double pos_rad, double vel_rad_s)
{
    v->external = true;
    v->pos_rad = pos_rad;
    v->vel_rad = vel_rad_s;
    update_sw(v);
}

double vdrive_velocity(const vdrive_t *v) { return v->vel_rad; }

static void fault(vdrive_t *v, uint16_t code, bool emcy)
{
    if (v->state == CIA402_FAULT || v->state == CIA402_FAULT_REACTION_ACTIVE)
        return;
    v->state = cia402_state_powered(v->state) ? CIA402_FAULT_REACTION_ACTIVE : CIA402_FAULT;
    v->error_code = code;
    if (emcy)
        queue_emcy(v, code);
    update_sw(v);
}

void vdrive_inject_fault(vdrive_t *v, uint16_t code) { fault(v, code, true); }
void vdrive_inject_silent_fault(vdrive_t *v, uint16_t code) { fault(v, code, false); }
cia402_state_t vdrive_state(const vdrive_t *v) { return v->state; }
uint16_t vdrive_statusword(const vdrive_t *v) { return v->statusword; }
co_nmt_state_t vdrive_nmt(const vdrive_t *v) { return v->dev.nmt; }
uint8_t vdrive_node(const vdrive_t *v) { return v->cfg.node; }
const co_dev_stats_t *vdrive_stats(const vdrive_t *v) { return &v->dev.stats; }
