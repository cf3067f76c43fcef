/* dev: a CANopen slave node over an application object dictionary. */
#include "hw/canopen/dev.h"

#include <errno.h>
#include <string.h>

#include "hw/canopen/co.h"
#include "hw/canopen/emcy.h"

static uint64_t od_get(const co_od_entry_t *e)
{
    switch (e->size) {
    case 1: return *(const uint8_t *)e->ptr;
    case 2: return *(const uint16_t *)e->ptr;
    case 4: return *(const uint32_t *)e->ptr;
    case 8: return *(const uint64_t *)e->ptr;
    }
    return 0;
}

static void od_set(const co_od_entry_t *e, uint64_t v)
{
    switch (e->size) {
    case 1: *(uint8_t *)e->ptr = (uint8_t)v; break;
    case 2: *(uint16_t *)e->ptr = (uint16_t)v; break;
    case 4: *(uint32_t *)e->ptr = (uint32_t)v; break;
    case 8: *(uint64_t *)e->ptr = v; break;
    }
}

static const co_od_entry_t *co_dev_find(const co_dev_t *d, uint16_t index, uint8_t sub)
{
    for (size_t i = 0; i < d->nod; i++)
        if (d->od[i].index == index && d->od[i].sub == sub)
            return &d->od[i];
    return NULL;
}

static bool index_exists(const co_dev_t *d, uint16_t index)
{
    for (size_t i = 0; i < d->nod; i++)
        if (d->od[i].index == index)
            return true;
    return false;
}

/* Check a mapping against the dictionary: objects exist, are mappable sizes, fit 64 bits. */
static uint32_t check_map(const co_dev_t *d, const uint32_t *map, uint8_t n, bool tx)
{
    int bits = 0;
    for (int i = 0; i < n; i++) {
        co_pdo_entry_t e = co_pdo_entry_from_u32(map[i]);
        const co_od_entry_t *o = co_dev_find(d, e.index, e.sub);
        if (!o)
            return CO_SDO_ABORT_NO_OBJECT;
        if (o->size == 0 || o->size * 8 != e.bits)
            return 0x06040041u;     /* object cannot be mapped to the PDO */
        if (!(o->access & (tx ? CO_OD_RO : CO_OD_WO)))
            return 0x06040041u;
        bits += e.bits;
    }
    return bits > 64 ? 0x06040042u : 0;   /* number and length exceed PDO length */
}

void co_dev_init(co_dev_t *d, uint8_t node, const co_od_entry_t *od, size_t nod,
                 const co_dev_hooks_t *hooks, void *user);

static uint32_t sdo_read(void *user, uint16_t index, uint8_t sub, uint8_t *buf, size_t cap, size_t *len);
static uint32_t sdo_write(void *user, uint16_t index, uint8_t sub, const uint8_t *data, size_t len);
static const co_sdo_server_ops_t sdo_ops = { sdo_read, sdo_write };

void co_dev_init(co_dev_t *d, uint8_t node, const co_od_entry_t *od, size_t nod,
                 const co_dev_hooks_t *hooks, void *user)
{
    memset(d, 0, sizeof *d);
    d->node = node;
    d->nmt = CO_NMT_UNKNOWN;
    d->od = od;
    d->nod = nod;
    if (hooks)
        d->hooks = *hooks;
    d->user = user;
    for (int i = 0; i < CO_DEV_NPDO; i++) {
        d->tpdo[i].cob = 0x80000000u | (CO_COB_TPDO1 + 0x100u * (unsigned)i + node);
        d->rpdo[i].cob = 0x80000000u | (CO_COB_RPDO1 + 0x100u * (unsigned)i + node);
        d->tpdo[i].type = d->rpdo[i].type = 255;
    }
    memcpy(d->power_on.tpdo, d->tpdo, sizeof d->tpdo);
    memcpy(d->power_on.rpdo, d->rpdo, sizeof d->rpdo);
    d->identity[3] = node;      /* serial: unique on the bus at least */
    co_sdo_server_init(&d->sdo, node, &sdo_ops, d);
}

