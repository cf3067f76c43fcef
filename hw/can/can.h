/* can: CAN frame I/O behind one fd: a real SocketCAN raw socket or a client of the emulated bus. */
#ifndef MARIE_HW_CAN_H
#define MARIE_HW_CAN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <linux/can.h>
#include <linux/can/error.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- pure helpers (no I/O) ---- */

/* Same semantics as the kernel's CAN_RAW filter: a frame passes when any filter matches,
 * (id & mask) == (can_id & mask), inverted by CAN_INV_FILTER; no filters: everything passes.
 * Error frames never pass data filters (they are governed by the error mask). */
bool can_filter_match(const struct can_filter *filters, size_t n, canid_t id);

/* Bus health as told by error frames. */
typedef enum {
    CAN_BUS_ACTIVE = 0,
    CAN_BUS_WARNING,      /* error counters above 96 */
    CAN_BUS_PASSIVE,      /* above 127 */
    CAN_BUS_BUS_OFF,      /* above 255: the controller stopped transmitting */
} can_bus_health_t;

typedef struct {
    uint32_t classes;       /* CAN_ERR_* class bits from can_id */
    bool bus_off, restarted, passive, warning, tx_timeout, ack, bus_error, overflow;
    uint8_t tx_errors, rx_errors;    /* counters when the controller reports them */
} can_err_info_t;

/* Decode an error frame (CAN_ERR_FLAG set). 0, or -1 with errno EINVAL if f is not an error frame. */
int can_err_decode(const struct can_frame *f, can_err_info_t *info);
/* New bus state after an error frame; a data frame received means the bus works again. */
can_bus_health_t can_health_next(can_bus_health_t cur, const can_err_info_t *info);
const char *can_health_name(can_bus_health_t s);

/* "123#1122" style text of a frame, as candump prints it; returns buf. */
char *can_frame_str(const struct can_frame *f, char *buf, size_t cap);

/* ---- the bus handle ---- */

typedef struct can_bus can_bus_t;

typedef struct {
    uint64_t rx, tx;            /* frames delivered / sent */
    uint64_t rx_filtered;       /* dropped by software filters (emulated backend) */
    uint64_t rx_bad;            /* packets that are not a CAN frame (wrong size, bad DLC) */
    uint64_t err_frames;        /* error frames delivered */
    uint64_t bus_off;           /* bus-off events */
    uint64_t tx_errors;         /* writes that failed (ENOBUFS, ENETDOWN, ...) */
} can_stats_t;

/* Open by URL: "can:IFNAME" (SocketCAN raw, e.g. can:vcan0) or "emu:PATH" (a marie-canbus
 * daemon listening on the AF_UNIX socket PATH). The fd is non-blocking. NULL with errno. */
can_bus_t *can_bus_open(const char *url);
/* Wrap one end of socketpair(AF_UNIX, SOCK_SEQPACKET) speaking the emulated bus protocol
 * (one 16-byte struct can_frame per packet). The bus owns fd from now on. */
can_bus_t *can_bus_from_fd(int fd);
void can_bus_close(can_bus_t *bus);         /* NULL is a no-op */

int can_bus_fd(const can_bus_t *bus);       /* poll it for can_bus_events() */
bool can_bus_is_socketcan(const can_bus_t *bus);
const char *can_bus_url(const can_bus_t *bus);

/* The emulated bus's one packet that is not a frame: a client's receive filters, so that its
 * server sends it only what they take, as SocketCAN's CAN_RAW_FILTER and CAN_RAW_ERR_FILTER do
 * in the kernel. 12 + 8 n bytes (never a frame's 16 or 72): "MFLT", n (u32, at most
 * CAN_EMU_MAX_FILTERS), the error mask (u32), then n x { can_id, can_mask } (u32 each), host
 * byte order. Sent by can_bus_set_filters and can_bus_set_err_mask on an "emu:" bus, whole
 * each time; a server that has none from a client sends it everything. */
#define CAN_EMU_FILTER_MAGIC "MFLT"
#define CAN_EMU_MAX_FILTERS 64
#define CAN_EMU_FILTER_HDR 12

/* Receive filters (replace the previous set; n == 0 receives everything). 0, or -1 with errno. On
 * the emulated bus the server is told too (best effort: the client filters what it reads
 * whatever the server sends). */
int can_bus_set_filters(can_bus_t *bus, const struct can_filter *filters, size_t n);
/* Which error frames to deliver (CAN_ERR_MASK bits; 0 = none, the default). */
int can_bus_set_err_mask(can_bus_t *bus, can_err_mask_t mask);

/* Read one frame: 1 with *f filled, 0 when nothing is waiting, -1 with errno on failure (EPIPE
 * when the emulated bus went away). Packets that are not frames are counted and skipped.
 * Error frames update the bus state (can_bus_state) before they are returned. */
int can_bus_read(can_bus_t *bus, struct can_frame *f);
/* Write one frame without blocking. 0, or -1 with errno (EAGAIN: transmit queue full; ENETDOWN:
 * bus-off or link down); failures are counted in tx_errors. On the emulated bus a frame its
 * server has no room for yet is held (up to 64, in order) and 0 returned: the caller's loop
 * watches can_bus_events() and calls can_bus_flush() when the fd is writable. */
int can_bus_write(can_bus_t *bus, const struct can_frame *f);
/* Send held frames as far as the server takes them: how many are still held, or -1 with errno. */
int can_bus_flush(can_bus_t *bus);
/* What to poll the fd for: POLLIN, and POLLOUT while frames are held. */
short can_bus_events(const can_bus_t *bus);

/* CAN FD: accept and send struct canfd_frame (72-byte packets; CAN_RAW_FD_FRAMES on
 * SocketCAN). Off by default; then FD frames are never delivered. */
int can_bus_enable_fd(can_bus_t *bus, bool on);
/* Like can_bus_read for both kinds: *is_fd tells which; a classic frame arrives in the
 * first CAN_MTU bytes layout (len <= 8). With FD off, only classic frames come. */
int can_bus_read_fd(can_bus_t *bus, struct canfd_frame *f, bool *is_fd);
int can_bus_write_fd(can_bus_t *bus, const struct canfd_frame *f);

can_bus_health_t can_bus_health(const can_bus_t *bus);
/* Ask for recovery after bus-off: SocketCAN restarts the controller through rtnetlink
 * (needs CAP_NET_ADMIN; EOPNOTSUPP on virtual interfaces), the emulated bus just resets
 * the state. The state returns to active in any case once frames flow again. */
int can_bus_restart(can_bus_t *bus);
const can_stats_t *can_bus_stats(const can_bus_t *bus);

#ifdef __cplusplus
}
#endif
#endif
