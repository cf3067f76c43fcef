/* sdo: SDO protocol (CiA 301 7.2.4.3): expedited and segmented upload and download. */
#include "hw/canopen/sdo.h"

#include <errno.h>
#include <string.h>

#include "core/err.h"
#include "hw/canopen/co.h"
#include "hw/canopen/nmt.h"

/* Command specifiers (top three bits of byte 0). */
#define CCS_DN_SEG  0   /* client: download segment */
#define CCS_DN_INIT 1
#define CCS_UP_INIT 2
#define CCS_UP_SEG  3
#define CS_ABORT    4
#define SCS_UP_SEG  0   /* server: upload segment */
#define SCS_DN_SEG  1
#define SCS_UP_INIT 2
#define SCS_DN_INIT 3

enum { ST_IDLE = 0, ST_DN_INIT, ST_DN_SEG, ST_UP_INIT, ST_UP_SEG };

const char *co_sdo_abort_str(uint32_t code)
{
    switch (code) {
    case 0: return "ok";
    case CO_SDO_ABORT_TOGGLE: return "toggle bit not alternated";
    case CO_SDO_ABORT_TIMEOUT: return "SDO protocol timed out";
    case CO_SDO_ABORT_CMD: return "command specifier not valid or unknown";
    case CO_SDO_ABORT_NO_MEM: return "out of memory";
    case CO_SDO_ABORT_WRITE_ONLY: return "attempt to read a write only object";
    case CO_SDO_ABORT_READ_ONLY: return "attempt to write a read only object";
    case CO_SDO_ABORT_NO_OBJECT: return "object does not exist in the object dictionary";
    case CO_SDO_ABORT_TYPE_LEN: return "data type does not match, length does not match";
    case CO_SDO_ABORT_TOO_LONG: return "data type does not match, length too high";
    case CO_SDO_ABORT_TOO_SHORT: return "data type does not match, length too low";
    case CO_SDO_ABORT_NO_SUB: return "sub-index does not exist";
    case CO_SDO_ABORT_PARAM_INCOMPAT: return "general parameter incompatibility";
    case CO_SDO_ABORT_RANGE: return "invalid value for parameter";
    case CO_SDO_ABORT_GENERAL: return "general error";
    case CO_SDO_ABORT_STATE: return "not possible in the present device state";
    }
    return "unknown abort code";
}

static void mux(uint8_t *d, uint16_t index, uint8_t sub)
{
    co_put_u16(d + 1, index);
    d[3] = sub;
}

static void abort_frame(struct can_frame *tx, canid_t id, uint16_t index, uint8_t sub, uint32_t code)
{
    uint8_t d[8] = { CS_ABORT << 5 };
    mux(d, index, sub);
    co_put_u32(d + 4, code);
    co_frame_set(tx, id, d, 8);
}

/* ---- client ---- */

void co_sdo_client_init(co_sdo_client_t *c, uint8_t node, int64_t timeout_us, co_sdo_done_cb_t cb, void *user)
{
    memset(c, 0, sizeof *c);
    c->node = node;
    c->timeout_us = timeout_us;
    c->cb = cb;
    c->user = user;
}

bool co_sdo_client_busy(const co_sdo_client_t *c) { return c->x.state != ST_IDLE; }

static canid_t cli_tx_id(const co_sdo_client_t *c) { return CO_COB_SDO_RX + c->node; }

static void cli_finish(co_sdo_client_t *c, uint32_t abort, const uint8_t *data, size_t len)
{
    c->x.state = ST_IDLE;
    if (c->cb)
        c->cb(c->user, c, c->x.index, c->x.sub, abort, data, len);
}

