/* test_canopen: NMT, heartbeat, SYNC, SDO client/server, PDO mapping, EMCY and the device node. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "hw/canopen/co.h"
#include "hw/canopen/dev.h"
#include "hw/canopen/emcy.h"
#include "hw/canopen/nmt.h"
#include "hw/canopen/pdo.h"
#include "hw/canopen/sdo.h"
#include "tests/fails.h"

static void nmt_commands_and_states(void **state)
{
    struct can_frame f;
    co_nmt_cmd_t cmd;
    uint8_t node;
    assert_int_equal(co_nmt_encode(&f, CO_NMT_CMD_START, 5), 2);
    assert_int_equal(f.can_id, 0);
    assert_int_equal(f.data[0], 1);
    assert_int_equal(co_nmt_decode(&f, &cmd, &node), 0);
    assert_int_equal(cmd, CO_NMT_CMD_START);
    assert_int_equal(node, 5);
    f.data[0] = 0x33;
    assert_fails(co_nmt_decode(&f, &cmd, &node), EBADMSG);
    f.data[0] = 1; f.len = 3;
    assert_fails(co_nmt_decode(&f, &cmd, &node), EBADMSG);
    bool reset;
    assert_int_equal(co_nmt_next(CO_NMT_PREOPERATIONAL, CO_NMT_CMD_START, &reset), CO_NMT_OPERATIONAL);
    assert_false(reset);
    assert_int_equal(co_nmt_next(CO_NMT_OPERATIONAL, CO_NMT_CMD_STOP, &reset), CO_NMT_STOPPED);
    assert_int_equal(co_nmt_next(CO_NMT_STOPPED, CO_NMT_CMD_ENTER_PREOP, &reset), CO_NMT_PREOPERATIONAL);
    assert_int_equal(co_nmt_next(CO_NMT_OPERATIONAL, CO_NMT_CMD_RESET_COMM, &reset), CO_NMT_PREOPERATIONAL);
    assert_true(reset);
    assert_string_equal(co_nmt_state_name(CO_NMT_OPERATIONAL), "operational");
}

struct hb_log { int n; uint8_t node[16]; co_hb_event_t ev[16]; };
static void hb_cb(void *user, uint8_t node, co_hb_event_t ev, co_nmt_state_t s)
{
    struct hb_log *l = user;
    if (l->n < 16) { l->node[l->n] = node; l->ev[l->n] = ev; l->n++; }
}

static void heartbeat_producer_and_consumer(void **state)
{
    co_hb_producer_t p;
    struct can_frame f;
    co_hb_producer_init(&p, 3, 100000, 0);
    assert_int_equal(co_hb_producer_poll(&p, 50000, CO_NMT_OPERATIONAL, &f), 0);
    assert_int_equal(co_hb_producer_poll(&p, 100000, CO_NMT_OPERATIONAL, &f), 1);
    assert_int_equal(f.can_id, 0x703);
    assert_int_equal(f.data[0], 5);
    /* late by many periods: one message, not a burst */
    assert_int_equal(co_hb_producer_poll(&p, 1000000, CO_NMT_OPERATIONAL, &f), 1);
    assert_int_equal(co_hb_producer_poll(&p, 1000001, CO_NMT_OPERATIONAL, &f), 0);

    struct hb_log log = { 0 };
    co_hb_consumer_t c;
    co_hb_consumer_init(&c, hb_cb, &log);
    assert_int_equal(co_hb_consumer_add(&c, 3, 300000, 0), 0);
    assert_fails(co_hb_consumer_add(&c, 0, 300000, 0), EINVAL);
    co_hb_encode(&f, 3, CO_NMT_BOOTUP);
    assert_int_equal(co_hb_consumer_feed(&c, &f, 10000), 1);
    assert_int_equal(log.ev[0], CO_HB_EV_BOOTUP);
    co_hb_encode(&f, 3, CO_NMT_OPERATIONAL);
    co_hb_consumer_feed(&c, &f, 110000);
    assert_int_equal(log.ev[1], CO_HB_EV_STATE);
    assert_int_equal(co_hb_consumer_state(&c, 3), CO_NMT_OPERATIONAL);
    co_hb_consumer_check(&c, 400000);
    assert_int_equal(log.n, 2);
    co_hb_consumer_check(&c, 420000);
    assert_int_equal(log.ev[2], CO_HB_EV_TIMEOUT);
    co_hb_consumer_check(&c, 900000);
    assert_int_equal(log.n, 3);                     /* a timeout is told once */
    co_hb_consumer_feed(&c, &f, 950000);
    assert_int_equal(log.ev[3], CO_HB_EV_RECOVERED);
    /* other nodes and malformed heartbeats */
    co_hb_encode(&f, 4, CO_NMT_OPERATIONAL);
    assert_int_equal(co_hb_consumer_feed(&c, &f, 960000), 0);
    co_hb_encode(&f, 3, CO_NMT_OPERATIONAL);
    f.len = 2;
    assert_fails(co_hb_consumer_feed(&c, &f, 960000), EBADMSG);
    f.len = 1; f.data[0] = 0x33;
    assert_fails(co_hb_consumer_feed(&c, &f, 960000), EBADMSG);
}

