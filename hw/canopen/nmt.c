/* nmt: NMT, heartbeat and SYNC encoding and the node-side NMT state machine. */
#include "hw/canopen/nmt.h"

#include <errno.h>
#include <string.h>

#include "core/err.h"
#include "hw/canopen/co.h"

const char *co_nmt_state_name(co_nmt_state_t s)
{
    switch (s) {
    case CO_NMT_BOOTUP: return "boot-up";
    case CO_NMT_STOPPED: return "stopped";
    case CO_NMT_OPERATIONAL: return "operational";
    case CO_NMT_PREOPERATIONAL: return "pre-operational";
    case CO_NMT_UNKNOWN: return "unknown";
    }
    return "invalid";
}

const char *co_nmt_cmd_name(co_nmt_cmd_t c)
{
    switch (c) {
    case CO_NMT_CMD_START: return "start";
    case CO_NMT_CMD_STOP: return "stop";
    case CO_NMT_CMD_ENTER_PREOP: return "enter-pre-operational";
    case CO_NMT_CMD_RESET_NODE: return "reset-node";
    case CO_NMT_CMD_RESET_COMM: return "reset-communication";
    }
    return "invalid";
}

static bool cmd_valid(uint8_t c)
{
    return c == CO_NMT_CMD_START || c == CO_NMT_CMD_STOP || c == CO_NMT_CMD_ENTER_PREOP ||
           c == CO_NMT_CMD_RESET_NODE || c == CO_NMT_CMD_RESET_COMM;
}

int co_nmt_encode(struct can_frame *f, co_nmt_cmd_t cmd, uint8_t node)
{
    uint8_t d[2] = { (uint8_t)cmd, node };
    co_frame_set(f, CO_COB_NMT, d, 2);
    return 2;
}

int co_nmt_decode(const struct can_frame *f, co_nmt_cmd_t *cmd, uint8_t *node)
{
    if (f->can_id != CO_COB_NMT || f->len != 2 || !cmd_valid(f->data[0]) || f->data[1] > CO_NODE_MAX)
        return marie_fail(EBADMSG);
    *cmd = (co_nmt_cmd_t)f->data[0];
    *node = f->data[1];
    return 0;
}

co_nmt_state_t co_nmt_next(co_nmt_state_t cur, co_nmt_cmd_t cmd, bool *reset)
{
    *reset = false;
    switch (cmd) {
    case CO_NMT_CMD_START: return CO_NMT_OPERATIONAL;
    case CO_NMT_CMD_STOP: return CO_NMT_STOPPED;
    case CO_NMT_CMD_ENTER_PREOP: return CO_NMT_PREOPERATIONAL;
    case CO_NMT_CMD_RESET_NODE:
    case CO_NMT_CMD_RESET_COMM:
        *reset = true;
        return CO_NMT_PREOPERATIONAL;   /* after initialisation and the boot-up message */
    }
    return cur;
}

int co_hb_encode(struct can_frame *f, uint8_t node, co_nmt_state_t s)
{
    uint8_t d = (uint8_t)s;
    co_frame_set(f, CO_COB_HEARTBEAT + node, &d, 1);
    return 1;
}

int co_hb_decode(const struct can_frame *f, uint8_t *node, co_nmt_state_t *s)
{
    uint8_t n;
    if (co_classify(f->can_id, &n, NULL) != CO_FC_HEARTBEAT || f->len != 1)
        return marie_fail(EBADMSG);
    uint8_t v = f->data[0] & 0x7F;      /* bit 7 is the toggle bit of node guarding */
    if (v != CO_NMT_BOOTUP && v != CO_NMT_STOPPED && v != CO_NMT_OPERATIONAL && v != CO_NMT_PREOPERATIONAL)
        return marie_fail(EBADMSG);
    *node = n;
    *s = (co_nmt_state_t)v;
    return 0;
}

void co_hb_producer_init(co_hb_producer_t *p, uint8_t node, int64_t period_us, int64_t now)
{
    p->node = node;
    p->period_us = period_us;
    p->next_us = now + period_us;
}

