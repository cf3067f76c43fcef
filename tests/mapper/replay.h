/* replay: the mapper's library fed as marie-mapper feeds it (odometry buffered and interpolated
 * at each scan's instant, scans waiting in order for their odometry: adapters/common), from
 * messages handed over in log order; every scan placed is kept with its time in the mapper. For
 * mapper_replay and the mapper's benchmarks on recorded and real logs. */
#ifndef TESTS_MAPPER_REPLAY_H
#define TESTS_MAPPER_REPLAY_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "adapters/mapper/slam.h"
#include "lcmtypes/marie_laser_scan_t.h"

typedef struct replay replay_t;

typedef struct {
    int64_t utime;
    double pose[3];             /* the mapper's, in the map frame */
    double odom[3];             /* the odometry at the scan */
    double ms;                  /* CPU time of slam_add_scan (the thread's: load elsewhere does not count) */
    bool optimized;             /* a closure optimized the graph (and re-rendered the map) in it */
} replay_scan_t;

typedef struct {
    double p50, p99, max;       /* ms a scan, over the scans that optimized nothing */
    size_t closures;            /* scans that optimized */
    double closure_max;         /* ms of the slowest of those (optimization and re-render included) */
    double total_s;             /* s in the mapper over the whole log */
} replay_times_t;

/* NULL with errno (slam_create's). replay_destroy(NULL) is a no-op. */
replay_t *replay_create(const slam_params_t *p, const double start[3]);
void replay_destroy(replay_t *r);
void replay_odometry(replay_t *r, int64_t utime, const double pose[3]);
void replay_laser(replay_t *r, const marie_laser_scan_t *m);
slam_t *replay_slam(replay_t *r);
const replay_scan_t *replay_scans(const replay_t *r, size_t *n);
void replay_times(const replay_t *r, replay_times_t *t);

#endif
