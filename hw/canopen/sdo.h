/* sdo: CANopen SDO client and server (expedited and segmented transfers, aborts, timeouts).
 * Pure state machines: a received frame goes in, the answer comes out in the caller's frame. */
#ifndef MARIE_HW_CO_SDO_H
#define MARIE_HW_CO_SDO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <linux/can.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Abort codes (CiA 301 table 22) used by marie. */
#define CO_SDO_ABORT_TOGGLE        0x05030000u
#define CO_SDO_ABORT_TIMEOUT       0x05040000u
#define CO_SDO_ABORT_CMD           0x05040001u
#define CO_SDO_ABORT_NO_MEM        0x05040005u
#define CO_SDO_ABORT_WRITE_ONLY    0x06010001u
#define CO_SDO_ABORT_READ_ONLY     0x06010002u
#define CO_SDO_ABORT_NO_OBJECT     0x06020000u
#define CO_SDO_ABORT_TYPE_LEN      0x06070010u
#define CO_SDO_ABORT_TOO_LONG      0x06070012u
#define CO_SDO_ABORT_TOO_SHORT     0x06070013u
#define CO_SDO_ABORT_NO_SUB        0x06090011u
#define CO_SDO_ABORT_PARAM_INCOMPAT 0x06040043u
#define CO_SDO_ABORT_RANGE         0x06090030u
#define CO_SDO_ABORT_GENERAL       0x08000000u
#define CO_SDO_ABORT_STATE         0x08000022u

const char *co_sdo_abort_str(uint32_t code);

/* Largest object a transfer carries (device names, mapping tables). */
#define CO_SDO_MAX 256

/* One transfer's progress, the same on both sides (private). */
typedef struct {
    int state;
    uint16_t index;
    uint8_t sub;
    uint8_t toggle;
    uint8_t buf[CO_SDO_MAX];
    size_t len, pos, expect;
} co_sdo_xfer_t;

/* ---- client ---- */
typedef struct co_sdo_client co_sdo_client_t;
/* A transfer ended: abort == 0 and data/len (the uploaded value; len 0 for a download) on
 * success, else the abort code (CO_SDO_ABORT_TIMEOUT when the server stayed silent). The
 * callback must not start another transfer on the same client. */
typedef void (*co_sdo_done_cb_t)(void *user, co_sdo_client_t *c, uint16_t index, uint8_t sub,
                                 uint32_t abort, const uint8_t *data, size_t len);

struct co_sdo_client {
    uint8_t node;
    int64_t timeout_us;
    co_sdo_done_cb_t cb;
    void *user;
    /* private */
    co_sdo_xfer_t x;
    int64_t deadline;
};

void co_sdo_client_init(co_sdo_client_t *c, uint8_t node, int64_t timeout_us, co_sdo_done_cb_t cb, void *user);
bool co_sdo_client_busy(const co_sdo_client_t *c);
/* Start a transfer; the request is written to *tx. 0, or -1 with errno EBUSY or EMSGSIZE. */
int co_sdo_client_upload(co_sdo_client_t *c, uint16_t index, uint8_t sub, int64_t now, struct can_frame *tx);
int co_sdo_client_download(co_sdo_client_t *c, uint16_t index, uint8_t sub, const void *data, size_t len,
                           int64_t now, struct can_frame *tx);
/* A frame from the bus: 1 with *tx to send, 0 consumed without answer (or not ours),
 * -1 with errno EBADMSG when a response from our server made no sense (the transfer is aborted
 * and the abort frame is in *tx, the return still -1 so the caller counts it; *tx_ready set). */
int co_sdo_client_feed(co_sdo_client_t *c, const struct can_frame *rx, int64_t now,
                       struct can_frame *tx, bool *tx_ready);
/* Timeouts: 1 with the abort frame in *tx when the transfer timed out (the callback ran). */
int co_sdo_client_poll(co_sdo_client_t *c, int64_t now, struct can_frame *tx);

/* A node's configuration as a table of steps, one SDO transfer each, run one after the other
 * (the drives' and the gyro's PDO mappings). A download writes `value`, or a value made from the
 * node id (kind CO_STEP_NODE: value + node; CO_STEP_INVALID_NODE: the same with bit 31, a COB-ID
 * switched off), or one the device computes (kinds CO_STEP_OWN and up). */
enum { CO_STEP_UP, CO_STEP_DN, CO_STEP_UP_OPT, CO_STEP_DN_OPT };    /* _OPT: may be missing */
enum { CO_STEP_CONST, CO_STEP_NODE, CO_STEP_INVALID_NODE, CO_STEP_OWN };
typedef struct {
    uint8_t op;
    uint16_t index;
    uint8_t sub;
    uint8_t size;
    uint8_t kind;
    uint32_t value;
} co_sdo_step_t;
typedef uint32_t (*co_sdo_step_value_cb_t)(void *user, const co_sdo_step_t *s);
/* Configuration step `pos` of the n in steps on c (whose node is the node id): 1 with its
 * request in *tx (own(user, step) gives the value of the kinds CO_STEP_OWN and up), or, once
 * every step is done, 0 with the node's NMT start in *tx: the configuration's last frame. */
int co_sdo_steps_next(co_sdo_client_t *c, const co_sdo_step_t *steps, int n, int pos, co_sdo_step_value_cb_t own,
                      void *user, int64_t now, struct can_frame *tx);
/* The CiA 301 name of a communication object ("consumer heartbeat time", "RPDO mapping
 * parameter", ...), NULL outside 0x1000-0x1FFF or when marie does not know it. */
const char *co_object_name(uint16_t index);

/* Whether an abort of step s only skips it: the step is optional and the node has no such
 * object or sub-index. */
bool co_sdo_step_skips(const co_sdo_step_t *s, uint32_t abort);

/* ---- server ---- */
/* Object access for the server. read: copy the value into buf (cap bytes), set *len; write:
 * take len bytes. Both return 0 or an abort code. An expedited download without size
 * indication (CiA 301 allows it: the client need not know the type) comes with
 * len == CO_SDO_LEN_UNSIZED and 4 bytes of data: the object's own size applies. */
#define CO_SDO_LEN_UNSIZED ((size_t)-1)
typedef struct {
    uint32_t (*read)(void *user, uint16_t index, uint8_t sub, uint8_t *buf, size_t cap, size_t *len);
    uint32_t (*write)(void *user, uint16_t index, uint8_t sub, const uint8_t *data, size_t len);
} co_sdo_server_ops_t;

typedef struct {
    uint8_t node;
    const co_sdo_server_ops_t *ops;
    void *user;
    /* private */
    co_sdo_xfer_t x;
} co_sdo_server_t;

void co_sdo_server_init(co_sdo_server_t *s, uint8_t node, const co_sdo_server_ops_t *ops, void *user);
/* A frame from the bus: 1 with *tx to send, 0 when it is not an SDO request to this node. */
int co_sdo_server_feed(co_sdo_server_t *s, const struct can_frame *rx, struct can_frame *tx);

#ifdef __cplusplus
}
#endif
#endif