void co_dev_set_heartbeat(co_dev_t *d, uint16_t producer_ms, const uint32_t *consumer, int n)
{
    d->hb_ms = d->power_on.hb_ms = producer_ms;
    memset(d->consumer, 0, sizeof d->consumer);
    for (int i = 0; i < n && i < CO_DEV_NCONSUMER; i++)
        d->consumer[i] = consumer[i];
    memcpy(d->power_on.consumer, d->consumer, sizeof d->consumer);
}

void co_dev_set_identity(co_dev_t *d, uint32_t vendor, uint32_t product, uint32_t revision, uint32_t serial)
{
    d->identity[0] = vendor;
    d->identity[1] = product;
    d->identity[2] = revision;
    d->identity[3] = serial;
}

/* Reset communication (CiA 301): communication objects back to their power-on values;
 * application objects are the application's business. */
static void restore_comm(co_dev_t *d)
{
    d->hb_ms = d->power_on.hb_ms;
    memcpy(d->consumer, d->power_on.consumer, sizeof d->consumer);
    memcpy(d->tpdo, d->power_on.tpdo, sizeof d->tpdo);
    memcpy(d->rpdo, d->power_on.rpdo, sizeof d->rpdo);
}

void co_dev_set_pdo(co_dev_t *d, bool tx, int pdo, uint32_t cob, uint8_t type, uint16_t event_ms,
                    const uint32_t *map, uint8_t n)
{
    if (pdo < 1 || pdo > CO_DEV_NPDO || n > CO_PDO_MAX_ENTRIES)
        return;
    co_dev_pdo_t *p = tx ? &d->tpdo[pdo - 1] : &d->rpdo[pdo - 1];
    memset(p, 0, sizeof *p);
    p->cob = cob;
    p->type = type;
    p->event_ms = event_ms;
    p->n = n;
    memcpy(p->map, map, n * sizeof *map);
    /* what the application sets up is the power-on value a reset restores */
    *(tx ? &d->power_on.tpdo[pdo - 1] : &d->power_on.rpdo[pdo - 1]) = *p;
}

/* Communication objects: 0x1001, 0x1016, 0x1017, 0x1018, PDO parameters. True if handled. */
static bool comm_object(co_dev_t *d, uint16_t index, uint8_t sub, co_dev_pdo_t **pdo, bool *tx, bool *mapping)
{
    *pdo = NULL;
    if (index >= 0x1400 && index < 0x1400 + CO_DEV_NPDO) { *pdo = &d->rpdo[index - 0x1400]; *tx = false; *mapping = false; }
    else if (index >= 0x1600 && index < 0x1600 + CO_DEV_NPDO) { *pdo = &d->rpdo[index - 0x1600]; *tx = false; *mapping = true; }
    else if (index >= 0x1800 && index < 0x1800 + CO_DEV_NPDO) { *pdo = &d->tpdo[index - 0x1800]; *tx = true; *mapping = false; }
    else if (index >= 0x1A00 && index < 0x1A00 + CO_DEV_NPDO) { *pdo = &d->tpdo[index - 0x1A00]; *tx = true; *mapping = true; }
    return *pdo || index == 0x1001 || (index == 0x1016 && !d->opts.no_consumer) || index == 0x1017 || index == 0x1018;
}

/* An RPDO's event timer (sub 5) on a device that has none. */
static bool no_deadline(const co_dev_t *d, bool tx, bool mapping, uint8_t sub)
{
    return d->opts.no_rpdo_deadline && !tx && !mapping && sub == 5;
}

/* The size of a writable communication object (0: none such). */
static size_t comm_size(uint16_t index, uint8_t sub, bool mapping)
{
    if (index == 0x1017)
        return 2;
    if (index == 0x1016)
        return 4;
    if (mapping)
        return sub ? 4 : 1;
    return sub == 1 ? 4 : sub == 2 ? 1 : sub == 5 ? 2 : 0;
}