static void sync_frames(void **state)
{
    struct can_frame f;
    uint8_t cnt;
    assert_int_equal(co_sync_encode(&f, 0), 0);
    assert_int_equal(f.can_id, 0x80);
    assert_int_equal(co_sync_decode(&f, &cnt), 0);
    assert_int_equal(cnt, 0);
    co_sync_encode(&f, 7);
    assert_int_equal(co_sync_decode(&f, &cnt), 0);
    assert_int_equal(cnt, 7);
    f.len = 2;
    assert_fails(co_sync_decode(&f, &cnt), EBADMSG);
}

/* ---- SDO ---- */

static uint32_t u32obj = 0x00020192;
static uint8_t u8obj = 3;
static char bigobj[CO_SDO_MAX];
static size_t biglen = 19;
static const char *rostr = "marie segmented name!";

static uint32_t srv_read(void *user, uint16_t idx, uint8_t sub, uint8_t *buf, size_t cap, size_t *len)
{
    if (idx == 0x1000) { co_put_u32(buf, u32obj); *len = 4; return 0; }
    if (idx == 0x6060) { buf[0] = u8obj; *len = 1; return 0; }
    if (idx == 0x1008) { *len = strlen(rostr); memcpy(buf, rostr, *len); return 0; }
    if (idx == 0x2000) { memcpy(buf, bigobj, biglen); *len = biglen; return 0; }
    if (idx == 0x2001) return CO_SDO_ABORT_WRITE_ONLY;
    return CO_SDO_ABORT_NO_OBJECT;
}

static uint32_t srv_write(void *user, uint16_t idx, uint8_t sub, const uint8_t *d, size_t len)
{
    if (idx == 0x6060) { if (len != 1) return CO_SDO_ABORT_TYPE_LEN; u8obj = d[0]; return 0; }
    if (idx == 0x2000) { memcpy(bigobj, d, len); biglen = len; return 0; }
    if (idx == 0x1000 || idx == 0x1008) return CO_SDO_ABORT_READ_ONLY;
    return CO_SDO_ABORT_NO_OBJECT;
}

static const co_sdo_server_ops_t srv_ops = { srv_read, srv_write };

struct done { int n; uint32_t abort; uint8_t data[CO_SDO_MAX]; size_t len; };
static void sdo_cb(void *user, co_sdo_client_t *c, uint16_t idx, uint8_t sub, uint32_t abort,
                   const uint8_t *data, size_t len)
{
    struct done *d = user;
    d->n++;
    d->abort = abort;
    d->len = len;
    if (len) memcpy(d->data, data, len);
}

/* Run a transfer between client and server until it ends; returns frames exchanged. */
static int exchange(co_sdo_client_t *c, co_sdo_server_t *s, struct can_frame req)
{
    int frames = 0;
    for (int i = 0; i < 200; i++) {
        struct can_frame resp, next;
        frames++;
        if (co_sdo_server_feed(s, &req, &resp) != 1)
            return frames;
        frames++;
        bool ready;
        co_sdo_client_feed(c, &resp, 0, &next, &ready);
        if (!ready)
            return frames;
        req = next;
    }
    return frames;
}

