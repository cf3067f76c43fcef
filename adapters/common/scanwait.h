/* scanwait: a laser scan meets the odometry of its own instant. A scan newer than the newest
 * odometry waits (one at most, a copy) until odometry brackets it; the component's handler then
 * runs on it. What the localizer and the mapper do with each scan starts here. */
#ifndef ADAPTERS_SCANWAIT_H
#define ADAPTERS_SCANWAIT_H

#include <stdbool.h>

#include "adapters/common/posebuf.h"
#include "core/component.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef void (*scanwait_fn)(marie_component_t *c, const marie_laser_scan_t *scan);

typedef struct {
    marie_laser_scan_t scan;    /* the waiting scan when `held` (ranges only) */
    float *ranges;
    int cap;
    bool held;
} scanwait_t;

/* A scan arrived: fn runs on it now when odom covers its time, else it waits (a scan already
 * waiting runs late first, counted as scans_late_odometry). Without odometry it is dropped and
 * counted (scans_without_odometry). */
void scanwait_scan(scanwait_t *w, marie_component_t *c, const posebuf_t *odom, const marie_laser_scan_t *m,
                   scanwait_fn fn);
/* Odometry at `utime` was added: the waiting scan runs if it is now covered. */
void scanwait_odometry(scanwait_t *w, marie_component_t *c, int64_t utime, scanwait_fn fn);
/* Forget the waiting scan (the odometry frame changed); scanwait_free also lets go of memory. */
void scanwait_drop(scanwait_t *w);
void scanwait_free(scanwait_t *w);

#ifdef __cplusplus
}
#endif
#endif
