/* gyro_ctl: the CANopen master for the yaw-rate gyro, without I/O: configures the TPDO
 * (event timer), heartbeat and starts the node; decodes samples; watches heartbeat and EMCY. */
#ifndef MARIE_HW_GYRO_CTL_H
#define MARIE_HW_GYRO_CTL_H

#include <stdbool.h>
#include <stdint.h>
#include <linux/can.h>

#include "hw/canopen/nmt.h"
#include "hw/canopen/sdo.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    uint8_t node;
    uint16_t period_ms;             /* TPDO event timer: one sample per period */
    uint16_t heartbeat_ms;
    int64_t heartbeat_timeout_us;
    int64_t sdo_timeout_us;
    int64_t boot_retry_us;
} gyro_cfg_t;

void gyro_cfg_default(gyro_cfg_t *cfg);

/* HB_TIMEOUT: heartbeats stopped once the device had been told to send them (0x1017).
 * NOT_FOUND: no boot-up within boot_retry_us of the start: reported once until one comes. */
typedef enum {
    GYRO_EV_CONFIGURED, GYRO_EV_CONFIG_FAILED, GYRO_EV_EMCY, GYRO_EV_HB_TIMEOUT, GYRO_EV_BOOTUP,
    GYRO_EV_BAD_FRAME, GYRO_EV_UNEXPECTED, GYRO_EV_LOST,   /* LOST: code = samples missed */
    GYRO_EV_NOT_FOUND,
} gyro_ev_t;
const char *gyro_ev_name(gyro_ev_t ev);

typedef void (*gyro_sample_cb_t)(void *user, double rate, uint8_t status);
typedef void (*gyro_event_cb_t)(void *user, gyro_ev_t ev, uint32_t code);

typedef struct gyro_ctl gyro_ctl_t;

gyro_ctl_t *gyro_ctl_create(const gyro_cfg_t *cfg, gyro_sample_cb_t on_sample, gyro_event_cb_t on_event, void *user);
void gyro_ctl_destroy(gyro_ctl_t *g);
int gyro_ctl_start(gyro_ctl_t *g, int64_t now, struct can_frame *tx, int max);
int gyro_ctl_feed(gyro_ctl_t *g, const struct can_frame *rx, int64_t now, struct can_frame *tx, int max);
/* Timeouts and retries; call a few times a second. */
int gyro_ctl_poll(gyro_ctl_t *g, int64_t now, struct can_frame *tx, int max);
bool gyro_ctl_running(const gyro_ctl_t *g);     /* configured, started and heard */
const char *gyro_ctl_name(const gyro_ctl_t *g); /* the device's 0x1008 */
int gyro_ctl_filters(const gyro_ctl_t *g, struct can_filter *f, int max);

#ifdef __cplusplus
}
#endif
#endif
