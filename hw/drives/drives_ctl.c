/* drives_ctl: CANopen master logic for the two wheel drives. */
#include "hw/drives/drives_ctl.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"
#include "core/log.h"
#include "hw/canopen/co.h"
#include "hw/canopen/emcy.h"
#include "hw/canopen/pdo.h"

#define EMCY_STORM 10       /* per second and axis: beyond this, count without events */

static const co_pdo_map_t tpdo1_map = { 0, 2, { { 0x6041, 0, 16 }, { 0x6064, 0, 32 } } };
static const co_pdo_map_t tpdo2_map = { 0, 1, { { 0x606C, 0, 32 } } };
static const co_pdo_map_t rpdo1_map = { 0, 2, { { 0x6040, 0, 16 }, { 0x60FF, 0, 32 } } };

/* Configuration written to each drive, in order: these steps, then the three PDO mappings above
 * (CiA 301's remapping procedure, co_pdo_map_steps). An optional object the drive does not have
 * (abort "no object" / "no sub-index") is skipped. */
enum { V_HB = CO_STEP_OWN, V_CONSUMER, V_RPDO_TMO };
static const co_sdo_step_t setup[] = {
    { CO_STEP_UP, 0x1000, 0, 4, CO_STEP_CONST, 0 },        /* device type: must be 402 */
    /* identity: CiA 301 asks for the vendor id only; the rest is read where it is */
    { CO_STEP_UP_OPT, 0x1018, 1, 4, CO_STEP_CONST, 0 },
    { CO_STEP_UP_OPT, 0x1018, 2, 4, CO_STEP_CONST, 0 },
    { CO_STEP_UP_OPT, 0x1018, 3, 4, CO_STEP_CONST, 0 },
    { CO_STEP_UP_OPT, 0x1018, 4, 4, CO_STEP_CONST, 0 },
    { CO_STEP_UP_OPT, 0x1008, 0, 0, CO_STEP_CONST, 0 },    /* device name (segmented upload) */
    { CO_STEP_DN, CIA402_OBJ_MODE, 0, 1, CO_STEP_CONST, CIA402_MODE_PROFILE_VELOCITY },
    { CO_STEP_DN, 0x1017, 0, 2, V_HB, 0 },
    /* the drive watches our heartbeat and reacts per 0x6007 (1: fault reaction) when it stops;
     * 0x1016 is optional in CiA 301: without it only the RPDO deadline (0x1400:05) watches us */
    { CO_STEP_DN_OPT, 0x1016, 1, 4, V_CONSUMER, 0 },
    { CO_STEP_DN_OPT, CIA402_OBJ_ABORT_CONN, 0, 2, CO_STEP_CONST, 1 },
};
#define NSETUP ((int)(sizeof setup / sizeof setup[0]))
static const co_sdo_step_t rpdo_deadline = { CO_STEP_DN_OPT, 0x1400, 5, 2, V_RPDO_TMO, 0 };

struct drives_ctl {
    drives_cfg_t cfg;
    co_sdo_step_t jobs[NSETUP + 3 * CO_PDO_MAX_STEPS];
    int njobs;
    drives_event_cb_t cb;
    void *user;
    drives_axis_t ax[DRIVES_N];
    co_hb_consumer_t hb;
    bool enable, estop;
    double wheel[DRIVES_N];
    int64_t cmd_us;
    bool have_cmd;
    int64_t now;
    /* frames produced inside callbacks (SDO done, heartbeat events) wait here */
    struct can_frame pend[8];
    int npend;
    int64_t hb_sent_us;     /* our own heartbeat */
};

const char *drives_ev_name(drives_ev_t ev)
{
    static const char *n[] = { "configured", "config_failed", "fault", "fault_reset", "recovered",
                               "emcy", "emcy_storm", "hb_timeout", "bootup", "bad_frame", "unexpected",
                               "emcy_quiet", "optional_missing", "watch", "hold", "not_found" };
    return (unsigned)ev < sizeof n / sizeof n[0] ? n[ev] : "?";
}

void drives_cfg_default(drives_cfg_t *cfg) { *cfg = (drives_cfg_t)DRIVES_CFG_DEFAULTS; }

