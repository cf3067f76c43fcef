/* fuzz_canopen: arbitrary frames into every CANopen frame handler (SDO client and server,
 * device node, heartbeat consumer, EMCY, PDO, the wheel-drive and gyro masters, a virtual
 * drive and a virtual gyro).
 * Input: records of [id_hi, id_lo, len, 8 data bytes]. */
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "hw/canopen/dev.h"
#include "hw/canopen/emcy.h"
#include "hw/canopen/nmt.h"
#include "hw/canopen/pdo.h"
#include "hw/canopen/sdo.h"
#include "hw/drives/drives_ctl.h"
#include "hw/drives/vdrive.h"
#include "hw/gyro/gyro_ctl.h"
#include "hw/gyro/vgyro.h"

static uint32_t rd(void *u, uint16_t i, uint8_t s, uint8_t *b, size_t cap, size_t *len)
{
    if (i == 0x2000) { memset(b, 'x', 40); *len = 40; return 0; }
    if (i == 0x2001) { b[0] = 1; *len = 1; return 0; }
    return CO_SDO_ABORT_NO_OBJECT;
}
static uint32_t wr(void *u, uint16_t i, uint8_t s, const uint8_t *d, size_t len) { return i == 0x2000 ? 0 : CO_SDO_ABORT_READ_ONLY; }
static const co_sdo_server_ops_t ops = { rd, wr };
static void done(void *u, co_sdo_client_t *c, uint16_t i, uint8_t s, uint32_t a, const uint8_t *d, size_t l) {}
static void hbcb(void *u, uint8_t n, co_hb_event_t e, co_nmt_state_t s) {}
static void drcb(void *u, int axis, drives_ev_t e, uint32_t code) {}
static void gscb(void *u, double rate, uint8_t status) {}
static void gecb(void *u, gyro_ev_t e, uint32_t code) {}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    co_sdo_server_t srv;
    co_sdo_client_t cli;
    co_hb_consumer_t hb;
    co_sdo_server_init(&srv, 5, &ops, NULL);
    co_sdo_client_init(&cli, 5, 1000, done, NULL);
    co_hb_consumer_init(&hb, hbcb, NULL);
    co_hb_consumer_add(&hb, 5, 1000, 0);
    drives_cfg_t cfg;
    drives_cfg_default(&cfg);
    drives_ctl_t *ctl = drives_ctl_create(&cfg, drcb, NULL);
    vdrive_cfg_t vc;
    vdrive_cfg_default(&vc, 1);
    vc.rpdo_timeout = 0.005;
    vdrive_t *vd = vdrive_create(&vc);
    gyro_cfg_t gc;
    gyro_cfg_default(&gc);
    gyro_ctl_t *gy = gyro_ctl_create(&gc, gscb, gecb, NULL);
    vgyro_cfg_t vgc;
    vgyro_cfg_default(&vgc, 0x20);
    vgyro_t *vg = vgyro_create(&vgc);
    struct can_frame tx[16], t1;
    int64_t now = 0;
    vdrive_boot(vd, now, tx, 16);
    drives_ctl_start(ctl, now, tx, 16);
    gyro_ctl_start(gy, now, tx, 16);
    vgyro_boot(vg, now, tx, 16);
    co_nmt_encode(&t1, CO_NMT_CMD_START, 0);
    vdrive_feed(vd, &t1, now, tx, 16);
    for (size_t off = 0; off + 11 <= size; off += 11) {
        struct can_frame f;
        memset(&f, 0, sizeof f);
        f.can_id = (canid_t)((data[off] << 8 | data[off + 1]) & 0x7FF);
        if (data[off] & 0x80) f.can_id |= CAN_RTR_FLAG;
        f.len = data[off + 2] % 9;
        memcpy(f.data, data + off + 3, 8);
        now += 700;
        bool ready;
        co_sdo_server_feed(&srv, &f, &t1);
        if (!co_sdo_client_busy(&cli)) {
            if (data[off + 2] & 0x10)
                co_sdo_client_download(&cli, 0x2000, 0, data, size < 200 ? size : 200, now, &t1);
            else
                co_sdo_client_upload(&cli, 0x2000, 0, now, &t1);
        }
        co_sdo_client_feed(&cli, &f, now, &t1, &ready);
        co_sdo_client_poll(&cli, now, &t1);
        co_hb_consumer_feed(&hb, &f, now);
        co_hb_consumer_check(&hb, now);
        co_emcy_t e;
        co_emcy_decode(&f, &e);
        uint64_t v[8];
        co_pdo_map_t m = { 0x181, 2, { { 0x6041, 0, 16 }, { 0x6064, 0, 32 } } };
        co_pdo_decode(&m, &f, v);
        uint8_t c;
        co_sync_decode(&f, &c);
        co_nmt_cmd_t cmd;
        uint8_t node;
        co_nmt_decode(&f, &cmd, &node);
        drives_ctl_set_wheels(ctl, data[off + 3] - 128.0, data[off + 4] - 128.0, now);
        drives_ctl_set_estop(ctl, data[off + 5] & 1);
        drives_ctl_feed(ctl, &f, now, tx, 16);
        drives_ctl_cycle(ctl, now, tx, 16);
        vdrive_feed(vd, &f, now, tx, 16);
        vdrive_step(vd, 0.0007);
        vdrive_poll(vd, now, tx, 16);
        gyro_ctl_feed(gy, &f, now, tx, 16);
        gyro_ctl_poll(gy, now, tx, 16);
        vgyro_feed(vg, &f, now, tx, 16);
        vgyro_poll(vg, now, tx, 16);
    }
    gyro_ctl_destroy(gy);
    vgyro_destroy(vg);
    drives_ctl_destroy(ctl);
    vdrive_destroy(vd);
    return 0;
}
