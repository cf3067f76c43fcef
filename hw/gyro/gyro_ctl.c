/* gyro_ctl: CANopen master logic for the gyro. */
#include "hw/gyro/gyro_ctl.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"
#include "hw/canopen/co.h"
#include "hw/canopen/emcy.h"
#include "hw/canopen/pdo.h"
#include "hw/gyro/gyro_proto.h"

enum { PH_BOOT, PH_CONFIG, PH_RUN, PH_OFFLINE };
static const co_pdo_map_t tpdo_map = GYRO_TPDO_MAP;

/* Configuration written to the gyro, in order: these steps, then its TPDO's mapping
 * (co_pdo_map_steps), event-driven (type 254, manufacturer specific) every period_ms. */
enum { V_HB = CO_STEP_OWN, V_PERIOD };
static const co_sdo_step_t setup[] = {
    { CO_STEP_UP, 0x1008, 0, 0, CO_STEP_CONST, 0 },
    { CO_STEP_DN, 0x1017, 0, 2, V_HB, 0 },
};
#define NSETUP ((int)(sizeof setup / sizeof setup[0]))
static const co_sdo_step_t event_timer = { CO_STEP_DN, 0x1800, 5, 2, V_PERIOD, 0 };

struct gyro_ctl {
    gyro_cfg_t cfg;
    co_sdo_step_t jobs[NSETUP + CO_PDO_MAX_STEPS];
    int njobs;
    gyro_sample_cb_t on_sample;
    gyro_event_cb_t on_event;
    void *user;
    int phase, job;
    int64_t phase_since, now;
    co_sdo_client_t sdo;
    co_hb_consumer_t hb;
    bool have_counter;
    uint8_t counter;
    bool booted;                    /* a boot-up heard since the start */
    bool not_found_reported;
    char name[32];
    struct can_frame pend[4];
    int npend;
};

void gyro_cfg_default(gyro_cfg_t *cfg) { *cfg = (gyro_cfg_t)GYRO_CFG_DEFAULTS; }

/* The TPDO's event timer, ms: one sample per period. */
static uint16_t period_ms(const gyro_ctl_t *g) { return (uint16_t)lround(1000 / g->cfg.rate_hz); }

static void hb_event(void *user, uint8_t node, co_hb_event_t e, co_nmt_state_t s);

static void ev(gyro_ctl_t *g, gyro_ev_t e, uint32_t code)
{
    if (g->on_event)
        g->on_event(g->user, e, code);
}

static void pend(gyro_ctl_t *g, const struct can_frame *f)
{
    if (g->npend < 4)
        g->pend[g->npend++] = *f;
}

static int take(gyro_ctl_t *g, struct can_frame *tx, int max)
{
    int n = 0;
    while (n < g->npend && n < max) {
        tx[n] = g->pend[n];
        n++;
    }
    memmove(g->pend, g->pend + n, (size_t)(g->npend - n) * sizeof g->pend[0]);
    g->npend -= n;
    return n;
}

static void set_phase(gyro_ctl_t *g, int p)
{
    g->phase = p;
    g->phase_since = g->now;
}

/* Heartbeat supervision of the node from now on; timeout 0 only listens (for boot-ups).
 * A node sends heartbeats only once 0x1017 is written (a reset communication clears it),
 * so a timeout counted from the start or from the boot-up is a race with the
 * configuration, not a fault: the timeout is armed when the write is confirmed. */
static void watch(gyro_ctl_t *g, int64_t timeout_us)
{
    co_hb_consumer_init(&g->hb, hb_event, g);
    co_hb_consumer_add(&g->hb, g->cfg.node, timeout_us, g->now);
}

/* The values of the gyro's own kinds of configuration step. */
static uint32_t job_value(void *user, const co_sdo_step_t *j)
{
    const gyro_ctl_t *g = user;
    return j->kind == V_HB ? (uint32_t)g->cfg.heartbeat_ms : period_ms(g);
}