/* The parameters in the protocol's units: s to us, s to ms; an axis' node id and mounting. */
static int64_t us(double s) { return (int64_t)(s * 1e6); }
static uint16_t ms(double s) { return (uint16_t)lround(s * 1000); }
static uint8_t node_id(const drives_ctl_t *d, int i) { return (uint8_t)(i == DRIVES_LEFT ? d->cfg.left_node : d->cfg.right_node); }
static bool inverted(const drives_ctl_t *d, int i) { return i == DRIVES_LEFT ? d->cfg.left_invert : d->cfg.right_invert; }

static void ev(drives_ctl_t *d, int axis, drives_ev_t e, uint32_t code)
{
    if (d->cb)
        d->cb(d->user, axis, e, code);
}

static void pend(drives_ctl_t *d, const struct can_frame *f)
{
    if (d->npend < (int)(sizeof d->pend / sizeof d->pend[0]))
        d->pend[d->npend++] = *f;
}

static int axis_of_node(const drives_ctl_t *d, uint8_t id)
{
    for (int i = 0; i < DRIVES_N; i++)
        if (node_id(d, i) == id)
            return i;
    return -1;
}

static void set_phase(drives_ctl_t *d, int i, drives_ax_phase_t p)
{
    d->ax[i].phase = p;
    d->ax[i].phase_since = d->now;
}

/* We lose control of a drive (it may be operational and turning): NMT takes it out of
 * operational first, which a CiA 402 drive answers per 0x6007, before anything else goes out.
 * Pre-operational keeps its SDO server for a configuration that follows at once. */
static void stop_drive(drives_ctl_t *d, int i, co_nmt_cmd_t cmd)
{
    struct can_frame f;
    co_nmt_encode(&f, cmd, node_id(d, i));
    pend(d, &f);
    d->ax[i].stops++;
}

/* NMT reset communication: the drive reboots into its power-on communication objects, 0x1017
 * = 0 among them, so its heartbeat is not awaited until the configuration writes it again. */
static void reset_drive(drives_ctl_t *d, int i)
{
    struct can_frame f;
    co_nmt_encode(&f, CO_NMT_CMD_RESET_COMM, node_id(d, i));
    pend(d, &f);
    co_hb_consumer_set_timeout(&d->hb, node_id(d, i), 0, d->now);
    d->ax[i].booted = false;
}

/* The values of the drive's own kinds of configuration step. */
static uint32_t job_value(void *user, const co_sdo_step_t *j)
{
    const drives_ctl_t *d = user;
    if (j->kind == V_HB)
        return d->cfg.heartbeat_ms;
    if (j->kind == V_CONSUMER)
        return d->cfg.master_heartbeat_ms ? (uint32_t)d->cfg.master_node << 16 | ms(d->cfg.master_timeout) : 0;
    return ms(d->cfg.rpdo_timeout);
}

/* Configured: how will the drive notice that we died? By our heartbeat (0x1016), or by its
 * RPDO deadline (0x1400:05) alone; a drive that watches neither would keep turning: refused,
 * unless the system file allows it. */
static void check_watch(drives_ctl_t *d, int i)
{
    drives_axis_t *a = &d->ax[i];
    if (a->watches_hb)
        return;
    if (a->watches_rpdo) {
        ev(d, i, DRIVES_EV_WATCH, DRIVES_WATCH_RPDO_ONLY);
        return;
    }
    a->refused = !d->cfg.allow_unwatched;
    ev(d, i, DRIVES_EV_WATCH, a->refused ? DRIVES_WATCH_NONE_REFUSED : DRIVES_WATCH_NONE_ALLOWED);
}

static void run_job(drives_ctl_t *d, int i)
{
    drives_axis_t *a = &d->ax[i];
    struct can_frame f;
    bool last = !co_sdo_steps_next(&a->sdo, d->jobs, d->njobs, a->job, job_value, d, d->now, &f);
    pend(d, &f);
    if (last) {
        set_phase(d, i, DRIVES_AX_RUN);     /* have_tpdo is still false: start_config's */
        a->fail = (drives_cfg_fail_t){ 0 };
        check_watch(d, i);
        ev(d, i, DRIVES_EV_CONFIGURED, 0);
    }
}