int co_hb_producer_poll(co_hb_producer_t *p, int64_t now, co_nmt_state_t s, struct can_frame *f)
{
    if (p->period_us <= 0 || now < p->next_us)
        return 0;
    p->next_us += p->period_us;
    if (p->next_us <= now)          /* we were late: do not burst, restart the period */
        p->next_us = now + p->period_us;
    co_hb_encode(f, p->node, s);
    return 1;
}

void co_hb_consumer_init(co_hb_consumer_t *c, co_hb_cb_t cb, void *user)
{
    memset(c, 0, sizeof *c);
    c->cb = cb;
    c->user = user;
}

int co_hb_consumer_add(co_hb_consumer_t *c, uint8_t node, int64_t timeout_us, int64_t now)
{
    if (c->count >= CO_HB_MAX_NODES)
        return marie_fail(ENOSPC);
    if (node == 0 || node > CO_NODE_MAX)
        return marie_fail(EINVAL);
    int i = c->count++;
    memset(&c->n[i], 0, sizeof c->n[i]);
    c->n[i].node = node;
    c->n[i].timeout_us = timeout_us;
    c->n[i].last_us = now;
    c->n[i].state = CO_NMT_UNKNOWN;
    return 0;
}

int co_hb_consumer_set_timeout(co_hb_consumer_t *c, uint8_t node, int64_t timeout_us, int64_t now)
{
    for (int i = 0; i < c->count; i++)
        if (c->n[i].node == node) {
            c->n[i].timeout_us = timeout_us;
            c->n[i].last_us = now;
            c->n[i].timed_out = false;
            return 0;
        }
    return marie_fail(ENOENT);
}

static void fire(co_hb_consumer_t *c, uint8_t node, co_hb_event_t ev, co_nmt_state_t s)
{
    if (c->cb)
        c->cb(c->user, node, ev, s);
}

int co_hb_consumer_feed(co_hb_consumer_t *c, const struct can_frame *f, int64_t now)
{
    uint8_t node;
    if (co_classify(f->can_id, &node, NULL) != CO_FC_HEARTBEAT)
        return 0;
    int i;
    for (i = 0; i < c->count && c->n[i].node != node; i++)
        ;
    if (i == c->count)
        return 0;
    co_nmt_state_t s;
    if (co_hb_decode(f, &node, &s) < 0)
        return marie_fail(EBADMSG);
    c->n[i].last_us = now;
    c->n[i].heard = true;
    if (c->n[i].timed_out) {
        c->n[i].timed_out = false;
        fire(c, node, CO_HB_EV_RECOVERED, s);
    }
    if (s == CO_NMT_BOOTUP) {
        c->n[i].bootups++;
        c->n[i].state = CO_NMT_PREOPERATIONAL;
        fire(c, node, CO_HB_EV_BOOTUP, s);
    } else if (s != c->n[i].state) {
        c->n[i].state = s;
        fire(c, node, CO_HB_EV_STATE, s);
    }
    return 1;
}

void co_hb_consumer_check(co_hb_consumer_t *c, int64_t now)
{
    for (int i = 0; i < c->count; i++) {
        if (c->n[i].timeout_us <= 0 || c->n[i].timed_out)
            continue;
        if (now - c->n[i].last_us > c->n[i].timeout_us) {
            c->n[i].timed_out = true;
            c->n[i].timeouts++;
            c->n[i].state = CO_NMT_UNKNOWN;
            fire(c, c->n[i].node, CO_HB_EV_TIMEOUT, CO_NMT_UNKNOWN);
        }
    }
}

co_nmt_state_t co_hb_consumer_state(const co_hb_consumer_t *c, uint8_t node)
{
    for (int i = 0; i < c->count; i++)
        if (c->n[i].node == node)
            return c->n[i].state;
    return CO_NMT_UNKNOWN;
}

int co_sync_encode(struct can_frame *f, uint8_t counter)
{
    co_frame_set(f, CO_COB_SYNC, &counter, counter ? 1 : 0);
    return f->len;
}

int co_sync_decode(const struct can_frame *f, uint8_t *counter)
{
    if (f->can_id != CO_COB_SYNC || f->len > 1)
        return marie_fail(EBADMSG);
    *counter = f->len ? f->data[0] : 0;
    if (f->len && (*counter == 0 || *counter > 240))
        return marie_fail(EBADMSG);
    return 0;
}
