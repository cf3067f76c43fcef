/* slam: 2D laser SLAM: scan-to-map matching on a smoothed grid, keyframes in a pose graph with
 * loop closures optimized by Ceres, and the log-odds occupancy grid rendered from them. */
#ifndef ADAPTERS_MAPPER_SLAM_H
#define ADAPTERS_MAPPER_SLAM_H

#include <stdbool.h>
#include <stdint.h>

#include "adapters/mapper/slam_params.h"
#include "map/occmap.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct slam slam_t;

/* slam_params_t: the parameters, declared in slam.params.yaml; these are its defaults. */
void slam_params_default(slam_params_t *p);

/* One laser scan in the sensor frame; a beam at or beyond range_max saw nothing. */
typedef struct {
    const float *ranges;
    int n;
    double angle_min, angle_increment, range_min, range_max;
} slam_scan_t;

typedef struct {
    int64_t scans, keyframes, matches, match_failures, loop_candidates, loop_closures, optimizations;
    int64_t loop_ambiguous;             /* matched, but as well elsewhere in the window: refused */
    int64_t loop_implausible;           /* best at the window's edge, or further than the matcher drifts: refused */
    int64_t loop_unconfirmed;           /* a large correction the next closure did not repeat: dropped */
    int64_t loop_cut;                   /* searched as far as loop_max_evals allows without a clear place: dropped */
    int64_t cells_cleared;              /* walls the beams have since seen through: a moved obstacle (or a
                                         * wall drawn out of place), cleared from the map */
    int64_t window_grown;               /* searches again in a wider window after a poor match */
    int64_t odometry_disagreements;     /* matches further from the odometry than it could have erred */
    int64_t off_grid;                   /* scans part of which fell off the grid (size_m): not mapped there */
    double last_score;                  /* mean likelihood of the last match */
    double last_match_ms, last_opt_ms;
} slam_stats_t;

/* A mapper whose map frame puts the robot at pose0 when the first scan arrives. NULL with errno
 * (EINVAL: bad parameters; ENOMEM). slam_destroy(NULL) is a no-op. */
slam_t *slam_create(const slam_params_t *p, const double pose0[3]);
void slam_destroy(slam_t *s);

/* Adds a scan taken at odometry pose odom; pose (may be NULL) gets the map-frame robot pose.
 * 1 when a keyframe was added (the map changed), 0 when not, -1 with errno EINVAL on a bad scan. */
int slam_add_scan(slam_t *s, const double odom[3], const slam_scan_t *scan, double pose[3]);
/* Forget the odometry frame (it restarted): the next scan is matched from the last map pose. */
void slam_odometry_reset(slam_t *s);
/* The map cropped to the cells seen (plus a one-cell margin): 0 free .. 100 occupied,
 * OCCMAP_UNKNOWN unseen. NULL with errno (ENOENT: nothing seen yet; ENOMEM). */
occmap_t *slam_render(const slam_t *s);
/* The same with the crop's edges on multiples of `block` cells of the whole grid (and the margin
 * inside): the crop, so the map's frame, then changes only when the map grows past a block. */
occmap_t *slam_render_blocks(const slam_t *s, int block);
void slam_get_stats(const slam_t *s, slam_stats_t *st);

#ifdef __cplusplus
}
#endif
#endif
