/* driver: the LMS200 state machine over a serial fd: find the device, initialise it, stream
 * scans, and recover from silence, garbage and a device that goes away and comes back. */
#ifndef MARIE_HW_LMS200_DRIVER_H
#define MARIE_HW_LMS200_DRIVER_H

#include <stdbool.h>
#include <stdint.h>

#include "hw/lms200/lms200.h"
#include "hw/lms200/driver_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/* lms200_driver_cfg_t: the driver's parameters, declared in driver.params.yaml (device, baud,
 * resolution in degrees, address, the timeouts in ms, retries); LMS200_DRIVER_DEFAULTS gives
 * their defaults. The driver copies the device's path. */

typedef enum {
    LMS200_DRV_CLOSED = 0,      /* no fd; reopening on a timer */
    LMS200_DRV_PROBE,           /* "stop continuous output" at each candidate rate */
    LMS200_DRV_VARIANT,         /* 180 degrees at the configured resolution */
    LMS200_DRV_BAUD,            /* switch the line to the configured rate */
    LMS200_DRV_START,           /* continuous output */
    LMS200_DRV_STREAM,          /* scans arriving */
} lms200_drv_state_t;

typedef struct {
    int64_t scans;              /* good scans delivered */
    int64_t crc_errors, truncated, oversized, garbage_bytes;
    int64_t bad_scans;          /* scans with an unexpected beam count or units */
    int64_t timeouts;           /* replies not received, streams that went silent */
    int64_t disconnects;        /* the fd hung up or failed */
    int64_t reconnects;         /* streaming again after a loss */
    int64_t naks;
    int64_t inits;              /* completed init sequences */
    int64_t degraded;           /* times the device went without a good scan for degraded_ms */
} lms200_driver_stats_t;

typedef struct {
    /* A complete scan; mono_us is when its last byte was read. */
    void (*on_scan)(void *user, const lms200_scan_t *scan, int res_cdeg, int64_t mono_us);
    /* Something a person should hear about: severity 0..3 as event_t, kind a short tag. */
    void (*on_event)(void *user, int severity, const char *kind, const char *text);
    /* A counter changed; bad_input marks counters of malformed input. */
    void (*on_count)(void *user, const char *counter, int64_t delta, bool bad_input);
    /* The device fd changed (opened, closed); -1 for none. */
    void (*on_fd)(void *user, int old_fd, int new_fd);
    /* No good scan for degraded_ms (degraded true, why says what the driver is doing), or
     * scans again (false). */
    void (*on_health)(void *user, bool degraded, const char *why);
} lms200_driver_ops_t;

typedef struct lms200_driver lms200_driver_t;

/* NULL with errno: EINVAL for a baud rate other than 9600, 19200, 38400 or 500000, a resolution
 * other than 0.5 or 1, an address over 127, or a timeout or retries not above 0. Any op may be
 * NULL. */
lms200_driver_t *lms200_driver_create(const lms200_driver_cfg_t *cfg, const lms200_driver_ops_t *ops, void *user);
void lms200_driver_destroy(lms200_driver_t *d);        /* closes the fd; NULL is a no-op */

/* Open the device and begin the init sequence (a failed open is retried on the timer). */
void lms200_driver_start(lms200_driver_t *d, int64_t now_us);
/* Ask the device to stop continuous output and close the line. */
void lms200_driver_stop(lms200_driver_t *d);

int lms200_driver_fd(const lms200_driver_t *d);        /* -1 when closed */
/* What to poll the fd for: POLLIN, and POLLOUT while a command waits for room on the line
 * (it may change after any call below). */
short lms200_driver_events(const lms200_driver_t *d);
/* Call when the loop reports events on the fd. */
void lms200_driver_io(lms200_driver_t *d, short revents, int64_t now_us);
/* Call at or after the deadline; harmless earlier. */
void lms200_driver_tick(lms200_driver_t *d, int64_t now_us);
int64_t lms200_driver_deadline(const lms200_driver_t *d);   /* monotonic us; INT64_MAX: none */

lms200_drv_state_t lms200_driver_state(const lms200_driver_t *d);
bool lms200_driver_degraded(const lms200_driver_t *d);
int lms200_driver_baud(const lms200_driver_t *d);      /* the line's current rate */
/* The stream's data timeout at the line's current rate (data_timeout_ms, or longer where 3
 * scan telegram times at the line's rate are: 2.49 s for 361 values at 9600 baud). */
int lms200_driver_data_timeout_ms(const lms200_driver_t *d);
const lms200_driver_stats_t *lms200_driver_stats(const lms200_driver_t *d);

#ifdef __cplusplus
}
#endif
#endif
