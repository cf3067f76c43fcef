/* drives_ctl: the CANopen master for two CiA 402 wheel drives, without I/O: it configures the
 * drives over SDO, starts them with NMT, walks their state machines to operation enabled,
 * sends controlword + target velocity in RPDO1 and SYNC every cycle, reads statusword,
 * position and velocity TPDOs, watches heartbeats and EMCY, and resets faults.
 * Frames in with drives_ctl_feed(), frames out into the caller's array. */
#ifndef MARIE_HW_DRIVES_CTL_H
#define MARIE_HW_DRIVES_CTL_H

#include <stdbool.h>
#include <stdint.h>
#include <linux/can.h>

#include "hw/canopen/nmt.h"
#include "hw/canopen/sdo.h"
#include "hw/drives/cia402.h"
#include "hw/drives/drives_ctl_params.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { DRIVES_LEFT = 0, DRIVES_RIGHT = 1, DRIVES_N = 2 };

typedef struct drives_ctl drives_ctl_t;

/* drives_cfg_t: the master's parameters, declared in drives_ctl.params.yaml (node ids, inverted
 * mountings, encoder resolution, the command timeout, heartbeats, SDO and RPDO deadlines, in the
 * units a user writes: s and ms); drives_cfg_default() gives their defaults. */
void drives_cfg_default(drives_cfg_t *cfg);

typedef enum {
    DRIVES_AX_BOOT = 0,     /* waiting for the boot-up message */
    DRIVES_AX_CONFIG,       /* SDO configuration running */
    DRIVES_AX_RUN,          /* started: PDOs flow */
    DRIVES_AX_OFFLINE,      /* heartbeat lost */
} drives_ax_phase_t;

/* Where a drive's configuration stopped: every failure names the object. */
typedef struct {
    uint16_t index;
    uint8_t sub;
    bool write;                     /* a download (else an upload) */
    uint32_t abort;                 /* the SDO abort code (CO_SDO_ABORT_TIMEOUT: no answer); 0 when
                                     * the drive answered a value marie cannot use: */
    uint32_t value;                 /* ... that value (0x1000: not a CiA 402 device) */
    uint32_t repeats;               /* attempts before this one that failed alike */
} drives_cfg_fail_t;

typedef struct {
    drives_ax_phase_t phase;
    co_nmt_state_t nmt;
    cia402_state_t state;
    uint16_t statusword, controlword;
    int32_t position;               /* increments, sign-corrected */
    int32_t velocity;               /* increments/s, sign-corrected */
    int32_t target;                 /* increments/s sent last, drive frame */
    uint16_t last_emcy;             /* the last EMCY's code, 0x0000 (error reset) included */
    bool have_fault_emcy;           /* an error EMCY came that no error reset (0x0000) cleared: */
    uint16_t fault_emcy;            /* ... its code */
    bool have_tpdo;
    bool recovering;                /* faulted; RECOVERED is told on reaching operation */
    char name[32];                  /* the drive's 0x1008 */
    uint32_t identity[4];           /* its 0x1018: vendor id, product code, revision, serial (0: absent) */
    bool watches_hb;                /* it watches our heartbeat (0x1016 written, master_heartbeat_ms > 0) */
    bool watches_rpdo;              /* it watches our RPDOs (0x1400:05 written, rpdo_timeout_ms > 0) */
    bool lacks_consumer;            /* it has no 0x1016 (optional in CiA 301) */
    bool refused;                   /* configured, but kept disabled: it watches neither */
    bool interlocked;               /* restart interlock: target 0 until a command newer than ... */
    int64_t enabled_at;             /* ... the moment it was (again) in operation enabled (0: not yet) */
    bool booted;                    /* a boot-up heard since our last reset communication */
    drives_cfg_fail_t fail;         /* the last configuration failure (index 0: none since configured) */
    uint64_t faults, emcy, fault_resets, hb_timeouts, bootups, sdo_aborts, config_failures;
    uint64_t stops;                 /* NMT stop / enter pre-operational sent on losing control */
    /* private */
    int job;
    uint16_t missing_index;         /* the optional object last told missing in this configuration */
    bool not_found_told, hold_told;
    int64_t phase_since, fault_since, emcy_window_start;
    uint32_t emcy_in_window;
    bool rpdo_early;                /* an RPDO1 went out at once since the last SYNC */
    uint16_t rpdo_cw;               /* the controlword of the last RPDO1 sent */
    co_sdo_client_t sdo;
} drives_axis_t;