static uint32_t put_uint(uint8_t *buf, size_t *len, uint64_t v, size_t size)
{
    for (size_t i = 0; i < size; i++)
        buf[i] = (uint8_t)(v >> (8 * i));
    *len = size;
    return 0;
}

static uint32_t sdo_read(void *user, uint16_t index, uint8_t sub, uint8_t *buf, size_t cap, size_t *len)
{
    co_dev_t *d = user;
    co_dev_pdo_t *p;
    bool tx, mapping;
    if (comm_object(d, index, sub, &p, &tx, &mapping)) {
        if (index == 0x1001)
            return sub ? CO_SDO_ABORT_NO_SUB : put_uint(buf, len, d->err_reg, 1);
        if (index == 0x1017)
            return sub ? CO_SDO_ABORT_NO_SUB : put_uint(buf, len, d->hb_ms, 2);
        if (index == 0x1016) {
            if (sub > CO_DEV_NCONSUMER)
                return CO_SDO_ABORT_NO_SUB;
            return sub ? put_uint(buf, len, d->consumer[sub - 1], 4) : put_uint(buf, len, CO_DEV_NCONSUMER, 1);
        }
        if (index == 0x1018) {
            if (sub > 4)
                return CO_SDO_ABORT_NO_SUB;
            return sub ? put_uint(buf, len, d->identity[sub - 1], 4) : put_uint(buf, len, 4, 1);
        }
        if (mapping) {
            if (sub == 0)
                return put_uint(buf, len, p->n, 1);
            if (sub > CO_PDO_MAX_ENTRIES)
                return CO_SDO_ABORT_NO_SUB;
            return put_uint(buf, len, p->map[sub - 1], 4);
        }
        if (no_deadline(d, tx, mapping, sub))
            return CO_SDO_ABORT_NO_SUB;
        switch (sub) {
        case 0: return put_uint(buf, len, 5, 1);
        case 1: return put_uint(buf, len, p->cob, 4);
        case 2: return put_uint(buf, len, p->type, 1);
        case 5: return put_uint(buf, len, p->event_ms, 2);
        default: return CO_SDO_ABORT_NO_SUB;
        }
    }
    const co_od_entry_t *e = co_dev_find(d, index, sub);
    if (!e)
        return index_exists(d, index) ? CO_SDO_ABORT_NO_SUB : CO_SDO_ABORT_NO_OBJECT;
    if (!(e->access & CO_OD_RO))
        return CO_SDO_ABORT_WRITE_ONLY;
    if (e->size == 0) {
        const char *s = e->ptr;
        size_t n = strlen(s);
        if (n > cap)
            return CO_SDO_ABORT_NO_MEM;
        memcpy(buf, s, n);
        *len = n;
        return 0;
    }
    return put_uint(buf, len, od_get(e), e->size);
}

static uint64_t get_uint(const uint8_t *data, size_t len)
{
    uint64_t v = 0;
    for (size_t i = 0; i < len && i < 8; i++)
        v |= (uint64_t)data[i] << (8 * i);
    return v;
}

/* 0x1016 sub 1..n: one entry per producer; a second active entry for a node is refused. */
static uint32_t write_consumer(co_dev_t *d, uint8_t sub, size_t len, uint32_t v)
{
    if (sub == 0)
        return CO_SDO_ABORT_READ_ONLY;
    if (sub > CO_DEV_NCONSUMER)
        return CO_SDO_ABORT_NO_SUB;
    if (len != 4)
        return CO_SDO_ABORT_TYPE_LEN;
    uint8_t node = (uint8_t)(v >> 16);
    if (v >> 24 || node > CO_NODE_MAX)
        return CO_SDO_ABORT_RANGE;
    for (int i = 0; i < CO_DEV_NCONSUMER; i++) {
        uint32_t o = d->consumer[i];
        if (i != sub - 1 && node && (v & 0xFFFF) && (uint8_t)(o >> 16) == node && (o & 0xFFFF))
            return CO_SDO_ABORT_PARAM_INCOMPAT;
    }
    d->consumer[sub - 1] = v;
    d->consumer_last[sub - 1] = 0;      /* monitoring starts with the next heartbeat heard */
    return 0;
}

