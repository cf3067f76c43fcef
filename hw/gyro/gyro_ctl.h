/* gyro_ctl: the CANopen master for the yaw-rate gyro, without I/O: configures the TPDO
 * (event timer), heartbeat and starts the node; decodes samples; watches heartbeat and EMCY. */
#ifndef MARIE_HW_GYRO_CTL_H
#define MARIE_HW_GYRO_CTL_H

#include <stdbool.h>
#include <stdint.h>
#include <linux/can.h>

#include "hw/canopen/nmt.h"
#include "hw/canopen/sdo.h"
#include "hw/gyro/gyro_ctl_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/* gyro_cfg_t: the master's parameters, declared in gyro_ctl.params.yaml (node id, rate_hz,
 * heartbeat period and timeout, in the units a user writes); gyro_cfg_default() gives their
 * defaults. */
void gyro_cfg_default(gyro_cfg_t *cfg);

/* HB_TIMEOUT: heartbeats stopped once the device had been told to send them (0x1017).
 * NOT_FOUND: no boot-up within GYRO_BOOT_RETRY_US of the start: reported once until one comes. */
#define GYRO_BOOT_RETRY_US 2000000
#define GYRO_SDO_TIMEOUT_US 200000
typedef enum {
    GYRO_EV_CONFIGURED, GYRO_EV_CONFIG_FAILED, GYRO_EV_EMCY, GYRO_EV_HB_TIMEOUT, GYRO_EV_BOOTUP,
    GYRO_EV_BAD_FRAME, GYRO_EV_UNEXPECTED, GYRO_EV_LOST,   /* LOST: code = samples missed */
    GYRO_EV_NOT_FOUND,
} gyro_ev_t;

typedef void (*gyro_sample_cb_t)(void *user, double rate, uint8_t status);
typedef void (*gyro_event_cb_t)(void *user, gyro_ev_t ev, uint32_t code);

typedef struct gyro_ctl gyro_ctl_t;

/* NULL with errno: EINVAL for a node id outside 1..127, rate_hz outside 1..1000, heartbeat_ms
 * outside 0..65535 or a negative heartbeat_timeout. */
gyro_ctl_t *gyro_ctl_create(const gyro_cfg_t *cfg, gyro_sample_cb_t on_sample, gyro_event_cb_t on_event, void *user);
void gyro_ctl_destroy(gyro_ctl_t *g);
int gyro_ctl_start(gyro_ctl_t *g, int64_t now, struct can_frame *tx, int max);
int gyro_ctl_feed(gyro_ctl_t *g, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max);
/* Timeouts and retries; call a few times a second. */
int gyro_ctl_poll(gyro_ctl_t *g, int64_t now, struct can_frame *tx, int max);
bool gyro_ctl_running(const gyro_ctl_t *g);     /* configured, started and heard */
const char *gyro_ctl_name(const gyro_ctl_t *g); /* the device's 0x1008 */
double gyro_ctl_period_s(const gyro_ctl_t *g);  /* between samples: the event timer's whole ms */
int gyro_ctl_filters(const gyro_ctl_t *g, struct can_filter *f, int max);

#ifdef __cplusplus
}
#endif
#endif
