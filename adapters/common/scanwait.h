/* scanwait: a laser scan meets the odometry of its own instant. Scans newer than the newest
 * odometry wait, in order, until odometry brackets them (at most SCANWAIT_CAP, copies); the
 * component's handler then runs on each. What the localizer and the mapper do with each scan
 * starts here: tf's message filter in ROS does the same. */
#ifndef ADAPTERS_SCANWAIT_H
#define ADAPTERS_SCANWAIT_H

#include <stdbool.h>

#include "adapters/common/posebuf.h"
#include "core/component.h"

#ifdef __cplusplus
extern "C" {
#endif

/* 0.8 s of scans at 10 Hz: the odometry is one hop further from the devices than the laser,
 * and under load it can fall a few periods behind. */
#define SCANWAIT_CAP 8

typedef void (*scanwait_fn)(marie_component_t *c, const marie_laser_scan_t *scan);

typedef struct {
    marie_laser_scan_t scan;    /* ranges only: intensities are not kept */
    int cap;                    /* floats the scan's ranges buffer holds */
} scanwait_slot_t;

typedef struct {
    scanwait_slot_t slot[SCANWAIT_CAP];
    int head, n;                /* the oldest waiting scan, and how many wait */
} scanwait_t;

/* A scan arrived: fn runs on it now when odom covers its time (after the scans waiting before
 * it), else it waits. When SCANWAIT_CAP already wait, the oldest is dropped, never run with
 * odometry older than itself (counted as scans_late_odometry); a scan not newer than the newest
 * waiting one is dropped (scans_out_of_order), and so is one before any odometry
 * (scans_without_odometry). c may be NULL (nothing is counted). */
void scanwait_scan(scanwait_t *w, marie_component_t *c, const posebuf_t *odom, const marie_laser_scan_t *m,
                   scanwait_fn fn);
/* Odometry at `utime` was added: the waiting scans it covers run, oldest first. */
void scanwait_odometry(scanwait_t *w, marie_component_t *c, int64_t utime, scanwait_fn fn);
/* How many scans wait. */
int scanwait_waiting(const scanwait_t *w);
/* Forget the waiting scans (the odometry frame changed); scanwait_free also lets go of memory. */
void scanwait_drop(scanwait_t *w);
void scanwait_free(scanwait_t *w);

#ifdef __cplusplus
}
#endif
#endif
