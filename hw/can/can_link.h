/* can_link: a CAN bus inside a marie_loop: reads every waiting frame into a callback, sends
 * frames with failures counted, reconnects to the emulated bus when it goes away, and
 * recovers from bus-off (restart request after a hold-off). */
#ifndef MARIE_HW_CAN_LINK_H
#define MARIE_HW_CAN_LINK_H

#include <stdbool.h>
#include <stddef.h>

#include "core/loop.h"
#include "hw/can/can.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct can_link can_link_t;

typedef void (*can_link_frame_cb_t)(void *user, const struct can_frame *f);
/* kind: "bus_off", "bus_restart", "bus_active", "disconnected", "connected", "tx_error". */
typedef void (*can_link_event_cb_t)(void *user, const char *kind, const char *text);

/* Open `url` (can:IF or emu:PATH) with receive filters; NULL with errno if the first open
 * fails (later losses are retried every second). */
can_link_t *can_link_open(marie_loop_t *loop, const char *url, const struct can_filter *filters, size_t n,
                          can_link_frame_cb_t on_frame, can_link_event_cb_t on_event, void *user);
void can_link_close(can_link_t *l);         /* NULL is a no-op */
/* Send frames in order; returns how many went out (the rest are counted as tx errors). */
int can_link_send(can_link_t *l, const struct can_frame *f, int n);
bool can_link_up(const can_link_t *l);      /* connected and not bus-off */

#ifdef __cplusplus
}
#endif
#endif