static void sdo_expedited_upload_and_download(void **state)
{
    co_sdo_client_t c;
    co_sdo_server_t s;
    struct done d = { 0 };
    struct can_frame req;
    co_sdo_client_init(&c, 5, 100000, sdo_cb, &d);
    co_sdo_server_init(&s, 5, &srv_ops, NULL);
    assert_int_equal(co_sdo_client_upload(&c, 0x1000, 0, 0, &req), 0);
    assert_int_equal(req.can_id, 0x605);
    assert_int_equal(req.data[0], 0x40);
    assert_fails(co_sdo_client_upload(&c, 0x1000, 0, 0, &req), EBUSY);
    exchange(&c, &s, req);
    assert_int_equal(d.n, 1);
    assert_int_equal(d.abort, 0);
    assert_int_equal(d.len, 4);
    assert_int_equal(co_get_u32(d.data), 0x00020192);
    uint8_t v = 9;
    assert_int_equal(co_sdo_client_download(&c, 0x6060, 0, &v, 1, 0, &req), 0);
    assert_int_equal(req.data[0], 0x2F);            /* expedited, size indicated, 1 byte */
    exchange(&c, &s, req);
    assert_int_equal(d.n, 2);
    assert_int_equal(d.abort, 0);
    assert_int_equal(u8obj, 9);
    assert_false(co_sdo_client_busy(&c));
}

static uint32_t own_value(void *user, const co_sdo_step_t *s) { return 250; }

/* A PDO's mapping as configuration steps, in CiA 301's order, and the table run to its end. */
static void pdo_remap_steps_and_their_frames(void **state)
{
    const co_pdo_map_t m = { 0, 2, { { 0x6040, 0, 16 }, { 0x60FF, 0, 32 } } };
    const co_sdo_step_t deadline = { CO_STEP_DN_OPT, 0x1400, 5, 2, CO_STEP_OWN, 0 };
    co_sdo_step_t st[CO_PDO_MAX_STEPS];
    int n = co_pdo_map_steps(st, 0x1400, CO_COB_RPDO1, &m, 1, &deadline);
    const struct { uint16_t index; uint8_t sub, kind; uint32_t value; } want[] = {
        { 0x1400, 1, CO_STEP_INVALID_NODE, CO_COB_RPDO1 }, { 0x1600, 0, CO_STEP_CONST, 0 },
        { 0x1600, 1, CO_STEP_CONST, 0x60400010 },          { 0x1600, 2, CO_STEP_CONST, 0x60FF0020 },
        { 0x1600, 0, CO_STEP_CONST, 2 },                   { 0x1400, 2, CO_STEP_CONST, 1 },
        { 0x1400, 5, CO_STEP_OWN, 0 },                     { 0x1400, 1, CO_STEP_NODE, CO_COB_RPDO1 },
    };
    assert_int_equal(n, 8);
    for (int i = 0; i < n; i++) {
        assert_int_equal(st[i].index, want[i].index);
        assert_int_equal(st[i].sub, want[i].sub);
        assert_int_equal(st[i].kind, want[i].kind);
        assert_int_equal(st[i].value, want[i].value);
    }
    assert_true(co_sdo_step_skips(&st[6], CO_SDO_ABORT_NO_SUB));
    assert_false(co_sdo_step_skips(&st[5], CO_SDO_ABORT_NO_SUB));
    assert_false(co_sdo_step_skips(&st[6], CO_SDO_ABORT_TYPE_LEN));

    /* The requests for node 5: the COB-ID switched off, the device's own value, switched on;
     * after the last step the node's NMT start. */
    co_sdo_client_t c;
    struct done d = { 0 };
    struct can_frame f;
    const int at[] = { 0, 6, 7 };
    const uint32_t value[] = { 0x80000205, 250, 0x205 };
    for (int k = 0; k < 3; k++) {
        co_sdo_client_init(&c, 5, 100000, sdo_cb, &d);
        assert_int_equal(co_sdo_steps_next(&c, st, n, at[k], own_value, NULL, 0, &f), 1);
        assert_int_equal(f.can_id, 0x605);
        assert_int_equal(f.data[1] | f.data[2] << 8, st[at[k]].index);
        assert_int_equal(f.data[3], st[at[k]].sub);
        assert_int_equal(co_get_u32(&f.data[4]) & (st[at[k]].size == 2 ? 0xFFFF : 0xFFFFFFFF), value[k]);
    }
    co_sdo_client_init(&c, 5, 100000, sdo_cb, &d);
    assert_int_equal(co_sdo_steps_next(&c, st, n, n, own_value, NULL, 0, &f), 0);
    assert_int_equal(f.can_id, 0);
    assert_int_equal(f.data[0], CO_NMT_CMD_START);
    assert_int_equal(f.data[1], 5);
}