static uint32_t sdo_write(void *user, uint16_t index, uint8_t sub, const uint8_t *data, size_t len)
{
    co_dev_t *d = user;
    co_dev_pdo_t *p;
    bool tx, mapping;
    if (comm_object(d, index, sub, &p, &tx, &mapping)) {
        if (len == CO_SDO_LEN_UNSIZED) {
            size_t sz = comm_size(index, sub, mapping);
            len = sz ? sz : 4;
        }
        uint64_t v = get_uint(data, len);
        if (index == 0x1001 || index == 0x1018)
            return sub > (index == 0x1018 ? 4 : 0) ? CO_SDO_ABORT_NO_SUB : CO_SDO_ABORT_READ_ONLY;
        if (index == 0x1016)
            return write_consumer(d, sub, len, (uint32_t)v);
        if (index == 0x1017) {
            if (sub)
                return CO_SDO_ABORT_NO_SUB;
            if (len != 2)
                return CO_SDO_ABORT_TYPE_LEN;
            d->hb_ms = (uint16_t)v;
            d->hb.period_us = 0;    /* restarted below on the next poll */
            return 0;
        }
        if (mapping) {
            if (sub > CO_PDO_MAX_ENTRIES)
                return CO_SDO_ABORT_NO_SUB;
            if (!(p->cob & 0x80000000u))
                return CO_SDO_ABORT_STATE;       /* remap only an invalid PDO */
            if (sub == 0) {
                if (len != 1)
                    return CO_SDO_ABORT_TYPE_LEN;
                if (v > CO_PDO_MAX_ENTRIES)
                    return CO_SDO_ABORT_RANGE;
                uint32_t ab = check_map(d, p->map, (uint8_t)v, tx);
                if (ab)
                    return ab;
                p->n = (uint8_t)v;
                return 0;
            }
            if (len != 4)
                return CO_SDO_ABORT_TYPE_LEN;
            if (p->n != 0)
                return CO_SDO_ABORT_STATE;       /* sub 0 must be 0 while entries change */
            p->map[sub - 1] = (uint32_t)v;
            return 0;
        }
        if (no_deadline(d, tx, mapping, sub))
            return CO_SDO_ABORT_NO_SUB;
        switch (sub) {
        case 0: return CO_SDO_ABORT_READ_ONLY;
        case 1:
            if (len != 4)
                return CO_SDO_ABORT_TYPE_LEN;
            if ((v & 0x7FF) != (p->cob & 0x7FF) && !(p->cob & 0x80000000u) && !(v & 0x80000000u))
                return CO_SDO_ABORT_RANGE;       /* change the id only while invalid */
            p->cob = (uint32_t)v;
            p->latched = false;
            return 0;
        case 2:
            if (len != 1)
                return CO_SDO_ABORT_TYPE_LEN;
            if (v > 240 && v < 252)
                return CO_SDO_ABORT_RANGE;
            p->type = (uint8_t)v;
            return 0;
        case 5:
            if (len != 2)
                return CO_SDO_ABORT_TYPE_LEN;
            p->event_ms = (uint16_t)v;
            p->next_us = 0;     /* RPDO: the deadline runs from the next reception */
            return 0;
        }
        return CO_SDO_ABORT_NO_SUB;
    }
    const co_od_entry_t *e = co_dev_find(d, index, sub);
    if (!e)
        return index_exists(d, index) ? CO_SDO_ABORT_NO_SUB : CO_SDO_ABORT_NO_OBJECT;
    if (!(e->access & CO_OD_WO))
        return CO_SDO_ABORT_READ_ONLY;
    if (len == CO_SDO_LEN_UNSIZED)
        len = e->size && e->size <= 4 ? e->size : 4;
    if (e->size == 0 || len != e->size)
        return len > e->size ? CO_SDO_ABORT_TOO_LONG : CO_SDO_ABORT_TOO_SHORT;
    uint64_t old = od_get(e);
    od_set(e, get_uint(data, len));
    if (d->hooks.on_write) {
        uint32_t ab = d->hooks.on_write(d->user, d, index, sub);
        if (ab) {
            od_set(e, old);
            return ab;
        }
    }
    return 0;
}

