/* nmt: CANopen network management: NMT commands and states, heartbeat producer and
 * consumer, SYNC. Pure: frames in, events out, frames written into the caller's buffer. */
#ifndef MARIE_HW_CO_NMT_H
#define MARIE_HW_CO_NMT_H

#include <stdbool.h>
#include <stdint.h>
#include <linux/can.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    CO_NMT_BOOTUP = 0x00,           /* the boot-up message; the node is then pre-operational */
    CO_NMT_STOPPED = 0x04,
    CO_NMT_OPERATIONAL = 0x05,
    CO_NMT_PREOPERATIONAL = 0x7F,
    CO_NMT_UNKNOWN = 0xFF,          /* not heard from (yet) */
} co_nmt_state_t;

typedef enum {
    CO_NMT_CMD_START = 0x01,
    CO_NMT_CMD_STOP = 0x02,
    CO_NMT_CMD_ENTER_PREOP = 0x80,
    CO_NMT_CMD_RESET_NODE = 0x81,
    CO_NMT_CMD_RESET_COMM = 0x82,
} co_nmt_cmd_t;

const char *co_nmt_state_name(co_nmt_state_t s);
const char *co_nmt_cmd_name(co_nmt_cmd_t c);

/* NMT command to `node` (0: all nodes). Returns the frame length (2). */
int co_nmt_encode(struct can_frame *f, co_nmt_cmd_t cmd, uint8_t node);
/* 0, or -1 with errno EBADMSG (not an NMT frame, wrong DLC, unknown command, node > 127). */
int co_nmt_decode(const struct can_frame *f, co_nmt_cmd_t *cmd, uint8_t *node);
/* A node's NMT state machine: the state after `cmd`; *reset tells that the node must run its
 * reset (application or communication) and then send its boot-up message. */
co_nmt_state_t co_nmt_next(co_nmt_state_t cur, co_nmt_cmd_t cmd, bool *reset);

/* Heartbeat / boot-up message 0x700+node with the state byte. */
int co_hb_encode(struct can_frame *f, uint8_t node, co_nmt_state_t s);
int co_hb_decode(const struct can_frame *f, uint8_t *node, co_nmt_state_t *s);

/* Heartbeat producer: one message every period (0 disables). */
typedef struct {
    uint8_t node;
    int64_t period_us;
    int64_t next_us;
} co_hb_producer_t;
void co_hb_producer_init(co_hb_producer_t *p, uint8_t node, int64_t period_us, int64_t now);
/* 1 with *f filled when a heartbeat is due at `now`, else 0. */
int co_hb_producer_poll(co_hb_producer_t *p, int64_t now, co_nmt_state_t s, struct can_frame *f);

/* Heartbeat consumer for a few nodes. */
typedef enum {
    CO_HB_EV_BOOTUP,        /* the node (re)booted: it must be configured again */
    CO_HB_EV_STATE,         /* its NMT state changed */
    CO_HB_EV_TIMEOUT,       /* no heartbeat within its timeout */
    CO_HB_EV_RECOVERED,     /* heard again after a timeout */
} co_hb_event_t;

#define CO_HB_MAX_NODES 8
typedef void (*co_hb_cb_t)(void *user, uint8_t node, co_hb_event_t ev, co_nmt_state_t s);

typedef struct {
    struct {
        uint8_t node;
        int64_t timeout_us;
        int64_t last_us;
        co_nmt_state_t state;
        bool heard, timed_out;
        uint32_t timeouts, bootups;
    } n[CO_HB_MAX_NODES];
    int count;
    co_hb_cb_t cb;
    void *user;
} co_hb_consumer_t;

void co_hb_consumer_init(co_hb_consumer_t *c, co_hb_cb_t cb, void *user);
/* Watch `node`; a node never heard from times out `timeout_us` after `now`. 0, or -1 with errno ENOSPC. */
int co_hb_consumer_add(co_hb_consumer_t *c, uint8_t node, int64_t timeout_us, int64_t now);
/* Supervise `node` with timeout_us from now on (0: only listen, for boot-ups and states): a
 * node sends heartbeats only once its 0x1017 is written, and a reset communication clears it.
 * 0, or -1 with errno ENOENT for a node not added. */
int co_hb_consumer_set_timeout(co_hb_consumer_t *c, uint8_t node, int64_t timeout_us, int64_t now);
/* 1 if f was a heartbeat of a watched node, 0 if not for us, -1 with errno EBADMSG if malformed. */
int co_hb_consumer_feed(co_hb_consumer_t *c, const struct can_frame *f, int64_t now);
/* Fire timeouts due at `now`. */
void co_hb_consumer_check(co_hb_consumer_t *c, int64_t now);
/* The last state heard from `node` (CO_NMT_UNKNOWN if never, or timed out). */
co_nmt_state_t co_hb_consumer_state(const co_hb_consumer_t *c, uint8_t node);

/* SYNC: counter 0 sends the classic empty SYNC, 1..240 the counter byte. */
int co_sync_encode(struct can_frame *f, uint8_t counter);
/* 0 with *counter (0 when absent), or -1 with errno EBADMSG. */
int co_sync_decode(const struct can_frame *f, uint8_t *counter);

#ifdef __cplusplus
}
#endif
#endif