/* A configuration step failed: the drive is stopped, the failure kept (naming the object)
 * and told, and the configuration starts again after DRIVES_BOOT_RETRY_US. */
static void config_failed(drives_ctl_t *d, int i, uint16_t index, uint8_t sub, uint32_t abort, uint32_t value)
{
    drives_axis_t *a = &d->ax[i];
    bool write = a->job < d->njobs && (d->jobs[a->job].op == CO_STEP_DN || d->jobs[a->job].op == CO_STEP_DN_OPT);
    drives_cfg_fail_t f = { index, sub, write, abort, value, 0 };
    if (a->fail.index == index && a->fail.sub == sub && a->fail.abort == abort && a->fail.value == value)
        f.repeats = a->fail.repeats + 1;
    a->fail = f;
    if (abort)
        a->sdo_aborts++;
    a->config_failures++;
    stop_drive(d, i, CO_NMT_CMD_STOP);
    ev(d, i, DRIVES_EV_CONFIG_FAILED, abort);
    set_phase(d, i, DRIVES_AX_BOOT);        /* retried after DRIVES_BOOT_RETRY_US */
}

/* A step's value, taken. Heartbeat supervision begins once 0x1017 is written. */
static void took(drives_ctl_t *d, int i, uint16_t index, uint8_t sub, const uint8_t *data, size_t len)
{
    drives_axis_t *a = &d->ax[i];
    if (index == 0x1008 && data) {
        size_t n = len < sizeof a->name - 1 ? len : sizeof a->name - 1;
        memcpy(a->name, data, n);
        a->name[n] = 0;
    } else if (index == 0x1018 && sub >= 1 && sub <= 4 && len == 4) {
        a->identity[sub - 1] = co_get_u32(data);
    } else if (index == 0x1017) {
        int64_t t = d->cfg.heartbeat_ms ? us(d->cfg.heartbeat_timeout) : 0;
        co_hb_consumer_set_timeout(&d->hb, node_id(d, i), t, d->now);
    } else if (index == 0x1016) {
        a->watches_hb = d->cfg.master_heartbeat_ms > 0;
    } else if (index == 0x1400 && sub == 5) {
        a->watches_rpdo = ms(d->cfg.rpdo_timeout) > 0;
    }
}

/* An optional object the drive has not: skipped, told once per object and configuration. */
static void missing(drives_ctl_t *d, int i, uint16_t index, uint8_t sub)
{
    drives_axis_t *a = &d->ax[i];
    if (index == 0x1016)
        a->lacks_consumer = true;
    if (a->missing_index != index)
        ev(d, i, DRIVES_EV_OPTIONAL_MISSING, (uint32_t)index << 8 | sub);
    a->missing_index = index;
}

static void sdo_done(void *user, co_sdo_client_t *c, uint16_t index, uint8_t sub, uint32_t abort,
                     const uint8_t *data, size_t len)
{
    drives_ctl_t *d = user;
    int i = c == &d->ax[0].sdo ? 0 : 1;
    drives_axis_t *a = &d->ax[i];
    if (a->phase != DRIVES_AX_CONFIG)
        return;
    if (!abort && index == 0x1000 && (len != 4 || (co_get_u32(data) & 0xFFFF) != 402)) {
        config_failed(d, i, index, sub, 0, len == 4 ? co_get_u32(data) : 0);   /* not a CiA 402 drive */
        return;
    }
    if (a->job < d->njobs && co_sdo_step_skips(&d->jobs[a->job], abort)) {
        missing(d, i, index, sub);
    } else if (abort) {
        config_failed(d, i, index, sub, abort, 0);
        return;
    } else {
        took(d, i, index, sub, data, len);
    }
    a->job++;
    run_job(d, i);
}

/* A boot-up: the drive starts from its power-on objects, which the configuration writes
 * again; what it had before (watching, refusal, a pending fault's EMCY) is forgotten, and it
 * will not move before a motor command newer than its enabling (restart interlock). */