static void run_job(gyro_ctl_t *g)
{
    struct can_frame f;
    bool last = !co_sdo_steps_next(&g->sdo, g->jobs, g->njobs, g->job, job_value, g, g->now, &f);
    pend(g, &f);
    if (last) {
        set_phase(g, PH_RUN);
        g->have_counter = false;
        ev(g, GYRO_EV_CONFIGURED, 0);
    }
}

static void sdo_done(void *user, co_sdo_client_t *c, uint16_t index, uint8_t sub, uint32_t abort,
                     const uint8_t *data, size_t len)
{
    gyro_ctl_t *g = user;
    if (g->phase != PH_CONFIG)
        return;
    if (abort) {
        ev(g, GYRO_EV_CONFIG_FAILED, abort);
        set_phase(g, PH_BOOT);
        return;
    }
    if (index == 0x1008 && data) {
        size_t n = len < sizeof g->name - 1 ? len : sizeof g->name - 1;
        memcpy(g->name, data, n);
        g->name[n] = 0;
    }
    if (index == 0x1017 && g->cfg.heartbeat_ms)
        watch(g, (int64_t)(g->cfg.heartbeat_timeout * 1e6));
    g->job++;
    run_job(g);
}

static void hb_event(void *user, uint8_t node, co_hb_event_t e, co_nmt_state_t s)
{
    gyro_ctl_t *g = user;
    struct can_frame f;
    switch (e) {
    case CO_HB_EV_BOOTUP:
        ev(g, GYRO_EV_BOOTUP, 0);
        g->booted = true;
        g->not_found_reported = false;
        watch(g, 0);        /* its heartbeat restarts with the configuration */
        set_phase(g, PH_CONFIG);
        g->job = 0;
        co_sdo_client_init(&g->sdo, (uint8_t)g->cfg.node, GYRO_SDO_TIMEOUT_US, sdo_done, g);
        run_job(g);
        break;
    case CO_HB_EV_TIMEOUT:
        ev(g, GYRO_EV_HB_TIMEOUT, 0);
        set_phase(g, PH_OFFLINE);
        break;
    case CO_HB_EV_RECOVERED:
        if (s != CO_NMT_BOOTUP) {
            co_nmt_encode(&f, CO_NMT_CMD_RESET_COMM, g->cfg.node);
            pend(g, &f);
            set_phase(g, PH_BOOT);
        }
        break;
    case CO_HB_EV_STATE:
        if (g->phase == PH_RUN && s != CO_NMT_OPERATIONAL &&
            g->now - g->phase_since > 2 * (int64_t)g->cfg.heartbeat_ms * 1000) {
            co_nmt_encode(&f, CO_NMT_CMD_RESET_COMM, g->cfg.node);
            pend(g, &f);
            set_phase(g, PH_BOOT);
        }
        break;
    }
}

gyro_ctl_t *gyro_ctl_create(const gyro_cfg_t *cfg, gyro_sample_cb_t on_sample, gyro_event_cb_t on_event, void *user)
{
    if (!cfg || cfg->node < 1 || cfg->node > CO_NODE_MAX || !(cfg->rate_hz >= 1 && cfg->rate_hz <= 1000) ||
        cfg->heartbeat_ms < 0 || cfg->heartbeat_ms > 65535 || !(cfg->heartbeat_timeout >= 0))
        return marie_fail_null(EINVAL);
    gyro_ctl_t *g = calloc(1, sizeof *g);
    if (!g)
        return NULL;
    g->cfg = *cfg;
    memcpy(g->jobs, setup, sizeof setup);
    g->njobs = NSETUP + co_pdo_map_steps(g->jobs + NSETUP, 0x1800, CO_COB_TPDO1, &tpdo_map, 254, &event_timer);
    g->on_sample = on_sample;
    g->on_event = on_event;
    g->user = user;
    co_sdo_client_init(&g->sdo, (uint8_t)cfg->node, GYRO_SDO_TIMEOUT_US, sdo_done, g);
    co_hb_consumer_init(&g->hb, hb_event, g);
    return g;
}

void gyro_ctl_destroy(gyro_ctl_t *g) { free(g); }