int co_sdo_client_upload(co_sdo_client_t *c, uint16_t index, uint8_t sub, int64_t now, struct can_frame *tx)
{
    if (c->x.state != ST_IDLE)
        return marie_fail(EBUSY);
    uint8_t d[8] = { CCS_UP_INIT << 5 };
    mux(d, index, sub);
    co_frame_set(tx, cli_tx_id(c), d, 8);
    c->x.index = index;
    c->x.sub = sub;
    c->x.len = c->x.pos = c->x.expect = 0;
    c->x.state = ST_UP_INIT;
    c->deadline = now + c->timeout_us;
    return 0;
}

int co_sdo_client_download(co_sdo_client_t *c, uint16_t index, uint8_t sub, const void *data, size_t len,
                           int64_t now, struct can_frame *tx)
{
    if (c->x.state != ST_IDLE)
        return marie_fail(EBUSY);
    if (len > CO_SDO_MAX || len == 0)
        return marie_fail(EMSGSIZE);
    uint8_t d[8] = { 0 };
    mux(d, index, sub);
    if (len <= 4) {
        /* expedited, size indicated: n = 4 - len unused bytes */
        d[0] = (uint8_t)(CCS_DN_INIT << 5 | (4 - len) << 2 | 0x03);
        memcpy(d + 4, data, len);
    } else {
        d[0] = CCS_DN_INIT << 5 | 0x01;
        co_put_u32(d + 4, (uint32_t)len);
    }
    co_frame_set(tx, cli_tx_id(c), d, 8);
    c->x.index = index;
    c->x.sub = sub;
    memcpy(c->x.buf, data, len);
    c->x.len = len;
    c->x.pos = 0;
    c->x.toggle = 0;
    c->x.state = ST_DN_INIT;
    c->deadline = now + c->timeout_us;
    return 0;
}

/* The sending side of a segmented transfer (a client's download, a server's upload): the next
 * up to 7 bytes of x's data into d, under command specifier cs and the current toggle. True when
 * it is the last segment. */
static bool xfer_put_segment(co_sdo_xfer_t *x, int cs, uint8_t d[8])
{
    size_t n = x->len - x->pos;
    if (n > 7)
        n = 7;
    bool last = x->pos + n == x->len;
    d[0] = (uint8_t)(cs << 5 | x->toggle << 4 | (7 - n) << 1 | (last ? 1 : 0));
    memcpy(d + 1, x->buf + x->pos, n);
    x->pos += n;
    return last;
}

/* The receiving side (a client's upload, a server's download): segment d appended to x's data
 * and the toggle flipped. 0, or the abort code for a wrong toggle, too many bytes, or a last
 * segment short of the size announced; *last tells whether d was the last segment. */
static uint32_t xfer_take_segment(co_sdo_xfer_t *x, const uint8_t d[8], bool *last)
{
    if (((d[0] >> 4) & 1) != x->toggle)
        return CO_SDO_ABORT_TOGGLE;
    size_t n = 7 - ((d[0] >> 1) & 7);
    if (x->len + n > CO_SDO_MAX || x->len + n > x->expect)
        return CO_SDO_ABORT_TOO_LONG;
    memcpy(x->buf + x->len, d + 1, n);
    x->len += n;
    x->toggle ^= 1;
    *last = d[0] & 1;
    if (*last && x->expect != CO_SDO_MAX && x->len != x->expect)
        return CO_SDO_ABORT_TOO_SHORT;
    return 0;
}

static void cli_next_dn_segment(co_sdo_client_t *c, struct can_frame *tx)
{
    uint8_t d[8] = { 0 };
    xfer_put_segment(&c->x, CCS_DN_SEG, d);
    co_frame_set(tx, cli_tx_id(c), d, 8);
}

static int cli_protocol_error(co_sdo_client_t *c, uint32_t code, struct can_frame *tx, bool *tx_ready)
{
    abort_frame(tx, cli_tx_id(c), c->x.index, c->x.sub, code);
    *tx_ready = true;
    cli_finish(c, code, NULL, 0);
    return marie_fail(EBADMSG);
}