static void start_config(drives_ctl_t *d, int i)
{
    drives_axis_t *a = &d->ax[i];
    set_phase(d, i, DRIVES_AX_CONFIG);
    co_hb_consumer_set_timeout(&d->hb, node_id(d, i), 0, d->now);
    a->job = 0;
    a->state = CIA402_UNKNOWN;
    a->have_tpdo = false;
    a->name[0] = 0;
    memset(a->identity, 0, sizeof a->identity);
    a->watches_hb = a->watches_rpdo = a->lacks_consumer = a->refused = false;
    a->have_fault_emcy = false;
    a->interlocked = true;
    a->enabled_at = 0;
    a->missing_index = 0;
    co_sdo_client_init(&a->sdo, node_id(d, i), us(d->cfg.sdo_timeout), sdo_done, d);
    run_job(d, i);
}

static void hb_event(void *user, uint8_t node, co_hb_event_t e, co_nmt_state_t s)
{
    drives_ctl_t *d = user;
    int i = axis_of_node(d, node);
    if (i < 0)
        return;
    drives_axis_t *a = &d->ax[i];
    switch (e) {
    case CO_HB_EV_BOOTUP:
        a->bootups++;
        a->booted = true;
        a->not_found_told = false;
        /* A boot-up while we drove it may be forged or a glitch: make sure it is not left
         * turning during the configuration (a real boot-up finds it pre-operational anyway). */
        if (a->phase == DRIVES_AX_RUN || a->phase == DRIVES_AX_CONFIG)
            stop_drive(d, i, CO_NMT_CMD_ENTER_PREOP);
        a->nmt = CO_NMT_PREOPERATIONAL;
        ev(d, i, DRIVES_EV_BOOTUP, 0);
        start_config(d, i);
        break;
    case CO_HB_EV_STATE:
        a->nmt = s;
        /* A drive that fell out of operational (NMT from elsewhere, internal reset) while
         * we think it runs: configure it again from the start. */
        if (a->phase == DRIVES_AX_RUN && s != CO_NMT_OPERATIONAL &&
            d->now - a->phase_since > 2 * (int64_t)d->cfg.heartbeat_ms * 1000) {
            reset_drive(d, i);
            set_phase(d, i, DRIVES_AX_BOOT);
        }
        break;
    case CO_HB_EV_TIMEOUT:
        a->hb_timeouts++;
        stop_drive(d, i, CO_NMT_CMD_STOP);      /* deaf to us, maybe not dumb: stop it */
        a->nmt = CO_NMT_UNKNOWN;
        a->state = CIA402_UNKNOWN;
        set_phase(d, i, DRIVES_AX_OFFLINE);
        ev(d, i, DRIVES_EV_HB_TIMEOUT, 0);
        break;
    case CO_HB_EV_RECOVERED:
        /* Heard again without a boot-up: it may have kept its configuration, but we cannot
         * know; reset its communication so it reboots into a known state. */
        if (s != CO_NMT_BOOTUP) {
            reset_drive(d, i);
            set_phase(d, i, DRIVES_AX_BOOT);
        }
        break;
    }
}

static bool node_ok(int64_t n) { return n >= 1 && n <= CO_NODE_MAX; }
static bool period_ok(int64_t ms) { return ms >= 0 && ms <= 65535; }
static bool seconds_ok(double s, double max) { return s >= 0 && s <= max; }

int drives_cfg_check(const drives_cfg_t *c, char *why, size_t len)
{
    if (!node_ok(c->left_node) || !node_ok(c->right_node) || !node_ok(c->master_node) ||
        c->left_node == c->right_node || c->master_node == c->left_node || c->master_node == c->right_node)
        return marie_fail_why(why, len, "node ids 1..127, the drives' and master_node distinct");
    if (c->ticks_per_rev <= 0 || c->ticks_per_rev > INT32_MAX)
        return marie_fail_why(why, len, "ticks_per_rev must be positive");
    if (!period_ok(c->heartbeat_ms) || !period_ok(c->master_heartbeat_ms))
        return marie_fail_why(why, len, "heartbeat_ms and master_heartbeat_ms 0..65535");
    if (!seconds_ok(c->master_timeout, 65.535) || !seconds_ok(c->rpdo_timeout, 65.535))
        return marie_fail_why(why, len, "master_timeout and rpdo_timeout 0..65.535 s");
    if (c->master_heartbeat_ms > 0 && c->master_timeout * 1000 <= c->master_heartbeat_ms)
        return marie_fail_why(why, len, "master_timeout (s) longer than master_heartbeat_ms");
    if (!seconds_ok(c->cmd_timeout, INFINITY) || !seconds_ok(c->heartbeat_timeout, INFINITY) ||
        !seconds_ok(c->sdo_timeout, INFINITY) || !seconds_ok(c->fault_reset_delay, INFINITY))
        return marie_fail_why(why, len, "cmd_timeout, heartbeat_timeout, sdo_timeout and fault_reset_delay "
                                        "must not be negative");
    return 0;
}

