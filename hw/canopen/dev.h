/* dev: the device side of a CANopen node, for emulators: object dictionary, NMT slave,
 * heartbeat producer and consumer, identity, SDO server, PDO communication and mapping
 * objects with RPDO deadline monitoring, EMCY producer.
 * Pure like the rest of hw/canopen: frames in, frames out into the caller's array. */
#ifndef MARIE_HW_CO_DEV_H
#define MARIE_HW_CO_DEV_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <linux/can.h>

#include "hw/canopen/dev_params.h"
#include "hw/canopen/nmt.h"
#include "hw/canopen/pdo.h"
#include "hw/canopen/sdo.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { CO_OD_RO = 1, CO_OD_WO = 2, CO_OD_RW = 3 };

/* An application object: `size` bytes (1, 2, 4) of an unsigned or signed integer at ptr, or
 * size 0 for a read-only visible string (ptr is a const char *). Communication objects
 * (0x1001, 0x1016, 0x1017, 0x1018, 0x1400-0x1A03) are provided by the node itself; a reset
 * (node or communication) restores them to their power-on values, set by co_dev_set_pdo()
 * and co_dev_set_heartbeat(). */
typedef struct {
    uint16_t index;
    uint8_t sub;
    uint8_t size;
    uint8_t access;
    void *ptr;
} co_od_entry_t;

typedef struct co_dev co_dev_t;

typedef struct {
    /* NMT state changed; reset: the node ran a reset (the application restores defaults). */
    void (*on_nmt)(void *user, co_dev_t *d, co_nmt_state_t s, bool reset);
    /* RPDO `pdo` (1..4) was written into the dictionary (at SYNC for synchronous RPDOs). */
    void (*on_rpdo)(void *user, co_dev_t *d, int pdo);
    /* SYNC received, before synchronous TPDOs sample the dictionary. */
    void (*on_sync)(void *user, co_dev_t *d);
    /* An SDO wrote an application object; return 0 or an abort code to refuse it (the
     * old value is then restored). */
    uint32_t (*on_write)(void *user, co_dev_t *d, uint16_t index, uint8_t sub);
    /* A communication error: CO_EMCY_HB_ERROR (a consumed heartbeat stopped) or
     * CO_EMCY_RPDO_TIMEOUT (an RPDO missed its event-timer deadline). The node has sent the
     * EMCY; the application reacts (CiA 402: per 0x6007). For a heartbeat error the node then
     * leaves operational for pre-operational (0x1029 default), which on_nmt reports. */
    void (*on_comm_error)(void *user, co_dev_t *d, uint16_t code);
} co_dev_hooks_t;

#define CO_DEV_NPDO 4

#define CO_DEV_NCONSUMER 4   /* 0x1016 entries */

typedef struct {
    uint32_t cob;           /* bit 31 set: PDO not valid */
    uint8_t type;           /* transmission type: 1..240 every n-th SYNC, 254/255 event-driven */
    uint16_t event_ms;      /* TPDO: event timer (types 254/255); RPDO: deadline (0: none) */
    uint8_t n;
    uint32_t map[CO_PDO_MAX_ENTRIES];
    /* private */
    int64_t next_us;        /* TPDO: next event; RPDO: deadline (0: not monitored yet) */
    uint8_t sync_count;
    bool latched;
    struct can_frame rx;
} co_dev_pdo_t;

typedef struct {
    uint64_t rx_frames, tx_frames, sdo_requests, sdo_aborts, rpdo, tpdo, bad_rpdo, syncs, nmt;
    uint64_t bad_frames;        /* NMT or SYNC with a wrong length or content */
    uint64_t hb_losses;         /* consumed heartbeats that stopped (0x1016) */
    uint64_t rpdo_timeouts;     /* RPDO deadlines missed (0x1400 sub 5) */
} co_dev_stats_t;

/* The communication objects a reset restores. */
typedef struct {
    uint16_t hb_ms;                         /* 0x1017 */
    uint32_t consumer[CO_DEV_NCONSUMER];    /* 0x1016: node << 16 | time in ms */
    co_dev_pdo_t tpdo[CO_DEV_NPDO], rpdo[CO_DEV_NPDO];
} co_dev_comm_t;

struct co_dev {
    uint8_t node;
    co_nmt_state_t nmt;
    const co_od_entry_t *od;
    size_t nod;
    co_dev_hooks_t hooks;
    void *user;
    uint16_t hb_ms;
    uint8_t err_reg;
    co_dev_pdo_t tpdo[CO_DEV_NPDO], rpdo[CO_DEV_NPDO];
    uint32_t consumer[CO_DEV_NCONSUMER];
    uint32_t identity[4];   /* 0x1018 sub 1..4: vendor, product code, revision, serial */
    /* Optional objects a device may lack (CiA 301, dev.params.yaml): no 0x1016 (abort "no
     * object"), no RPDO event timer 0x1400+n sub 5 (abort "no sub-index"); set before the
     * first frame. */
    co_dev_opts_t opts;
    co_dev_stats_t stats;
    /* private */
    co_dev_comm_t power_on;
    int64_t consumer_last[CO_DEV_NCONSUMER];   /* 0: not heard yet, not monitored */
    co_sdo_server_t sdo;
    co_hb_producer_t hb;
    bool booted;
};

/* The node starts in initialisation; co_dev_boot() sends the boot-up message. The
 * dictionary must outlive the node. PDOs start invalid: set them with co_dev_set_pdo(). */
void co_dev_init(co_dev_t *d, uint8_t node, const co_od_entry_t *od, size_t nod,
                 const co_dev_hooks_t *hooks, void *user);
/* Default communication and mapping of PDO `pdo` (1..4); tx selects TPDO vs RPDO. */
void co_dev_set_pdo(co_dev_t *d, bool tx, int pdo, uint32_t cob, uint8_t type, uint16_t event_ms,
                    const uint32_t *map, uint8_t n);
/* Power-on producer heartbeat time (0x1017) and consumer entries (0x1016: node << 16 | ms). */
void co_dev_set_heartbeat(co_dev_t *d, uint16_t producer_ms, const uint32_t *consumer, int n);
/* The identity object 0x1018 (read-only). */
void co_dev_set_identity(co_dev_t *d, uint32_t vendor, uint32_t product, uint32_t revision, uint32_t serial);
/* Boot (power-on or after a reset command): pre-operational, boot-up message in *tx. */
int co_dev_boot(co_dev_t *d, int64_t now, struct can_frame *tx);
/* A frame from the bus. Returns how many answer frames were written to tx[0..max-1]. */
int co_dev_feed(co_dev_t *d, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max);
/* Time-driven output due at now: heartbeat, event-timer TPDOs, and the EMCY of a consumed
 * heartbeat or an RPDO deadline that expired (then on_comm_error runs). */
int co_dev_poll(co_dev_t *d, int64_t now, struct can_frame *tx, int max);
/* An emergency message (sent in any state but stopped). Returns 1 with *tx, 0 if not sent. */
int co_dev_emcy(co_dev_t *d, uint16_t code, uint8_t reg, const uint8_t vendor[5], struct can_frame *tx);


#ifdef __cplusplus
}
#endif
#endif
