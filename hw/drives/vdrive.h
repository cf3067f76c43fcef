/* vdrive: a virtual CiA 402 wheel drive in profile velocity mode, speaking CANopen frames.
 * The simulator ticks it and reads the commanded wheel velocity; it may write back the
 * measured wheel position and velocity. Without that feedback, an ideal motor follows the
 * ramped setpoint. Frames go in with vdrive_feed(); answers come out into the caller's array. */
#ifndef MARIE_HW_VDRIVE_H
#define MARIE_HW_VDRIVE_H

#include <stdbool.h>
#include <stdint.h>
#include <linux/can.h>

#include "hw/drives/cia402.h"
#include "hw/canopen/dev.h"
#include "hw/drives/vdrive_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Identity 0x1018 (the serial number is the node id). */
#define VDRIVE_VENDOR_ID    0x00000000u     /* no CiA vendor id: an emulator */
#define VDRIVE_PRODUCT_CODE 0x00000402u
#define VDRIVE_REVISION     0x00010000u

/* vdrive_cfg_t: the drive's settings, declared in vdrive.params.yaml (ticks_per_rev, accel,
 * quickstop_decel, max_velocity, the power-on RPDO deadline in s, the optional objects it lacks)
 * with VDRIVE_DEFAULTS, and its node id and name, set by the code. */

void vdrive_cfg_default(vdrive_cfg_t *cfg, uint8_t node);

typedef struct vdrive vdrive_t;

vdrive_t *vdrive_create(const vdrive_cfg_t *cfg);   /* NULL with errno (EINVAL: ticks_per_rev <= 0) */
void vdrive_destroy(vdrive_t *v);                   /* NULL is a no-op */

/* Power on: boot-up message. Returns frames written (at most max). */
int vdrive_boot(vdrive_t *v, int64_t now, struct can_frame *tx, int max);
/* A frame from the bus. Returns frames to send. */
int vdrive_feed(vdrive_t *v, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max);
/* Time-driven output (heartbeat, queued EMCY), the heartbeat consumer (0x1016) and the RPDO
 * deadline (0x1400:05): their loss is answered per 0x6007 (default 1: fault reaction). */
int vdrive_poll(vdrive_t *v, int64_t now, struct can_frame *tx, int max);

/* Physics. step() ramps the velocity setpoint toward the target (or to zero when stopping)
 * and, without external feedback, integrates the ideal motor. */
void vdrive_step(vdrive_t *v, double dt);
double vdrive_command(const vdrive_t *v);            /* rad/s the motor is told to turn */
void vdrive_set_feedback(vdrive_t *v, double pos_rad, double vel_rad_s);
double vdrive_velocity(const vdrive_t *v);           /* rad/s */

/* Fault injection: fault reaction, then fault; an EMCY with `code` is queued. */
void vdrive_inject_fault(vdrive_t *v, uint16_t code);
/* A statusword fault without an EMCY (a drive that only reports through its statusword). */
void vdrive_inject_silent_fault(vdrive_t *v, uint16_t code);

cia402_state_t vdrive_state(const vdrive_t *v);
uint16_t vdrive_statusword(const vdrive_t *v);
co_nmt_state_t vdrive_nmt(const vdrive_t *v);
uint8_t vdrive_node(const vdrive_t *v);
const co_dev_stats_t *vdrive_stats(const vdrive_t *v);

#ifdef __cplusplus
}
#endif
#endif