static void sdo_segmented_upload_and_download(void **state)
{
    co_sdo_client_t c;
    co_sdo_server_t s;
    struct done d = { 0 };
    struct can_frame req;
    co_sdo_client_init(&c, 5, 100000, sdo_cb, &d);
    co_sdo_server_init(&s, 5, &srv_ops, NULL);
    co_sdo_client_upload(&c, 0x1008, 0, 0, &req);
    int frames = exchange(&c, &s, req);
    assert_int_equal(d.abort, 0);
    assert_int_equal(d.len, strlen(rostr));
    assert_memory_equal(d.data, rostr, d.len);
    assert_int_equal(frames, 2 + 2 * 3);            /* initiate + 3 segments of 7 bytes */
    /* download of 100 bytes: 15 segments, toggle alternating */
    uint8_t data[100];
    for (int i = 0; i < 100; i++) data[i] = (uint8_t)(i * 7);
    co_sdo_client_download(&c, 0x2000, 0, data, sizeof data, 0, &req);
    exchange(&c, &s, req);
    assert_int_equal(d.n, 2);
    assert_int_equal(d.abort, 0);
    assert_int_equal(biglen, 100);
    assert_memory_equal(bigobj, data, 100);
    /* and read it back segmented */
    co_sdo_client_upload(&c, 0x2000, 0, 0, &req);
    exchange(&c, &s, req);
    assert_int_equal(d.len, 100);
    assert_memory_equal(d.data, data, 100);
}

static void sdo_aborts_and_timeouts(void **state)
{
    co_sdo_client_t c;
    co_sdo_server_t s;
    struct done d = { 0 };
    struct can_frame req, resp;
    bool ready;
    co_sdo_client_init(&c, 5, 100000, sdo_cb, &d);
    co_sdo_server_init(&s, 5, &srv_ops, NULL);
    co_sdo_client_upload(&c, 0x3000, 0, 0, &req);
    exchange(&c, &s, req);
    assert_int_equal(d.abort, CO_SDO_ABORT_NO_OBJECT);
    co_sdo_client_upload(&c, 0x2001, 0, 0, &req);
    exchange(&c, &s, req);
    assert_int_equal(d.abort, CO_SDO_ABORT_WRITE_ONLY);
    uint32_t x = 1;
    co_sdo_client_download(&c, 0x1000, 0, &x, 4, 0, &req);
    exchange(&c, &s, req);
    assert_int_equal(d.abort, CO_SDO_ABORT_READ_ONLY);
    assert_string_equal(co_sdo_abort_str(CO_SDO_ABORT_READ_ONLY), "attempt to write a read only object");
    /* timeout: the client aborts with 0x05040000 */
    co_sdo_client_upload(&c, 0x1000, 0, 1000, &req);
    assert_int_equal(co_sdo_client_poll(&c, 50000, &resp), 0);
    assert_int_equal(co_sdo_client_poll(&c, 101000, &resp), 1);
    assert_int_equal(resp.data[0], 0x80);
    assert_int_equal(co_get_u32(resp.data + 4), CO_SDO_ABORT_TIMEOUT);
    assert_int_equal(d.abort, CO_SDO_ABORT_TIMEOUT);
    assert_false(co_sdo_client_busy(&c));
    /* server: a segment with the wrong toggle is aborted */
    co_sdo_client_upload(&c, 0x1008, 0, 0, &req);
    co_sdo_server_feed(&s, &req, &resp);
    struct can_frame seg = { .can_id = 0x605, .len = 8, .data = { 0x70 } };  /* toggle 1 first */
    assert_int_equal(co_sdo_server_feed(&s, &seg, &resp), 1);
    assert_int_equal(co_get_u32(resp.data + 4), CO_SDO_ABORT_TOGGLE);
    /* client: a response with the wrong toggle aborts and is reported as bad */
    co_sdo_client_init(&c, 5, 100000, sdo_cb, &d);
    co_sdo_client_upload(&c, 0x1008, 0, 0, &req);
    co_sdo_server_init(&s, 5, &srv_ops, NULL);
    co_sdo_server_feed(&s, &req, &resp);
    co_sdo_client_feed(&c, &resp, 0, &req, &ready);
    co_sdo_server_feed(&s, &req, &resp);
    resp.data[0] ^= 0x10;
    assert_fails(co_sdo_client_feed(&c, &resp, 0, &req, &ready), EBADMSG);
    assert_true(ready);
    assert_int_equal(req.data[0], 0x80);
    assert_int_equal(d.abort, CO_SDO_ABORT_TOGGLE);
    /* short frame from the server */
    co_sdo_client_upload(&c, 0x1000, 0, 0, &req);
    resp.can_id = 0x585; resp.len = 4;
    assert_fails(co_sdo_client_feed(&c, &resp, 0, &req, &ready), EBADMSG);
    /* an abort frame with code 0 still fails the transfer */
    co_sdo_client_upload(&c, 0x1008, 0, 0, &req);
    struct can_frame ab0 = { .can_id = 0x585, .len = 8, .data = { 0x80, 0x08, 0x10, 0 } };
    assert_int_equal(co_sdo_client_feed(&c, &ab0, 0, &req, &ready), 0);
    assert_int_equal(d.abort, CO_SDO_ABORT_GENERAL);
    assert_false(co_sdo_client_busy(&c));
    /* frames for other nodes are ignored */
    resp.can_id = 0x586;
    assert_int_equal(co_sdo_server_feed(&s, &resp, &req), 0);
    /* unknown command specifier */
    struct can_frame junk = { .can_id = 0x605, .len = 8, .data = { 0xE0 } };
    assert_int_equal(co_sdo_server_feed(&s, &junk, &resp), 1);
    assert_int_equal(co_get_u32(resp.data + 4), CO_SDO_ABORT_CMD);
}