int co_dev_boot(co_dev_t *d, int64_t now, struct can_frame *tx)
{
    d->nmt = CO_NMT_PREOPERATIONAL;
    d->booted = true;
    d->hb.period_us = 0;
    for (int i = 0; i < CO_DEV_NPDO; i++) {
        d->rpdo[i].latched = false;
        d->rpdo[i].next_us = 0;
        d->tpdo[i].next_us = 0;
        d->tpdo[i].sync_count = 0;
    }
    memset(d->consumer_last, 0, sizeof d->consumer_last);
    co_hb_encode(tx, d->node, CO_NMT_BOOTUP);
    d->stats.tx_frames++;
    return 1;
}

static int pdo_frame(co_dev_t *d, co_dev_pdo_t *p, struct can_frame *tx)
{
    co_pdo_map_t m = { .cob_id = p->cob & 0x7FF, .n = p->n };
    uint64_t vals[CO_PDO_MAX_ENTRIES];
    for (int i = 0; i < p->n; i++) {
        m.e[i] = co_pdo_entry_from_u32(p->map[i]);
        const co_od_entry_t *e = co_dev_find(d, m.e[i].index, m.e[i].sub);
        vals[i] = e ? od_get(e) : 0;
    }
    if (co_pdo_encode(&m, vals, tx) < 0)
        return 0;
    d->stats.tpdo++;
    d->stats.tx_frames++;
    return 1;
}

/* Write an RPDO's values into the dictionary. */
static void apply_rpdo(co_dev_t *d, int i)
{
    co_dev_pdo_t *p = &d->rpdo[i];
    co_pdo_map_t m = { .cob_id = p->cob & 0x7FF, .n = p->n };
    uint64_t vals[CO_PDO_MAX_ENTRIES];
    for (int k = 0; k < p->n; k++)
        m.e[k] = co_pdo_entry_from_u32(p->map[k]);
    if (co_pdo_decode(&m, &p->rx, vals) < 0) {
        d->stats.bad_rpdo++;
        return;
    }
    for (int k = 0; k < p->n; k++) {
        const co_od_entry_t *e = co_dev_find(d, m.e[k].index, m.e[k].sub);
        if (e)
            od_set(e, vals[k]);
    }
    d->stats.rpdo++;
    if (d->hooks.on_rpdo)
        d->hooks.on_rpdo(d->user, d, i + 1);
}

int co_dev_emcy(co_dev_t *d, uint16_t code, uint8_t reg, const uint8_t vendor[5], struct can_frame *tx)
{
    if (d->nmt == CO_NMT_STOPPED || d->nmt == CO_NMT_UNKNOWN)
        return 0;
    co_emcy_t e = { .node = d->node, .code = code, .reg = reg };
    if (vendor)
        memcpy(e.vendor, vendor, 5);
    d->err_reg = reg;
    co_emcy_encode(tx, &e);
    d->stats.tx_frames++;
    return 1;
}

/* Enter NMT state ns; the application hears of it. */
static void set_nmt(co_dev_t *d, co_nmt_state_t ns)
{
    if (ns == d->nmt)
        return;
    d->nmt = ns;
    for (int i = 0; i < CO_DEV_NPDO; i++) {
        d->tpdo[i].next_us = 0;
        d->rpdo[i].next_us = 0;     /* deadlines run only while operational */
        d->rpdo[i].latched = false;
    }
    if (d->hooks.on_nmt)
        d->hooks.on_nmt(d->user, d, ns, false);
}