int co_sdo_client_feed(co_sdo_client_t *c, const struct can_frame *rx, int64_t now,
                       struct can_frame *tx, bool *tx_ready)
{
    *tx_ready = false;
    if (rx->can_id != (canid_t)(CO_COB_SDO_TX + c->node) || c->x.state == ST_IDLE)
        return 0;
    if (rx->len != 8)
        return cli_protocol_error(c, CO_SDO_ABORT_CMD, tx, tx_ready);
    const uint8_t *d = rx->data;
    int scs = d[0] >> 5;
    if (scs == CS_ABORT) {
        /* An abort always ends the transfer as failed, even one carrying code 0. */
        uint32_t code = co_get_u32(d + 4);
        cli_finish(c, code ? code : CO_SDO_ABORT_GENERAL, NULL, 0);
        return 0;
    }
    bool mux_ok = co_get_u16(d + 1) == c->x.index && d[3] == c->x.sub;
    /* An initiate response for another object is a late answer to an earlier transfer
     * (e.g. one cut short by a node reset): ignore it and keep waiting for ours. */
    if ((scs == SCS_UP_INIT || scs == SCS_DN_INIT) && !mux_ok &&
        (c->x.state == ST_UP_INIT || c->x.state == ST_DN_INIT))
        return 0;
    c->deadline = now + c->timeout_us;
    switch (c->x.state) {
    case ST_DN_INIT:
        if (scs != SCS_DN_INIT || !mux_ok)
            return cli_protocol_error(c, CO_SDO_ABORT_CMD, tx, tx_ready);
        if (c->x.len <= 4) {
            cli_finish(c, 0, NULL, 0);
            return 0;
        }
        c->x.state = ST_DN_SEG;
        cli_next_dn_segment(c, tx);
        *tx_ready = true;
        return 1;
    case ST_DN_SEG:
        if (scs != SCS_DN_SEG)
            return cli_protocol_error(c, CO_SDO_ABORT_CMD, tx, tx_ready);
        if (((d[0] >> 4) & 1) != c->x.toggle)
            return cli_protocol_error(c, CO_SDO_ABORT_TOGGLE, tx, tx_ready);
        c->x.toggle ^= 1;
        if (c->x.pos == c->x.len) {
            cli_finish(c, 0, NULL, 0);
            return 0;
        }
        cli_next_dn_segment(c, tx);
        *tx_ready = true;
        return 1;
    case ST_UP_INIT: {
        if (scs != SCS_UP_INIT || !mux_ok)
            return cli_protocol_error(c, CO_SDO_ABORT_CMD, tx, tx_ready);
        bool e = d[0] & 0x02, s = d[0] & 0x01;
        if (e) {
            size_t n = s ? 4 - ((d[0] >> 2) & 3) : 4;
            memcpy(c->x.buf, d + 4, n);
            cli_finish(c, 0, c->x.buf, n);
            return 0;
        }
        c->x.expect = s ? co_get_u32(d + 4) : CO_SDO_MAX;
        if (c->x.expect > CO_SDO_MAX)
            return cli_protocol_error(c, CO_SDO_ABORT_NO_MEM, tx, tx_ready);
        c->x.len = 0;
        c->x.toggle = 0;
        c->x.state = ST_UP_SEG;
        uint8_t q[8] = { CCS_UP_SEG << 5 };
        co_frame_set(tx, cli_tx_id(c), q, 8);
        *tx_ready = true;
        return 1;
    }
    case ST_UP_SEG: {
        if (scs != SCS_UP_SEG)
            return cli_protocol_error(c, CO_SDO_ABORT_CMD, tx, tx_ready);
        bool last;
        uint32_t ab = xfer_take_segment(&c->x, d, &last);
        if (ab)
            return cli_protocol_error(c, ab, tx, tx_ready);
        if (last) {
            cli_finish(c, 0, c->x.buf, c->x.len);
            return 0;
        }
        uint8_t q[8] = { (uint8_t)(CCS_UP_SEG << 5 | c->x.toggle << 4) };
        co_frame_set(tx, cli_tx_id(c), q, 8);
        *tx_ready = true;
        return 1;
    }
    }
    return 0;
}

