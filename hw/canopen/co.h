/* co: CANopen (CiA 301) basics shared by the protocol modules: COB-IDs and byte order. */
#ifndef MARIE_HW_CO_H
#define MARIE_HW_CO_H

#include <stdint.h>
#include <string.h>
#include <linux/can.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Predefined connection set: COB-ID = function code + node id (1..127). */
#define CO_COB_NMT        0x000
#define CO_COB_SYNC       0x080
#define CO_COB_EMCY       0x080   /* + node */
#define CO_COB_TPDO1      0x180
#define CO_COB_RPDO1      0x200
#define CO_COB_TPDO2      0x280
#define CO_COB_RPDO2      0x300
#define CO_COB_TPDO3      0x380
#define CO_COB_RPDO3      0x400
#define CO_COB_TPDO4      0x480
#define CO_COB_RPDO4      0x500
#define CO_COB_SDO_TX     0x580   /* server -> client, + node */
#define CO_COB_SDO_RX     0x600   /* client -> server, + node */
#define CO_COB_HEARTBEAT  0x700   /* + node */

#define CO_NODE_MAX 127

typedef enum {
    CO_FC_NMT, CO_FC_SYNC, CO_FC_EMCY, CO_FC_TPDO, CO_FC_RPDO, CO_FC_SDO_TX, CO_FC_SDO_RX,
    CO_FC_HEARTBEAT, CO_FC_OTHER,
} co_fc_t;

/* Classify a standard frame id; *node gets the node id (0 for broadcast objects),
 * *pdo the PDO number 1..4 for PDOs. */
static inline co_fc_t co_classify(canid_t id, uint8_t *node, int *pdo)
{
    *node = (uint8_t)(id & 0x7F);
    if (pdo)
        *pdo = 0;
    if (id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG))
        return CO_FC_OTHER;
    uint32_t fc = id & 0x780;
    if (id == CO_COB_NMT)
        return CO_FC_NMT;
    if (id == CO_COB_SYNC)
        return CO_FC_SYNC;
    if (*node == 0)
        return CO_FC_OTHER;
    switch (fc) {
    case 0x080: return CO_FC_EMCY;
    case 0x180: case 0x280: case 0x380: case 0x480:
        if (pdo) *pdo = (int)((fc - 0x180) / 0x100) + 1;
        return CO_FC_TPDO;
    case 0x200: case 0x300: case 0x400: case 0x500:
        if (pdo) *pdo = (int)((fc - 0x200) / 0x100) + 1;
        return CO_FC_RPDO;
    case 0x580: return CO_FC_SDO_TX;
    case 0x600: return CO_FC_SDO_RX;
    case 0x700: return CO_FC_HEARTBEAT;
    }
    return CO_FC_OTHER;
}

static inline void co_frame_set(struct can_frame *f, canid_t id, const void *data, uint8_t len)
{
    memset(f, 0, sizeof *f);
    f->can_id = id;
    f->len = len;
    if (len)
        memcpy(f->data, data, len);
}

static inline uint16_t co_get_u16(const uint8_t *p) { return (uint16_t)(p[0] | p[1] << 8); }
static inline uint32_t co_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static inline void co_put_u16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static inline void co_put_u32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}

#ifdef __cplusplus
}
#endif
#endif
