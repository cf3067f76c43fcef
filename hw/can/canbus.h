/* canbus: the emulated CAN bus: an AF_UNIX SOCK_SEQPACKET server relaying every frame a
 * client writes to all other clients, as a real bus (and SocketCAN's loopback) would, each
 * through the receive filters it told (can.h, CAN_EMU_FILTER_MAGIC) as the kernel would. Its
 * listening socket and its clients are fds of the caller's marie_loop. */
#ifndef MARIE_HW_CANBUS_H
#define MARIE_HW_CANBUS_H

#include <stdint.h>
#include <linux/can.h>
#include <linux/can/error.h>

#include "core/loop.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct can_emubus can_emubus_t;

typedef struct {
    uint64_t clients;           /* connections accepted so far */
    uint64_t frames;            /* frames received from clients */
    uint64_t delivered;         /* frame copies handed to clients */
    uint64_t overflow;          /* copies dropped: a client's queue (socket and 512 held frames) was full */
    uint64_t bad;               /* packets that are not a CAN / CAN FD frame or a filter packet */
    uint64_t filtered;          /* copies not sent: the client's filters do not take them */
} can_emubus_stats_t;
const can_emubus_stats_t *can_emubus_stats(const can_emubus_t *b);

/* Listen on `path` (an existing socket file is replaced; the path appears only once the bus
 * listens, so a client that sees it can connect); the bus accepts, relays and drops clients
 * from `loop` as it runs. NULL with errno. */
can_emubus_t *can_emubus_create(marie_loop_t *loop, const char *path);
/* NULL is a no-op; takes its fds off the loop and unlinks the path. */
void can_emubus_destroy(can_emubus_t *b);
/* Accept, relay and drop clients now, without waiting for the loop (a simulator that must see
 * the frames sent during its step before it judges deadlines). Returns frames relayed. */
int can_emubus_process(can_emubus_t *b);
/* Put a frame on the bus from the bus itself (e.g. an error frame): every client gets it. */
int can_emubus_inject(can_emubus_t *b, const struct can_frame *f);
int can_emubus_nclients(const can_emubus_t *b);
/* Clients that have frames they have not read yet (held here or in their socket). */
int can_emubus_unread(const can_emubus_t *b);

#ifdef __cplusplus
}
#endif
#endif