int gyro_ctl_start(gyro_ctl_t *g, int64_t now, struct can_frame *tx, int max)
{
    g->now = now;
    g->booted = false;
    g->not_found_reported = false;
    watch(g, 0);
    struct can_frame f;
    co_nmt_encode(&f, CO_NMT_CMD_RESET_COMM, g->cfg.node);
    pend(g, &f);
    set_phase(g, PH_BOOT);
    return take(g, tx, max);
}

int gyro_ctl_feed(gyro_ctl_t *g, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max)
{
    g->now = now;
    uint8_t node;
    int pdo;
    if (rx->can_id & CAN_ERR_FLAG)
        return 0;
    co_fc_t fc = co_classify(rx->can_id, &node, &pdo);
    if (node != g->cfg.node || fc == CO_FC_OTHER || fc == CO_FC_NMT || fc == CO_FC_SYNC) {
        ev(g, GYRO_EV_UNEXPECTED, rx->can_id);
        return 0;
    }
    switch (fc) {
    case CO_FC_HEARTBEAT:
        if (co_hb_consumer_feed(&g->hb, rx, now) < 0)
            ev(g, GYRO_EV_BAD_FRAME, rx->can_id);
        break;
    case CO_FC_SDO_TX: {
        struct can_frame f;
        bool ready;
        if (co_sdo_client_feed(&g->sdo, rx, now, &f, &ready) < 0)
            ev(g, GYRO_EV_BAD_FRAME, rx->can_id);
        if (ready)
            pend(g, &f);
        break;
    }
    case CO_FC_EMCY: {
        co_emcy_t e;
        if (co_emcy_decode(rx, &e) < 0)
            ev(g, GYRO_EV_BAD_FRAME, rx->can_id);
        else
            ev(g, GYRO_EV_EMCY, e.code);
        break;
    }
    case CO_FC_TPDO: {
        uint64_t v[3];
        if (g->phase != PH_RUN)
            break;
        if (pdo != 1) {
            ev(g, GYRO_EV_UNEXPECTED, rx->can_id);
            break;
        }
        if (co_pdo_decode(&tpdo_map, rx, v) < 0) {
            ev(g, GYRO_EV_BAD_FRAME, rx->can_id);
            break;
        }
        uint8_t cnt = (uint8_t)v[2];
        if (g->have_counter && cnt != (uint8_t)(g->counter + 1))
            ev(g, GYRO_EV_LOST, (uint8_t)(cnt - g->counter - 1));
        g->counter = cnt;
        g->have_counter = true;
        if (g->on_sample)
            g->on_sample(g->user, (double)co_pdo_signed(v[0], 32) * GYRO_RATE_SCALE, (uint8_t)v[1]);
        break;
    }
    default:
        ev(g, GYRO_EV_UNEXPECTED, rx->can_id);
        break;
    }
    return take(g, tx, max);
}

int gyro_ctl_poll(gyro_ctl_t *g, int64_t now, struct can_frame *tx, int max)
{
    g->now = now;
    struct can_frame f;
    co_hb_consumer_check(&g->hb, now);
    if (co_sdo_client_poll(&g->sdo, now, &f))
        pend(g, &f);
    if ((g->phase == PH_BOOT || g->phase == PH_OFFLINE) && now - g->phase_since >= GYRO_BOOT_RETRY_US) {
        if (!g->booted && !g->not_found_reported) {
            g->not_found_reported = true;
            ev(g, GYRO_EV_NOT_FOUND, 0);
        }
        co_nmt_encode(&f, CO_NMT_CMD_RESET_COMM, g->cfg.node);
        pend(g, &f);
        g->phase_since = now;
    }
    return take(g, tx, max);
}

bool gyro_ctl_running(const gyro_ctl_t *g) { return g->phase == PH_RUN; }
const char *gyro_ctl_name(const gyro_ctl_t *g) { return g->name; }

int gyro_ctl_filters(const gyro_ctl_t *g, struct can_filter *f, int max)
{
    if (max < 1)
        return 0;
    f[0].can_id = g->cfg.node;
    f[0].can_mask = 0x7F | CAN_EFF_FLAG | CAN_RTR_FLAG;
    return 1;
}

double gyro_ctl_period_s(const gyro_ctl_t *g) { return period_ms(g) / 1000.0; }