drives_ctl_t *drives_ctl_create(const drives_cfg_t *cfg, drives_event_cb_t cb, void *user)
{
    if (!cfg || drives_cfg_check(cfg, NULL, 0) < 0)
        return marie_fail_null(EINVAL);
    drives_ctl_t *d = calloc(1, sizeof *d);
    if (!d)
        return NULL;
    d->cfg = *cfg;
    memcpy(d->jobs, setup, sizeof setup);
    d->njobs = NSETUP;
    d->njobs += co_pdo_map_steps(d->jobs + d->njobs, 0x1400, CO_COB_RPDO1, &rpdo1_map, 1, &rpdo_deadline);
    d->njobs += co_pdo_map_steps(d->jobs + d->njobs, 0x1800, CO_COB_TPDO1, &tpdo1_map, 1, NULL);
    d->njobs += co_pdo_map_steps(d->jobs + d->njobs, 0x1801, CO_COB_TPDO2, &tpdo2_map, 1, NULL);
    d->cb = cb;
    d->user = user;
    d->enable = true;
    for (int i = 0; i < DRIVES_N; i++) {
        d->ax[i].state = CIA402_UNKNOWN;
        d->ax[i].nmt = CO_NMT_UNKNOWN;
        d->ax[i].interlocked = true;
        co_sdo_client_init(&d->ax[i].sdo, node_id(d, i), us(cfg->sdo_timeout), sdo_done, d);
    }
    co_hb_consumer_init(&d->hb, hb_event, d);
    return d;
}

void drives_ctl_destroy(drives_ctl_t *d) { free(d); }

static int take_pending(drives_ctl_t *d, struct can_frame *tx, int n, int max)
{
    int k = 0;
    while (k < d->npend && n < max)
        tx[n++] = d->pend[k++];
    memmove(d->pend, d->pend + k, (size_t)(d->npend - k) * sizeof d->pend[0]);
    d->npend -= k;
    return n;
}

int drives_ctl_start(drives_ctl_t *d, int64_t now, struct can_frame *tx, int max)
{
    d->now = now;
    co_hb_consumer_init(&d->hb, hb_event, d);
    for (int i = 0; i < DRIVES_N; i++) {
        co_hb_consumer_add(&d->hb, node_id(d, i), 0, now);   /* timed once 0x1017 is written */
        reset_drive(d, i);
        set_phase(d, i, DRIVES_AX_BOOT);
    }
    return take_pending(d, tx, 0, max);
}

void drives_ctl_enable(drives_ctl_t *d, bool enable) { d->enable = enable; }
void drives_ctl_set_estop(drives_ctl_t *d, bool pressed) { d->estop = pressed; }

void drives_ctl_set_wheels(drives_ctl_t *d, double left, double right, int64_t now)
{
    double m = d->cfg.max_wheel_velocity;
    if (!isfinite(left)) left = 0;
    if (!isfinite(right)) right = 0;
    /* Scale both together so the curvature survives the limit. */
    double big = fmax(fabs(left), fabs(right));
    if (m > 0 && big > m) {
        left *= m / big;
        right *= m / big;
    }
    d->wheel[DRIVES_LEFT] = left;
    d->wheel[DRIVES_RIGHT] = right;
    d->cmd_us = now;
    d->have_cmd = true;
}

bool drives_ctl_command_stale(const drives_ctl_t *d, int64_t now)
{
    int64_t timeout = us(d->cfg.cmd_timeout);
    return !d->have_cmd || (timeout > 0 && now - d->cmd_us > timeout);
}

double drives_ctl_counts_to_rad(const drives_ctl_t *d, double counts)
{
    return counts * 2 * M_PI / d->cfg.ticks_per_rev;
}