/* A heartbeat (or boot-up) from another node: it is alive; its monitoring starts now. */
static void consume_heartbeat(co_dev_t *d, const struct can_frame *rx, uint8_t node, int64_t now)
{
    if (rx->len != 1) {
        d->stats.bad_frames++;
        return;
    }
    for (int i = 0; i < CO_DEV_NCONSUMER; i++)
        if ((d->consumer[i] & 0xFFFF) && (uint8_t)(d->consumer[i] >> 16) == node)
            d->consumer_last[i] = now ? now : 1;
}

int co_dev_feed(co_dev_t *d, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max)
{
    int n = 0;
    uint8_t node;
    int pdo;
    if (max <= 0 || !d->booted)
        return 0;
    co_fc_t fc = co_classify(rx->can_id, &node, &pdo);
    d->stats.rx_frames++;
    switch (fc) {
    case CO_FC_NMT: {
        co_nmt_cmd_t cmd;
        uint8_t target;
        if (co_nmt_decode(rx, &cmd, &target) < 0) {
            d->stats.bad_frames++;
            return 0;
        }
        if (target != 0 && target != d->node)
            return 0;
        d->stats.nmt++;
        bool reset;
        co_nmt_state_t ns = co_nmt_next(d->nmt, cmd, &reset);
        if (reset) {
            /* Reset node also resets the application; reset communication keeps its objects
             * but still leaves operational, which the application hears as a state change. */
            if (cmd == CO_NMT_CMD_RESET_COMM)
                set_nmt(d, CO_NMT_PREOPERATIONAL);
            else if (d->hooks.on_nmt)
                d->hooks.on_nmt(d->user, d, CO_NMT_PREOPERATIONAL, true);
            restore_comm(d);
            return co_dev_boot(d, now, &tx[0]);
        }
        set_nmt(d, ns);
        return 0;
    }
    case CO_FC_HEARTBEAT:
        consume_heartbeat(d, rx, node, now);
        return 0;
    case CO_FC_SDO_RX:
        if (node != d->node || d->nmt == CO_NMT_STOPPED)
            return 0;
        d->stats.sdo_requests++;
        if (co_sdo_server_feed(&d->sdo, rx, &tx[0]) == 1) {
            if ((tx[0].data[0] >> 5) == 4)
                d->stats.sdo_aborts++;
            d->stats.tx_frames++;
            return 1;
        }
        return 0;
    case CO_FC_SYNC:
        if (rx->len > 1) {
            d->stats.bad_frames++;
            return 0;
        }
        if (d->nmt != CO_NMT_OPERATIONAL)
            return 0;
        d->stats.syncs++;
        for (int i = 0; i < CO_DEV_NPDO; i++) {
            co_dev_pdo_t *p = &d->rpdo[i];
            if (p->latched && !(p->cob & 0x80000000u) && p->type <= 240) {
                p->latched = false;
                apply_rpdo(d, i);
            }
        }
        if (d->hooks.on_sync)
            d->hooks.on_sync(d->user, d);
        for (int i = 0; i < CO_DEV_NPDO && n < max; i++) {
            co_dev_pdo_t *p = &d->tpdo[i];
            if ((p->cob & 0x80000000u) || p->type == 0 || p->type > 240)
                continue;
            if (++p->sync_count >= p->type) {
                p->sync_count = 0;
                n += pdo_frame(d, p, &tx[n]);
            }
        }
        return n;
    default:
        break;
    }
    /* RPDOs are matched on their configured COB-ID, which may differ from the default. */
    if (d->nmt != CO_NMT_OPERATIONAL || (rx->can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)))
        return 0;
    for (int i = 0; i < CO_DEV_NPDO; i++) {
        co_dev_pdo_t *p = &d->rpdo[i];
        if ((p->cob & 0x80000000u) || (p->cob & 0x7FF) != rx->can_id)
            continue;
        int need = 0;
        for (int k = 0; k < p->n; k++)
            need += co_pdo_entry_from_u32(p->map[k]).bits;
        if (rx->len < (need + 7) / 8) {
            d->stats.bad_rpdo++;
            /* CiA 301: a PDO shorter than its mapping is not processed; tell the master. */
            return co_dev_emcy(d, CO_EMCY_PDO_LENGTH, d->err_reg | 0x10, NULL, &tx[0]);
        }
        p->rx = *rx;
        if (p->event_ms)
            p->next_us = now + (int64_t)p->event_ms * 1000;
        if (p->type <= 240)
            p->latched = true;
        else
            apply_rpdo(d, i);
        return 0;
    }
    return 0;
}