/* ---- PDO ---- */

static void pdo_pack_unpack(void **state)
{
    co_pdo_map_t m = { 0x181, 3, { { 0x6041, 0, 16 }, { 0x6064, 0, 32 }, { 0x2000, 1, 4 } } };
    assert_int_equal(co_pdo_map_bytes(&m), 7);
    uint64_t in[3] = { 0x1237, (uint32_t)-123456, 0xA }, out[3];
    struct can_frame f;
    assert_int_equal(co_pdo_encode(&m, in, &f), 7);
    assert_int_equal(f.can_id, 0x181);
    assert_int_equal(f.data[0], 0x37);
    assert_int_equal(f.data[1], 0x12);
    assert_int_equal(co_pdo_decode(&m, &f, out), 0);
    assert_int_equal(out[0], 0x1237);
    assert_int_equal(co_pdo_signed(out[1], 32), -123456);
    assert_int_equal(out[2], 0xA);
    f.len = 5;
    assert_fails(co_pdo_decode(&m, &f, out), EBADMSG);
    co_pdo_map_t big = { 0x181, 3, { { 1, 0, 32 }, { 2, 0, 32 }, { 3, 0, 8 } } };
    assert_fails(co_pdo_encode(&big, in, &f), EINVAL);
    co_pdo_entry_t e = co_pdo_entry_from_u32(0x60FF0020);
    assert_int_equal(e.index, 0x60FF);
    assert_int_equal(e.bits, 32);
    assert_int_equal(co_pdo_entry_u32(e), 0x60FF0020);
    assert_int_equal(co_pdo_signed(0xFF, 8), -1);
}

static void emcy_codec(void **state)
{
    co_emcy_t e = { .node = 9, .code = 0x2310, .reg = 0x03, .vendor = { 1, 2, 3, 4, 5 } }, o;
    struct can_frame f;
    co_emcy_encode(&f, &e);
    assert_int_equal(f.can_id, 0x89);
    assert_int_equal(co_emcy_decode(&f, &o), 0);
    assert_int_equal(o.code, 0x2310);
    assert_int_equal(o.node, 9);
    assert_int_equal(o.vendor[4], 5);
    assert_string_equal(co_emcy_str(0x2310), "continuous over-current");
    assert_string_equal(co_emcy_str(0x4999), "temperature");
    f.len = 4;
    assert_fails(co_emcy_decode(&f, &o), EBADMSG);
    f.len = 8; f.can_id = 0x080;
    assert_fails(co_emcy_decode(&f, &o), EBADMSG);     /* that is SYNC */
}

/* ---- device node ---- */

static uint16_t dv_cw, dv_sw = 0x1234;
static int32_t dv_target, dv_pos = 777;
static int rpdos, syncs;
static void dv_rpdo(void *u, co_dev_t *d, int pdo) { rpdos++; }
static void dv_sync(void *u, co_dev_t *d) { syncs++; }

