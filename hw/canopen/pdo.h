/* pdo: CANopen PDO mapping: pack and unpack object values into a PDO per a mapping table. */
#ifndef MARIE_HW_CO_PDO_H
#define MARIE_HW_CO_PDO_H

#include <stdint.h>
#include <linux/can.h>

#include "hw/canopen/sdo.h"

#ifdef __cplusplus
extern "C" {
#endif

#define CO_PDO_MAX_ENTRIES 8

typedef struct {
    uint16_t index;
    uint8_t sub;
    uint8_t bits;           /* 1..64 */
} co_pdo_entry_t;

typedef struct {
    canid_t cob_id;
    uint8_t n;
    co_pdo_entry_t e[CO_PDO_MAX_ENTRIES];
} co_pdo_map_t;

/* Mapping entries as stored in the object dictionary (0x1600/0x1A00 sub 1..8):
 * index << 16 | sub << 8 | bits. */
static inline uint32_t co_pdo_entry_u32(co_pdo_entry_t e)
{
    return (uint32_t)e.index << 16 | (uint32_t)e.sub << 8 | e.bits;
}
static inline co_pdo_entry_t co_pdo_entry_from_u32(uint32_t v)
{
    co_pdo_entry_t e = { (uint16_t)(v >> 16), (uint8_t)(v >> 8), (uint8_t)v };
    return e;
}

/* Total mapped length in bytes, or -1 with errno EINVAL (more than 64 bits, an entry of 0 bits or > 64). */
int co_pdo_map_bytes(const co_pdo_map_t *m);
/* Pack vals[i] (low `bits` bits, little-endian, in mapping order) into f. Returns the DLC, or
 * -1 with errno EINVAL. */
int co_pdo_encode(const co_pdo_map_t *m, const uint64_t *vals, struct can_frame *f);
/* Unpack f into vals[0..n-1]. 0, or -1 with errno EBADMSG if the frame is shorter than the
 * mapping (a longer frame is accepted, as CiA 301 allows) or EINVAL for a bad mapping. */
int co_pdo_decode(const co_pdo_map_t *m, const struct can_frame *f, uint64_t *vals);
/* Sign-extend a `bits`-wide value. */
int64_t co_pdo_signed(uint64_t v, uint8_t bits);

#define CO_PDO_MAX_STEPS (CO_PDO_MAX_ENTRIES + 6)
/* The configuration steps (sdo.h) that give a node's PDO the mapping m, in CiA 301's order:
 * switch the PDO off (COB-ID cob + node, bit 31 set), clear the mapping count, write the
 * entries, set the count, the transmission type trans, then `extra` unless NULL (an event timer,
 * an RPDO deadline), and switch the PDO on. comm is the PDO's communication parameter object
 * (0x1400 + n: RPDO n+1, 0x1800 + n: TPDO n+1); its mapping is at comm + 0x200. Writes at most
 * CO_PDO_MAX_STEPS steps into out and returns how many. */
int co_pdo_map_steps(co_sdo_step_t *out, uint16_t comm, canid_t cob, const co_pdo_map_t *m, uint8_t trans,
                     const co_sdo_step_t *extra);

#ifdef __cplusplus
}
#endif
#endif