int co_sdo_client_poll(co_sdo_client_t *c, int64_t now, struct can_frame *tx)
{
    if (c->x.state == ST_IDLE || now < c->deadline)
        return 0;
    abort_frame(tx, cli_tx_id(c), c->x.index, c->x.sub, CO_SDO_ABORT_TIMEOUT);
    cli_finish(c, CO_SDO_ABORT_TIMEOUT, NULL, 0);
    return 1;
}

/* ---- server ---- */

void co_sdo_server_init(co_sdo_server_t *s, uint8_t node, const co_sdo_server_ops_t *ops, void *user)
{
    memset(s, 0, sizeof *s);
    s->node = node;
    s->ops = ops;
    s->user = user;
}

static int srv_abort(co_sdo_server_t *s, struct can_frame *tx, uint16_t index, uint8_t sub, uint32_t code)
{
    abort_frame(tx, CO_COB_SDO_TX + s->node, index, sub, code);
    s->x.state = ST_IDLE;
    return 1;
}

int co_sdo_server_feed(co_sdo_server_t *s, const struct can_frame *rx, struct can_frame *tx)
{
    if (rx->can_id != (canid_t)(CO_COB_SDO_RX + s->node))
        return 0;
    canid_t txid = CO_COB_SDO_TX + s->node;
    if (rx->len != 8)
        return srv_abort(s, tx, s->x.index, s->x.sub, CO_SDO_ABORT_CMD);
    const uint8_t *d = rx->data;
    int ccs = d[0] >> 5;
    uint16_t index = co_get_u16(d + 1);
    uint8_t sub = d[3];
    uint8_t r[8] = { 0 };

    switch (ccs) {
    case CS_ABORT:
        s->x.state = ST_IDLE;
        return 0;
    case CCS_DN_INIT: {
        s->x.index = index;
        s->x.sub = sub;
        bool e = d[0] & 0x02, sz = d[0] & 0x01;
        if (e) {
            size_t n = sz ? (size_t)(4 - ((d[0] >> 2) & 3)) : CO_SDO_LEN_UNSIZED;
            uint32_t ab = s->ops->write(s->user, index, sub, d + 4, n);
            if (ab)
                return srv_abort(s, tx, index, sub, ab);
            s->x.state = ST_IDLE;
        } else {
            s->x.expect = sz ? co_get_u32(d + 4) : CO_SDO_MAX;
            if (s->x.expect > CO_SDO_MAX)
                return srv_abort(s, tx, index, sub, CO_SDO_ABORT_NO_MEM);
            s->x.len = 0;
            s->x.toggle = 0;
            s->x.state = ST_DN_SEG;
        }
        r[0] = SCS_DN_INIT << 5;
        mux(r, index, sub);
        co_frame_set(tx, txid, r, 8);
        return 1;
    }
    case CCS_DN_SEG: {
        if (s->x.state != ST_DN_SEG)
            return srv_abort(s, tx, s->x.index, s->x.sub, CO_SDO_ABORT_CMD);
        uint8_t t = (d[0] >> 4) & 1;     /* the answer repeats the segment's toggle */
        bool last;
        uint32_t ab = xfer_take_segment(&s->x, d, &last);
        if (ab)
            return srv_abort(s, tx, s->x.index, s->x.sub, ab);
        if (last) {
            ab = s->ops->write(s->user, s->x.index, s->x.sub, s->x.buf, s->x.len);
            if (ab)
                return srv_abort(s, tx, s->x.index, s->x.sub, ab);
            s->x.state = ST_IDLE;
        }
        r[0] = (uint8_t)(SCS_DN_SEG << 5 | t << 4);
        co_frame_set(tx, txid, r, 8);
        return 1;
    }
    case CCS_UP_INIT: {
        s->x.index = index;
        s->x.sub = sub;
        size_t len = 0;
        uint32_t ab = s->ops->read(s->user, index, sub, s->x.buf, sizeof s->x.buf, &len);
        if (ab)
            return srv_abort(s, tx, index, sub, ab);
        mux(r, index, sub);
        if (len <= 4 && len > 0) {
            r[0] = (uint8_t)(SCS_UP_INIT << 5 | (4 - len) << 2 | 0x03);
            memcpy(r + 4, s->x.buf, len);
            s->x.state = ST_IDLE;
        } else {
            r[0] = SCS_UP_INIT << 5 | 0x01;
            co_put_u32(r + 4, (uint32_t)len);
            s->x.len = len;
            s->x.pos = 0;
            s->x.toggle = 0;
            s->x.state = ST_UP_SEG;
        }
        co_frame_set(tx, txid, r, 8);
        return 1;
    }
    case CCS_UP_SEG: {
        if (s->x.state != ST_UP_SEG)
            return srv_abort(s, tx, s->x.index, s->x.sub, CO_SDO_ABORT_CMD);
        if (((d[0] >> 4) & 1) != s->x.toggle)
            return srv_abort(s, tx, s->x.index, s->x.sub, CO_SDO_ABORT_TOGGLE);
        bool last = xfer_put_segment(&s->x, SCS_UP_SEG, r);
        s->x.toggle ^= 1;
        if (last)
            s->x.state = ST_IDLE;
        co_frame_set(tx, txid, r, 8);
        return 1;
    }
    default:
        return srv_abort(s, tx, index, sub, CO_SDO_ABORT_CMD);
    }
}