static void device_node_nmt_sdo_pdo(void **state)
{
    co_od_entry_t od[] = {
        { 0x6040, 0, 2, CO_OD_RW, &dv_cw }, { 0x6041, 0, 2, CO_OD_RO, &dv_sw },
        { 0x6064, 0, 4, CO_OD_RO, &dv_pos }, { 0x60FF, 0, 4, CO_OD_RW, &dv_target },
    };
    co_dev_hooks_t hooks = { .on_rpdo = dv_rpdo, .on_sync = dv_sync };
    co_dev_t d;
    struct can_frame tx[8], f;
    co_dev_init(&d, 4, od, 4, &hooks, NULL);
    assert_int_equal(co_dev_boot(&d, 0, &tx[0]), 1);
    assert_int_equal(tx[0].can_id, 0x704);
    assert_int_equal(tx[0].data[0], 0);
    /* heartbeat via SDO write of 0x1017, then produced by poll */
    co_sdo_client_t c;
    struct done dn = { 0 };
    co_sdo_client_init(&c, 4, 100000, sdo_cb, &dn);
    uint16_t hb = 50;
    co_sdo_client_download(&c, 0x1017, 0, &hb, 2, 0, &f);
    assert_int_equal(co_dev_feed(&d, &f, 0, tx, 8), 1);
    bool ready;
    co_sdo_client_feed(&c, &tx[0], 0, &f, &ready);
    assert_int_equal(dn.abort, 0);
    assert_int_equal(co_dev_poll(&d, 1000, tx, 8), 1);
    assert_int_equal(tx[0].data[0], CO_NMT_PREOPERATIONAL);
    assert_int_equal(co_dev_poll(&d, 20000, tx, 8), 0);
    assert_int_equal(co_dev_poll(&d, 51000, tx, 8), 1);
    /* remap TPDO1 through SDO: must be invalid first */
    uint32_t v = 0x60640020;
    co_sdo_client_download(&c, 0x1A00, 1, &v, 4, 0, &f);
    co_dev_feed(&d, &f, 0, tx, 8);
    co_sdo_client_feed(&c, &tx[0], 0, &f, &ready);
    assert_int_equal(dn.abort, 0);                   /* PDOs start invalid in co_dev */
    uint8_t n1 = 1;
    co_sdo_client_download(&c, 0x1A00, 0, &n1, 1, 0, &f);
    co_dev_feed(&d, &f, 0, tx, 8);
    co_sdo_client_feed(&c, &tx[0], 0, &f, &ready);
    assert_int_equal(dn.abort, 0);
    uint8_t sync1 = 1;
    co_sdo_client_download(&c, 0x1800, 2, &sync1, 1, 0, &f);
    co_dev_feed(&d, &f, 0, tx, 8);
    co_sdo_client_feed(&c, &tx[0], 0, &f, &ready);
    assert_int_equal(dn.abort, 0);
    uint32_t cob = 0x184;
    co_sdo_client_download(&c, 0x1800, 1, &cob, 4, 0, &f);
    co_dev_feed(&d, &f, 0, tx, 8);
    co_sdo_client_feed(&c, &tx[0], 0, &f, &ready);
    assert_int_equal(dn.abort, 0);
    /* mapping entries of a valid PDO cannot change */
    co_sdo_client_download(&c, 0x1A00, 1, &v, 4, 0, &f);
    co_dev_feed(&d, &f, 0, tx, 8);
    co_sdo_client_feed(&c, &tx[0], 0, &f, &ready);
    assert_int_equal(dn.abort, CO_SDO_ABORT_STATE);
    /* mapping a missing object is refused */
    uint32_t rcob = 0x80000204, bad = 0x70000020;
    co_sdo_client_download(&c, 0x1400, 1, &rcob, 4, 0, &f);
    co_dev_feed(&d, &f, 0, tx, 8);
    co_sdo_client_feed(&c, &tx[0], 0, &f, &ready);
    co_sdo_client_download(&c, 0x1600, 1, &bad, 4, 0, &f);
    co_dev_feed(&d, &f, 0, tx, 8);
    co_sdo_client_feed(&c, &tx[0], 0, &f, &ready);
    co_sdo_client_download(&c, 0x1600, 0, &n1, 1, 0, &f);
    co_dev_feed(&d, &f, 0, tx, 8);
    co_sdo_client_feed(&c, &tx[0], 0, &f, &ready);
    assert_int_equal(dn.abort, CO_SDO_ABORT_NO_OBJECT);
    /* RPDO1 = controlword + target, synchronous */
    uint32_t rmap[] = { 0x60400010, 0x60FF0020 };
    co_dev_set_pdo(&d, false, 1, 0x204, 1, 0, rmap, 2);
    /* PDOs only in operational */
    struct can_frame r = { .can_id = 0x204, .len = 6, .data = { 0x0F, 0, 0x10, 0x27, 0, 0 } };
    assert_int_equal(co_dev_feed(&d, &r, 0, tx, 8), 0);
    co_nmt_encode(&f, CO_NMT_CMD_START, 0);
    co_dev_feed(&d, &f, 0, tx, 8);
    assert_int_equal(d.nmt, CO_NMT_OPERATIONAL);
    co_dev_feed(&d, &r, 0, tx, 8);
    assert_int_equal(dv_cw, 0);                      /* latched until SYNC */
    co_sync_encode(&f, 0);
    int n = co_dev_feed(&d, &f, 0, tx, 8);
    assert_int_equal(dv_cw, 0x0F);
    assert_int_equal(dv_target, 10000);
    assert_int_equal(rpdos, 1);
    assert_int_equal(syncs, 1);
    assert_int_equal(n, 1);                          /* TPDO1, synchronous */
    assert_int_equal(tx[0].can_id, 0x184);
    assert_int_equal(tx[0].len, 4);
    assert_int_equal((int32_t)co_get_u32(tx[0].data), 777);
    /* a short RPDO is not processed and answered by EMCY 0x8210 */
    r.len = 3;
    assert_int_equal(co_dev_feed(&d, &r, 0, tx, 8), 1);
    assert_int_equal(tx[0].can_id, 0x84);
    assert_int_equal(co_get_u16(tx[0].data), CO_EMCY_PDO_LENGTH);
    assert_int_equal(d.stats.bad_rpdo, 1);
    /* NMT to another node is ignored; reset communication reboots */
    co_nmt_encode(&f, CO_NMT_CMD_STOP, 5);
    co_dev_feed(&d, &f, 0, tx, 8);
    assert_int_equal(d.nmt, CO_NMT_OPERATIONAL);
    co_nmt_encode(&f, CO_NMT_CMD_RESET_COMM, 4);
    assert_int_equal(co_dev_feed(&d, &f, 0, tx, 8), 1);
    assert_int_equal(tx[0].can_id, 0x704);
    assert_int_equal(d.nmt, CO_NMT_PREOPERATIONAL);
    /* stopped: no SDO answers */
    co_nmt_encode(&f, CO_NMT_CMD_STOP, 4);
    co_dev_feed(&d, &f, 0, tx, 8);
    co_sdo_client_init(&c, 4, 100000, sdo_cb, &dn);
    co_sdo_client_upload(&c, 0x6041, 0, 0, &f);
    assert_int_equal(co_dev_feed(&d, &f, 0, tx, 8), 0);
}