static void note_state(drives_ctl_t *d, int i, uint16_t sw)
{
    drives_axis_t *a = &d->ax[i];
    cia402_state_t ns = cia402_state_from_sw(sw);
    a->statusword = sw;
    if (ns == a->state)
        return;
    if (ns == CIA402_FAULT || ns == CIA402_FAULT_REACTION_ACTIVE) {
        if (a->state != CIA402_FAULT && a->state != CIA402_FAULT_REACTION_ACTIVE) {
            a->faults++;
            a->fault_since = d->now;
            a->recovering = true;
            ev(d, i, DRIVES_EV_FAULT, a->have_fault_emcy ? a->fault_emcy : 0);
        }
    } else if (ns == CIA402_OPERATION_ENABLED && a->recovering) {
        a->recovering = false;
        ev(d, i, DRIVES_EV_RECOVERED, 0);
    }
    /* Restart interlock: leaving operation enabled arms it, entering it dates it. */
    if (a->state == CIA402_OPERATION_ENABLED)
        a->interlocked = true;
    if (ns == CIA402_OPERATION_ENABLED && a->interlocked) {
        a->enabled_at = d->now;
        a->hold_told = false;
    }
    a->state = ns;
}

int drives_ctl_feed(drives_ctl_t *d, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max)
{
    d->now = now;
    uint8_t node;
    int pdo;
    co_fc_t fc = co_classify(rx->can_id, &node, &pdo);
    int i = axis_of_node(d, node);
    if (rx->can_id & CAN_ERR_FLAG)
        return 0;
    if (i < 0 || fc == CO_FC_OTHER || fc == CO_FC_NMT || fc == CO_FC_SYNC) {
        ev(d, -1, DRIVES_EV_UNEXPECTED, rx->can_id);
        return 0;
    }
    drives_axis_t *a = &d->ax[i];
    switch (fc) {
    case CO_FC_HEARTBEAT:
        if (co_hb_consumer_feed(&d->hb, rx, now) < 0)
            ev(d, i, DRIVES_EV_BAD_FRAME, rx->can_id);
        break;
    case CO_FC_SDO_TX: {
        struct can_frame f;
        bool ready;
        if (!co_sdo_client_busy(&a->sdo)) {
            /* nobody asked: a late answer, or another client on the bus */
            ev(d, i, rx->len != 8 ? DRIVES_EV_BAD_FRAME : DRIVES_EV_UNEXPECTED, rx->can_id);
            break;
        }
        int r = co_sdo_client_feed(&a->sdo, rx, now, &f, &ready);
        if (r < 0)
            ev(d, i, DRIVES_EV_BAD_FRAME, rx->can_id);
        if (ready)
            pend(d, &f);
        break;
    }
    case CO_FC_EMCY: {
        co_emcy_t e;
        if (co_emcy_decode(rx, &e) < 0) {
            ev(d, i, DRIVES_EV_BAD_FRAME, rx->can_id);
            break;
        }
        a->emcy++;
        a->last_emcy = e.code;
        a->have_fault_emcy = e.code != CO_EMCY_NO_ERROR;     /* 0x0000: error reset, all clear */
        a->fault_emcy = e.code;
        if (now - a->emcy_window_start > 1000000) {
            a->emcy_window_start = now;
            a->emcy_in_window = 0;
        }
        if (++a->emcy_in_window <= EMCY_STORM)
            ev(d, i, DRIVES_EV_EMCY, e.code);
        else if (a->emcy_in_window == EMCY_STORM + 1)
            ev(d, i, DRIVES_EV_EMCY_STORM, e.code);
        else
            ev(d, i, DRIVES_EV_EMCY_QUIET, e.code);
        break;
    }
    case CO_FC_TPDO: {
        uint64_t v[2];
        const co_pdo_map_t *map = pdo == 1 ? &tpdo1_map : pdo == 2 ? &tpdo2_map : NULL;
        if (!map) {
            ev(d, i, DRIVES_EV_UNEXPECTED, rx->can_id);
            break;
        }
        if (co_pdo_decode(map, rx, v) < 0) {
            ev(d, i, DRIVES_EV_BAD_FRAME, rx->can_id);
            break;
        }
        if (a->phase != DRIVES_AX_RUN)
            break;
        if (pdo == 1) {
            int32_t pos = (int32_t)co_pdo_signed(v[1], 32);
            a->position = inverted(d, i) ? (int32_t)(0u - (uint32_t)pos) : pos;
            a->have_tpdo = true;
            note_state(d, i, (uint16_t)v[0]);
        } else {
            int32_t vel = (int32_t)co_pdo_signed(v[0], 32);
            a->velocity = inverted(d, i) ? -vel : vel;
        }
        break;
    }
    default:
        /* RPDO or SDO request to our node from someone else: a second master on the bus. */
        ev(d, i, DRIVES_EV_UNEXPECTED, rx->can_id);
        break;
    }
    return take_pending(d, tx, 0, max);
}