typedef enum {
    DRIVES_EV_CONFIGURED,       /* axis configured and started */
    DRIVES_EV_CONFIG_FAILED,    /* SDO abort or wrong device type: code = abort code; the
                                 * axis' `fail` names the object */
    DRIVES_EV_FAULT,            /* entered fault (statusword): code = fault_emcy when
                                 * have_fault_emcy (else no EMCY told why) */
    DRIVES_EV_FAULT_RESET,      /* sent a fault reset */
    DRIVES_EV_RECOVERED,        /* back in operation enabled after a fault */
    DRIVES_EV_EMCY,             /* emergency message: code = error code */
    DRIVES_EV_EMCY_STORM,       /* more than 10 EMCY in a second: further ones only counted */
    DRIVES_EV_HB_TIMEOUT,
    DRIVES_EV_BOOTUP,           /* the node (re)booted */
    DRIVES_EV_BAD_FRAME,        /* malformed frame from a drive (wrong DLC...): code = COB-ID */
    DRIVES_EV_UNEXPECTED,       /* a frame no drive should send: code = COB-ID */
    DRIVES_EV_EMCY_QUIET,       /* an EMCY past the storm threshold: count it, no event */
    DRIVES_EV_OPTIONAL_MISSING, /* an optional object is absent: code = index << 8 | sub */
    DRIVES_EV_WATCH,            /* configured, and how it will notice our death is worth telling:
                                 * code = DRIVES_WATCH_* */
    DRIVES_EV_HOLD,             /* (re)enabled with a motor command from before: target held at 0
                                 * until a newer one (restart interlock) */
    DRIVES_EV_NOT_FOUND,        /* no boot-up within DRIVES_BOOT_RETRY_US of a reset communication */
} drives_ev_t;

enum {
    DRIVES_WATCH_RPDO_ONLY = 1, /* no consumer heartbeat (0x1016 absent or ours off): by its RPDO deadline */
    DRIVES_WATCH_NONE_ALLOWED,  /* neither, enabled all the same (allow_unwatched) */
    DRIVES_WATCH_NONE_REFUSED,  /* neither: kept disabled */
};

/* A silent node is sent reset communication again after this long. */
#define DRIVES_BOOT_RETRY_US 2000000

const char *drives_ev_name(drives_ev_t ev);
/* What an event says to a person, naming the drive, and for configuration failures the object
 * (index, sub-index, its name, read or write) and the abort; into buf. */
void drives_ctl_event_text(const drives_ctl_t *d, int axis, drives_ev_t ev, uint32_t code, char *buf, size_t cap);
typedef void (*drives_event_cb_t)(void *user, int axis, drives_ev_t ev, uint32_t code);

/* -1 with the reason in why[0..len) (EINVAL) for parameters the protocol cannot carry: node ids
 * outside 1..127 or alike, ticks_per_rev <= 0, periods over 65535 ms, negative times, a
 * heartbeat consumer time (master_timeout) not longer than our heartbeat's period. */
int drives_cfg_check(const drives_cfg_t *cfg, char *why, size_t len);
/* NULL with errno (EINVAL: drives_cfg_check refuses cfg). */
drives_ctl_t *drives_ctl_create(const drives_cfg_t *cfg, drives_event_cb_t cb, void *user);
void drives_ctl_destroy(drives_ctl_t *d);           /* NULL is a no-op */

/* Begin: NMT reset-communication to both nodes (they answer with boot-up). */
int drives_ctl_start(drives_ctl_t *d, int64_t now, struct can_frame *tx, int max);
/* enable false brings the drives to switch on disabled (component stopped). */
void drives_ctl_enable(drives_ctl_t *d, bool enable);
void drives_ctl_set_estop(drives_ctl_t *d, bool pressed);
/* Wheel velocities in rad/s (left, right), counted from `now` for the command timeout. */
void drives_ctl_set_wheels(drives_ctl_t *d, double left, double right, int64_t now);
/* A frame from the bus; returns frames to send. */
int drives_ctl_feed(drives_ctl_t *d, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max);
/* One SYNC cycle: our heartbeat when due, SDO and heartbeat timeouts, controlwords, RPDO1 to
 * each running drive, then SYNC. Call it every 1/sync_hz for as long as the drives are ours
 * (also while disabled), or they see the heartbeat and RPDOs stop. Returns frames to send
 * (at most 9 are ever needed). */
int drives_ctl_cycle(drives_ctl_t *d, int64_t now, struct can_frame *tx, int max);
/* RPDO1 of both running drives now, with the current command (on the bus at once rather
 * than up to a cycle later; the drives apply them at the next SYNC). At most one per drive
 * between two SYNCs unless its controlword changes (an e-stop, a disable): a later command
 * in the same period rides with the cycle's RPDO1 just before that SYNC, applied at the same
 * instant, so a client sending commands far faster than the cycle cannot flood the bus. */
int drives_ctl_rpdo_now(drives_ctl_t *d, int64_t now, struct can_frame *tx, int max);

/* Leaving for good: disable voltage in RPDO1 with one last SYNC, then NMT stop to both. */
int drives_ctl_shutdown(drives_ctl_t *d, int64_t now, struct can_frame *tx, int max);

const drives_axis_t *drives_ctl_axis(const drives_ctl_t *d, int axis);
bool drives_ctl_all_enabled(const drives_ctl_t *d);
bool drives_ctl_command_stale(const drives_ctl_t *d, int64_t now);
/* CAN filters matching every frame the drives send: fills up to max, returns count. */
int drives_ctl_filters(const drives_ctl_t *d, struct can_filter *f, int max);
double drives_ctl_counts_to_rad(const drives_ctl_t *d, double counts);
uint8_t drives_ctl_node(const drives_ctl_t *d, int axis);
/* The RPDO deadline written to the drives' 0x1400:05, ms (0: off). */
uint16_t drives_ctl_rpdo_timeout_ms(const drives_ctl_t *d);

#ifdef __cplusplus
}
#endif
#endif
