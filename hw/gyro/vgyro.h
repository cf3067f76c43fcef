/* vgyro: a virtual CANopen yaw-rate gyro. The simulator feeds the true yaw rate; the gyro
 * adds its bias and noise and sends samples in TPDO1 by its event timer. */
#ifndef MARIE_HW_VGYRO_H
#define MARIE_HW_VGYRO_H

#include <stdint.h>
#include <linux/can.h>

#include "hw/canopen/dev.h"
#include "hw/gyro/vgyro_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/* vgyro_cfg_t: the gyro's settings, declared in vgyro.params.yaml (bias, noise, range, seed)
 * with VGYRO_DEFAULTS, and its node id and name, set by the code. */

void vgyro_cfg_default(vgyro_cfg_t *cfg, uint8_t node);

typedef struct vgyro vgyro_t;
vgyro_t *vgyro_create(const vgyro_cfg_t *cfg);
void vgyro_destroy(vgyro_t *g);
int vgyro_boot(vgyro_t *g, int64_t now, struct can_frame *tx, int max);
int vgyro_feed(vgyro_t *g, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max);
/* Heartbeat and samples due at now (the event timer). */
int vgyro_poll(vgyro_t *g, int64_t now, struct can_frame *tx, int max);
void vgyro_set_rate(vgyro_t *g, double true_yaw_rate);
/* Sensor fault: status 2 in every sample and an EMCY 0x7300; 0 clears it (EMCY 0x0000). */
void vgyro_set_fault(vgyro_t *g, int fault);
co_nmt_state_t vgyro_nmt(const vgyro_t *g);

#ifdef __cplusplus
}
#endif
#endif