static void step_start(co_sdo_client_t *c, const co_sdo_step_t *s, co_sdo_step_value_cb_t own, void *user,
                       int64_t now, struct can_frame *tx)
{
    if (s->op == CO_STEP_UP || s->op == CO_STEP_UP_OPT) {
        co_sdo_client_upload(c, s->index, s->sub, now, tx);
        return;
    }
    uint32_t v = s->value;
    if (s->kind == CO_STEP_NODE)
        v += c->node;
    else if (s->kind == CO_STEP_INVALID_NODE)
        v = 0x80000000u | (v + c->node);
    else if (s->kind >= CO_STEP_OWN)
        v = own(user, s);
    uint8_t b[4];
    co_put_u32(b, v);
    co_sdo_client_download(c, s->index, s->sub, b, s->size, now, tx);
}

int co_sdo_steps_next(co_sdo_client_t *c, const co_sdo_step_t *steps, int n, int pos, co_sdo_step_value_cb_t own,
                      void *user, int64_t now, struct can_frame *tx)
{
    if (pos < n) {
        step_start(c, &steps[pos], own, user, now, tx);
        return 1;
    }
    co_nmt_encode(tx, CO_NMT_CMD_START, c->node);
    return 0;
}

bool co_sdo_step_skips(const co_sdo_step_t *s, uint32_t abort)
{
    return (abort == CO_SDO_ABORT_NO_OBJECT || abort == CO_SDO_ABORT_NO_SUB) &&
           (s->op == CO_STEP_UP_OPT || s->op == CO_STEP_DN_OPT);
}

const char *co_object_name(uint16_t index)
{
    static const struct { uint16_t index; const char *name; } names[] = {
        { 0x1000, "device type" }, { 0x1001, "error register" }, { 0x1008, "manufacturer device name" },
        { 0x1016, "consumer heartbeat time" }, { 0x1017, "producer heartbeat time" },
        { 0x1018, "identity object" }, { 0x1029, "error behavior" },
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (names[i].index == index)
            return names[i].name;
    if (index >= 0x1400 && index < 0x1C00) {
        static const char *pdo[] = { "RPDO communication parameter", "RPDO mapping parameter",
                                     "TPDO communication parameter", "TPDO mapping parameter" };
        return pdo[(index - 0x1400) >> 9];
    }
    return NULL;
}