static int rpdo(drives_ctl_t *d, int i, struct can_frame *f)
{
    drives_axis_t *a = &d->ax[i];
    uint64_t v[2] = { a->controlword, (uint32_t)a->target };
    co_pdo_map_t m = rpdo1_map;
    m.cob_id = CO_COB_RPDO1 + node_id(d, i);
    a->rpdo_cw = a->controlword;
    return co_pdo_encode(&m, v, f) > 0;
}

/* The restart interlock holds a drive (re)enabled at enabled_at until a motor command newer
 * than that: a drive that rebooted, recovered from a fault or came back from a stop, an e-stop
 * or a pause does not resume a command given before. */
static bool interlock_holds(drives_ctl_t *d, int i, int64_t now)
{
    drives_axis_t *a = &d->ax[i];
    if (!a->interlocked)
        return false;
    if (a->state != CIA402_OPERATION_ENABLED || !a->enabled_at)
        return true;
    if (d->have_cmd && d->cmd_us > a->enabled_at) {
        a->interlocked = false;
        return false;
    }
    if (!a->hold_told && !drives_ctl_command_stale(d, now) && d->wheel[i] != 0) {
        a->hold_told = true;
        ev(d, i, DRIVES_EV_HOLD, 0);
    }
    return true;
}

static void compute_target(drives_ctl_t *d, int i, int64_t now)
{
    drives_axis_t *a = &d->ax[i];
    double w = d->wheel[i];
    if (d->estop || !d->enable || drives_ctl_command_stale(d, now) || a->state != CIA402_OPERATION_ENABLED ||
        a->refused || interlock_holds(d, i, now))
        w = 0;
    if (inverted(d, i))
        w = -w;
    a->target = (int32_t)lround(w * d->cfg.ticks_per_rev / (2 * M_PI));
}

static cia402_want_t want(const drives_ctl_t *d, int i)
{
    if (!d->enable || d->ax[i].refused)
        return CIA402_WANT_DISABLED;
    return d->estop ? CIA402_WANT_QUICK_STOP : CIA402_WANT_ENABLED;
}

/* RPDO1 of each running drive now; unless `force`, one whose early RPDO1 of this SYNC period
 * already went out with the same controlword waits for the cycle's. */
static int rpdo_early(drives_ctl_t *d, int64_t now, struct can_frame *tx, int max, bool force)
{
    int n = 0;
    for (int i = 0; i < DRIVES_N && n < max; i++) {
        drives_axis_t *a = &d->ax[i];
        if (a->phase != DRIVES_AX_RUN)
            continue;
        /* e-stop or disable take effect now (the drive applies them at the next SYNC);
         * enabling and fault resets are the cycle's business */
        if (a->have_tpdo && want(d, i) != CIA402_WANT_ENABLED)
            a->controlword = cia402_next_controlword(a->state, want(d, i), a->controlword, false);
        compute_target(d, i, now);
        if (!force && a->rpdo_early && a->controlword == a->rpdo_cw)
            continue;
        n += rpdo(d, i, &tx[n]);
        a->rpdo_early = true;
    }
    return n;
}

int drives_ctl_rpdo_now(drives_ctl_t *d, int64_t now, struct can_frame *tx, int max)
{
    return rpdo_early(d, now, tx, max, false);
}

/* Our heartbeat, on the cycle when due; a cycle a little early still sends it, so timer
 * jitter does not stretch the period to two cycles. */
