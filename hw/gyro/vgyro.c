/* vgyro: virtual gyro on the generic CANopen device. */
#include "hw/gyro/vgyro.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hw/canopen/co.h"
#include "hw/canopen/emcy.h"
#include "hw/canopen/pdo.h"
#include "hw/gyro/gyro_proto.h"

struct vgyro {
    vgyro_cfg_t cfg;
    char name[32];
    co_dev_t dev;
    co_od_entry_t od[6];
    uint32_t device_type;
    int32_t rate;
    uint8_t status, counter;
    double truth;
    int fault;
    uint64_t rng;
    struct can_frame out[4];
    int nout;
};

void vgyro_cfg_default(vgyro_cfg_t *cfg, uint8_t node)
{
    *cfg = (vgyro_cfg_t)VGYRO_DEFAULTS;
    cfg->node = node;
}

static double uniform(vgyro_t *g)
{
    g->rng = g->rng * 6364136223846793005ULL + 1442695040888963407ULL;
    return ((g->rng >> 11) + 0.5) / 9007199254740992.0;
}

static double gauss(vgyro_t *g)
{
    return sqrt(-2 * log(uniform(g))) * cos(2 * M_PI * uniform(g));
}

vgyro_t *vgyro_create(const vgyro_cfg_t *cfg)
{
    vgyro_t *g = calloc(1, sizeof *g);
    if (!g)
        return NULL;
    g->cfg = *cfg;
    g->rng = cfg->seed ? (uint64_t)cfg->seed : 1;
    snprintf(g->name, sizeof g->name, "%s", cfg->name ? cfg->name : "marie vgyro");
    co_od_entry_t od[] = {
        { 0x1000, 0, 4, CO_OD_RO, &g->device_type },
        { 0x1008, 0, 0, CO_OD_RO, g->name },
        { GYRO_OBJ_RATE, 0, 4, CO_OD_RO, &g->rate },
        { GYRO_OBJ_STATUS, 0, 1, CO_OD_RO, &g->status },
        { GYRO_OBJ_COUNTER, 0, 1, CO_OD_RO, &g->counter },
    };
    memcpy(g->od, od, sizeof od);
    co_dev_init(&g->dev, cfg->node, g->od, 5, NULL, g);
    const co_pdo_map_t tm = GYRO_TPDO_MAP;
    uint32_t map[CO_PDO_MAX_ENTRIES];
    for (int i = 0; i < tm.n; i++)
        map[i] = co_pdo_entry_u32(tm.e[i]);
    co_dev_set_pdo(&g->dev, true, 1, CO_COB_TPDO1 + cfg->node, 254, 10, map, tm.n);
    return g;
}

void vgyro_destroy(vgyro_t *g) { free(g); }

int vgyro_boot(vgyro_t *g, int64_t now, struct can_frame *tx, int max)
{
    return max > 0 ? co_dev_boot(&g->dev, now, tx) : 0;
}

static int flush(vgyro_t *g, struct can_frame *tx, int n, int max)
{
    int k = 0;
    while (k < g->nout && n < max)
        tx[n++] = g->out[k++];
    memmove(g->out, g->out + k, (size_t)(g->nout - k) * sizeof g->out[0]);
    g->nout -= k;
    return n;
}

int vgyro_feed(vgyro_t *g, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max)
{
    return flush(g, tx, co_dev_feed(&g->dev, rx, now, tx, max), max);
}

/* A fresh sample just before the node samples the dictionary for the TPDO. */
static void sample(vgyro_t *g)
{
    double r = g->truth + g->cfg.bias + g->cfg.noise * gauss(g);
    g->status = g->fault ? GYRO_STATUS_SENSOR_FAULT : GYRO_STATUS_OK;
    if (fabs(r) > g->cfg.range) {
        r = r > 0 ? g->cfg.range : -g->cfg.range;
        if (!g->fault)
            g->status = GYRO_STATUS_SATURATED;
    }
    g->rate = (int32_t)lround(r / GYRO_RATE_SCALE);
    g->counter++;
}

int vgyro_poll(vgyro_t *g, int64_t now, struct can_frame *tx, int max)
{
    co_dev_pdo_t *p = &g->dev.tpdo[0];
    /* The device samples only when its event timer is due, so counters match TPDOs. */
    if (g->dev.nmt == CO_NMT_OPERATIONAL && !(p->cob & 0x80000000u) && p->event_ms &&
        (p->next_us == 0 || now >= p->next_us))
        sample(g);
    return flush(g, tx, co_dev_poll(&g->dev, now, tx, max), max);
}

void vgyro_set_rate(vgyro_t *g, double true_yaw_rate) { g->truth = true_yaw_rate; }

void vgyro_set_fault(vgyro_t *g, int fault)
{
    if (!!fault == !!g->fault)
        return;
    g->fault = fault;
    struct can_frame f;
    if (co_dev_emcy(&g->dev, fault ? CO_EMCY_SENSOR : CO_EMCY_NO_ERROR, fault ? 0x81 : 0, NULL, &f) &&
        g->nout < 4)
        g->out[g->nout++] = f;
}

co_nmt_state_t vgyro_nmt(const vgyro_t *g) { return g->dev.nmt; }
