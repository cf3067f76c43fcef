/* vlms200: a virtual SICK LMS200 on a pseudo-terminal, answering the real telegram protocol,
 * with ranges fed by the caller (the simulator's physics) and fault injection for tests. */
#ifndef MARIE_HW_LMS200_VLMS200_H
#define MARIE_HW_LMS200_VLMS200_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "hw/lms200/lms200.h"
#include "hw/lms200/vlms200_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/* vlms200_cfg_t: the device's settings, declared in vlms200.params.yaml (rate_hz, units "mm" or
 * "cm", address, fault injection every Nth scan, ignore_baud) with VLMS200_DEFAULTS, and
 * marie-vlms200's options VLMS200_CLI; line_time is set by the code (the simulator). */

typedef struct {
    int64_t commands;           /* good telegrams received */
    int64_t naks_sent;          /* answers to damaged or unknown commands */
    int64_t scans_sent;
    int64_t corrupted, garbage_bytes, truncated;   /* injected faults */
    int64_t dropped_scans;      /* not sent because the host was not reading */
    int64_t baud_mismatch_bytes;/* bytes received or sent while the host's rate differed */
    int64_t lost_bytes;         /* sent while the host's buffer was full (host dead or stalled) */
    int64_t unplugs;
    int64_t baud_changes;
} vlms200_stats_t;

typedef struct vlms200 vlms200_t;

/* NULL with errno on failure (EINVAL: units not "mm" or "cm", an address over 127); cfg NULL
 * takes the defaults; a rate_hz <= 0 is the LMS200's mirror, 75. */
vlms200_t *vlms200_create(const vlms200_cfg_t *cfg);
void vlms200_destroy(vlms200_t *v);                     /* NULL is a no-op */

/* Create the pty and power the device on (9600 baud, output stopped, 180 deg at 1 deg).
 * link (may be NULL) becomes a symlink to the slave, replaced atomically on every reopen,
 * so a driver configured with the link finds the device again after an unplug; it is
 * removed while the device is unplugged and by vlms200_destroy. */
int vlms200_open(vlms200_t *v, const char *link);
const char *vlms200_path(const vlms200_t *v);          /* the slave's path, "" when unplugged */
int vlms200_fd(const vlms200_t *v);                     /* master fd, -1 when unplugged */
short vlms200_events(const vlms200_t *v);               /* what to watch the fd for */
void vlms200_io(vlms200_t *v, short revents, int64_t now_us);
void vlms200_tick(vlms200_t *v, int64_t now_us);
int64_t vlms200_deadline(const vlms200_t *v);           /* monotonic us; INT64_MAX: none */
/* Whether vlms200_tick(v, now_us) writes to the host: a caller whose host stamps what it
 * reads by a clock the caller publishes (the simulator) publishes that instant first. */
bool vlms200_sends_at(const vlms200_t *v, int64_t now_us);

/* Ranges in metres for the next scans: n >= 2 values evenly spread from 0 to 180 degrees
 * (right to left), resampled to the current resolution. Non-finite or out-of-range values
 * are sent as "no echo". The default is a ramp: 1 m at 0 deg to 2.8 m at 180 deg. */
void vlms200_set_ranges(vlms200_t *v, const float *ranges_m, size_t n);
/* Called just before each scan telegram is built (streaming or on request), so a
 * simulator can set the ranges for that very moment with vlms200_set_ranges(). */
typedef void (*vlms200_scan_cb_t)(void *user, vlms200_t *v, int64_t now_us);
void vlms200_on_scan(vlms200_t *v, vlms200_scan_cb_t cb, void *user);
/* The range (metres) the device sends for beam i at the resolution res_cdeg. */
double vlms200_expected_range(const vlms200_t *v, int i, int res_cdeg);

/* Faults. */
void vlms200_silence(vlms200_t *v, int64_t until_us);   /* no answers, no scans until then */
void vlms200_inject_garbage(vlms200_t *v, size_t n);    /* n garbage bytes right now */
/* Close the pty and remove the link now (the cable is pulled); a fresh pty, with the device
 * power-cycled, and the link to it appear after back_after_us (< 0: never). */
void vlms200_unplug(vlms200_t *v, int64_t now_us, int64_t back_after_us);

/* State as the device sees it. */
int vlms200_baud(const vlms200_t *v);
bool vlms200_streaming(const vlms200_t *v);
int vlms200_res_cdeg(const vlms200_t *v);
const vlms200_stats_t *vlms200_stats(const vlms200_t *v);
/* Bytes sent that the host has not read yet (0 when unplugged or unknown): a simulator uses it
 * to keep simulated time from running far ahead of a driver that lags in wall time. */
int vlms200_unread(const vlms200_t *v);
/* Of those, the bytes already on the host's side of the line (the device's own queue for the
 * line time left out): what the host could read now and has not. */
int vlms200_host_unread(const vlms200_t *v);

#ifdef __cplusplus
}
#endif
#endif