static int heartbeat(drives_ctl_t *d, int64_t now, struct can_frame *f)
{
    int64_t period = (int64_t)d->cfg.master_heartbeat_ms * 1000;
    if (period <= 0 || (d->hb_sent_us && now - d->hb_sent_us < period - period / 4))
        return 0;
    d->hb_sent_us = now;
    co_hb_encode(f, d->cfg.master_node, CO_NMT_OPERATIONAL);
    return 1;
}

int drives_ctl_shutdown(drives_ctl_t *d, int64_t now, struct can_frame *tx, int max)
{
    d->now = now;
    d->enable = false;
    int n = rpdo_early(d, now, tx, max, true);
    if (n > 0 && n < max)
        n += co_sync_encode(&tx[n], 0) >= 0;
    for (int i = 0; i < DRIVES_N && n < max; i++)
        n += co_nmt_encode(&tx[n], CO_NMT_CMD_STOP, node_id(d, i)) > 0;
    return n;
}

int drives_ctl_cycle(drives_ctl_t *d, int64_t now, struct can_frame *tx, int max)
{
    d->now = now;
    int n = heartbeat(d, now, &tx[0]);
    co_hb_consumer_check(&d->hb, now);
    for (int i = 0; i < DRIVES_N; i++) {
        drives_axis_t *a = &d->ax[i];
        struct can_frame f;
        if (co_sdo_client_poll(&a->sdo, now, &f)) {
            /* the callback already moved the axis back to BOOT; the abort frame goes out */
            pend(d, &f);
        }
        if ((a->phase == DRIVES_AX_BOOT || a->phase == DRIVES_AX_OFFLINE) &&
            now - a->phase_since >= DRIVES_BOOT_RETRY_US) {
            if (a->phase == DRIVES_AX_BOOT && !a->booted && !a->not_found_told) {
                a->not_found_told = true;
                ev(d, i, DRIVES_EV_NOT_FOUND, 0);
            }
            reset_drive(d, i);
            a->phase_since = now;
        }
    }
    n = take_pending(d, tx, n, max);
    bool any_run = false;
    for (int i = 0; i < DRIVES_N && n < max; i++) {
        drives_axis_t *a = &d->ax[i];
        if (a->phase != DRIVES_AX_RUN)
            continue;
        any_run = true;
        bool allow = now - a->fault_since >= us(d->cfg.fault_reset_delay);
        uint16_t cw = a->have_tpdo ? cia402_next_controlword(a->state, want(d, i), a->controlword, allow)
                                   : CIA402_CW_DISABLE_VOLTAGE;
        if (cw == CIA402_CW_FAULT_RESET && !(a->controlword & CIA402_CW_FAULT_RESET)) {
            a->fault_resets++;
            a->fault_since = now;       /* next attempt only after another delay */
            ev(d, i, DRIVES_EV_FAULT_RESET, a->fault_emcy);
        }
        a->controlword = cw;
        compute_target(d, i, now);
        n += rpdo(d, i, &tx[n]);
        a->rpdo_early = false;          /* the SYNC below closes the period */
    }
    if (any_run && n < max) {
        co_sync_encode(&tx[n], 0);
        n++;
    }
    return n;
}

const drives_axis_t *drives_ctl_axis(const drives_ctl_t *d, int axis) { return &d->ax[axis]; }

bool drives_ctl_all_enabled(const drives_ctl_t *d)
{
    for (int i = 0; i < DRIVES_N; i++)
        if (d->ax[i].phase != DRIVES_AX_RUN || d->ax[i].state != CIA402_OPERATION_ENABLED)
            return false;
    return true;
}

int drives_ctl_filters(const drives_ctl_t *d, struct can_filter *f, int max)
{
    int n = 0;
    for (int i = 0; i < DRIVES_N && n < max; i++) {
        f[n].can_id = node_id(d, i);
        f[n].can_mask = 0x7F | CAN_EFF_FLAG | CAN_RTR_FLAG;
        n++;
    }
    return n;
}

uint8_t drives_ctl_node(const drives_ctl_t *d, int axis) { return node_id(d, axis); }
uint16_t drives_ctl_rpdo_timeout_ms(const drives_ctl_t *d) { return ms(d->cfg.rpdo_timeout); }