static void device_event_timer_tpdo(void **state)
{
    static uint32_t val = 42;
    co_od_entry_t od[] = { { 0x2100, 0, 4, CO_OD_RO, &val } };
    co_dev_t d;
    struct can_frame tx[4], f;
    co_dev_init(&d, 0x20, od, 1, NULL, NULL);
    uint32_t map[] = { 0x21000020 };
    co_dev_set_pdo(&d, true, 1, 0x1A0, 254, 10, map, 1);
    co_dev_boot(&d, 0, tx);
    assert_int_equal(co_dev_poll(&d, 0, tx, 4), 0);   /* pre-operational: none */
    co_nmt_encode(&f, CO_NMT_CMD_START, 0x20);
    co_dev_feed(&d, &f, 0, tx, 4);
    int total = 0;
    for (int64_t t = 0; t <= 100000; t += 1000)
        total += co_dev_poll(&d, t, tx, 4);
    assert_int_equal(total, 11);                      /* every 10 ms over 100 ms */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(nmt_commands_and_states),
        cmocka_unit_test(heartbeat_producer_and_consumer),
        cmocka_unit_test(sync_frames),
        cmocka_unit_test(sdo_expedited_upload_and_download),
        cmocka_unit_test(sdo_segmented_upload_and_download),
        cmocka_unit_test(sdo_aborts_and_timeouts),
        cmocka_unit_test(pdo_pack_unpack),
        cmocka_unit_test(pdo_remap_steps_and_their_frames),
        cmocka_unit_test(emcy_codec),
        cmocka_unit_test(device_node_nmt_sdo_pdo),
        cmocka_unit_test(device_event_timer_tpdo),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