/* A communication error: EMCY with the communication bit of the error register, then the
 * application's reaction. */
static int comm_error(co_dev_t *d, uint16_t code, struct can_frame *tx, int max)
{
    int n = max > 0 ? co_dev_emcy(d, code, d->err_reg | 0x11, NULL, &tx[0]) : 0;
    if (d->hooks.on_comm_error)
        d->hooks.on_comm_error(d->user, d, code);
    return n;
}

/* 0x1016: a producer heard once and then silent for its time is lost (until heard again). */
static int check_consumers(co_dev_t *d, int64_t now, struct can_frame *tx, int max)
{
    int n = 0;
    for (int i = 0; i < CO_DEV_NCONSUMER; i++) {
        int64_t t = (int64_t)(d->consumer[i] & 0xFFFF) * 1000;
        if (!t || !(d->consumer[i] >> 16) || !d->consumer_last[i] || now - d->consumer_last[i] <= t)
            continue;
        d->consumer_last[i] = 0;
        d->stats.hb_losses++;
        n += comm_error(d, CO_EMCY_HB_ERROR, &tx[n], max - n);
        if (d->nmt == CO_NMT_OPERATIONAL)       /* 0x1029 sub 1 = 0: enter pre-operational */
            set_nmt(d, CO_NMT_PREOPERATIONAL);
    }
    return n;
}

/* 0x1400 sub 5: an RPDO received once must come again within its event time. */
static int check_rpdo_deadlines(co_dev_t *d, int64_t now, struct can_frame *tx, int max)
{
    int n = 0;
    for (int i = 0; i < CO_DEV_NPDO; i++) {
        co_dev_pdo_t *p = &d->rpdo[i];
        if (!p->next_us || !p->event_ms || (p->cob & 0x80000000u) || now <= p->next_us)
            continue;
        p->next_us = 0;                 /* monitoring resumes with the next RPDO */
        d->stats.rpdo_timeouts++;
        n += comm_error(d, CO_EMCY_RPDO_TIMEOUT, &tx[n], max - n);
    }
    return n;
}

int co_dev_poll(co_dev_t *d, int64_t now, struct can_frame *tx, int max)
{
    int n = 0;
    if (!d->booted || max <= 0)
        return 0;
    if (d->hb_ms && d->hb.period_us != (int64_t)d->hb_ms * 1000)
        co_hb_producer_init(&d->hb, d->node, (int64_t)d->hb_ms * 1000, now - (int64_t)d->hb_ms * 1000);
    if (!d->hb_ms)
        d->hb.period_us = 0;
    if (n < max && co_hb_producer_poll(&d->hb, now, d->nmt, &tx[n])) {
        d->stats.tx_frames++;
        n++;
    }
    n += check_consumers(d, now, &tx[n], max - n);
    if (d->nmt != CO_NMT_OPERATIONAL)
        return n;
    n += check_rpdo_deadlines(d, now, &tx[n], max - n);
    for (int i = 0; i < CO_DEV_NPDO && n < max; i++) {
        co_dev_pdo_t *p = &d->tpdo[i];
        if ((p->cob & 0x80000000u) || p->type < 254 || p->event_ms == 0)
            continue;
        if (p->next_us == 0)
            p->next_us = now;
        if (now >= p->next_us) {
            p->next_us += (int64_t)p->event_ms * 1000;
            if (p->next_us <= now)
                p->next_us = now + (int64_t)p->event_ms * 1000;
            n += pdo_frame(d, p, &tx[n]);
        }
    }
    return n;
}
