/* mcl: Monte Carlo localization on an occupancy map (likelihood field with AMCL's beam skipping,
 * augmented MCL, KLD resampling), and how well a scan fits the map at a pose. */
#ifndef ADAPTERS_MCL_H
#define ADAPTERS_MCL_H

#include <stdbool.h>
#include <stdint.h>

#include "adapters/localizer/mcl_params.h"
#include "map/occmap.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct mcl mcl_t;

/* mcl_params_t: the parameters, declared in mcl.params.yaml; these are its defaults. */
void mcl_params_default(mcl_params_t *p);

/* One laser scan in the sensor frame. */
typedef struct {
    const float *ranges;
    int n;
    double angle_min, angle_increment, range_min, range_max;
} mcl_scan_t;

/* The filter keeps its own field of the map (adapters/localizer/field.h); the map may be freed
 * after. NULL on failure (errno: EINVAL bad parameters, ENOMEM, EFBIG a map too large).
 * mcl_destroy(NULL) is a no-op. */
mcl_t *mcl_create(const occmap_t *map, const mcl_params_t *p, uint64_t seed);
void mcl_destroy(mcl_t *f);

/* Start around a pose (Gaussian, sigma x, y, theta) with max_particles particles, or
 * uniformly over the free space. */
void mcl_init_pose(mcl_t *f, const double pose[3], const double sigma[3]);
void mcl_init_global(mcl_t *f);

/* Feed the odometry pose at the scan's time and the scan. Motion since the last update is
 * applied and the scan weighs the particles when the robot moved enough (or force).
 * Returns 1 when the filter was updated, 0 when the step was skipped. */
int mcl_step(mcl_t *f, const double odom[3], const mcl_scan_t *scan, bool force);


/* Pose estimate (the mean of the best cluster) with its covariance (row-major x, y, theta). */
void mcl_estimate(const mcl_t *f, double pose[3], double cov[9]);
/* The estimate carried forward to odometry pose `odom` by the motion since the last update,
 * so a pose can be published at every scan even when the filter skipped it. */
void mcl_pose_at(const mcl_t *f, const double odom[3], double pose[3], double cov[9]);
int mcl_count(const mcl_t *f);
/* Copy up to max particles as x, y, theta, weight quadruples; returns how many. */
int mcl_particles(const mcl_t *f, float *xytw, int max);
/* Counters: sensor updates, resamplings, recovery particles injected. */
int64_t mcl_updates(const mcl_t *f);
double mcl_likelihood(const mcl_t *f);  /* smoothed mean per-beam likelihood of the last update */

/* A scan judged at one pose, beam by beam, against what the map shows from there:
 * - hit: it ends on a wall of the map (within 3 sigma) with nothing of the map on the way;
 * - shorter: it ends in the map's free space, short of any wall: something the map lacks
 *   (a box, a person) stands there. Neither for nor against the pose;
 * - through: it passed through a wall of the map, or saw nothing (max range) where the map has a
 *   wall well within range. Against the pose.
 * A beam that went where the map does not know (unknown cells, off the map) counts for neither.
 * contradiction = through / (hit + through), 0 when fewer than 10 beams are hit or through
 * (the scan says nothing either way). */
typedef struct {
    int beams, hit, shorter, through;
    double contradiction;
} mcl_fit_t;

/* Judges the scan at a map-frame robot pose (the laser's mount applied). Every beam is used. */
void mcl_judge(const mcl_t *f, const double pose[3], const mcl_scan_t *scan, mcl_fit_t *fit);
/* The last update's scan judged at the estimate, the share of beams it skipped as outliers,
 * and the weight of the estimate's cluster (1: one cluster). */
void mcl_last_fit(const mcl_t *f, mcl_fit_t *fit, double *skipped, double *cluster_mass);
/* How far a ray from (x, y) at `angle` (map frame) goes before the map's walls stop it, up to
 * max_r (the map's edge stops it too). */
double mcl_trace(const mcl_t *f, double x, double y, double angle, double max_r);
/* What the map says of a map-frame point. */
typedef enum { MCL_FREE = 0, MCL_WALL, MCL_UNKNOWN, MCL_OFF_MAP } mcl_place_t;
mcl_place_t mcl_map_at(const mcl_t *f, double x, double y);
/* "in free space", "inside a wall", "in unknown space", "off the map". */
const char *mcl_place_name(mcl_place_t where);

#ifdef __cplusplus
}
#endif
#endif
