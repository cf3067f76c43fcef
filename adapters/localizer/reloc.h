/* reloc: global relocalization. Scan points gathered while the robot turns (and drives) are kept
 * in the frame of the pose where gathering began; the whole free space of the map is searched
 * for the poses of that frame that explain them best (a coarse pass over every position and
 * heading, the best refined on the localizer's field), and each is judged as a scan is. */
#ifndef ADAPTERS_LOCALIZER_RELOC_H
#define ADAPTERS_LOCALIZER_RELOC_H

#include "adapters/localizer/mcl.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct reloc_cloud reloc_cloud_t;

/* NULL with errno ENOMEM. reloc_cloud_destroy(NULL) is a no-op. */
reloc_cloud_t *reloc_cloud_create(void);
void reloc_cloud_destroy(reloc_cloud_t *c);
/* Starts again, the frame being the robot's at odometry pose odom. */
void reloc_cloud_reset(reloc_cloud_t *c, const double odom[3]);
/* Adds a scan taken at odometry pose odom, the laser at `mount` (x, y, theta) on the robot: its
 * returns (not max-range readings), one per 10 cm square of the frame (20000 squares at most).
 * A square counts once two scans have seen it: a stray reading is seen once. */
void reloc_cloud_add(reloc_cloud_t *c, const double odom[3], const double mount[3], const mcl_scan_t *scan);
/* The map pose of the robot now (odometry pose odom) if the frame's origin is at `origin`, and the
 * frame's origin if the robot is at map pose `now`. */
void reloc_cloud_pose_now(const reloc_cloud_t *c, const double origin[3], const double odom[3], double out[3]);
void reloc_cloud_origin(const reloc_cloud_t *c, const double now[3], const double odom[3], double out[3]);

typedef struct {
    double x, y, theta;         /* the frame's origin in the map */
    double score;               /* mean log likelihood per point (higher: better) */
    double hit;                 /* share of the points within 3 sigma of a wall of the map */
    double contradiction;       /* share of the points' rays, of those that hit or pass through a
                                   wall, that pass through one (or end off the map) */
} reloc_hyp_t;

/* Up to max hypotheses, best score first, each at least 1 m or 0.35 rad from every better one;
 * the cloud's origin is searched over the map cells known free at least 0.15 m from a wall.
 * Returns how many; -1 with errno ENOMEM. */
int reloc_search(const mcl_t *f, const reloc_cloud_t *c, reloc_hyp_t *out, int max);
/* One place, the frame's origin near `origin` (refined within 10 cm and 3 degrees), scored and
 * judged as reloc_search's are. */
void reloc_judge_at(const mcl_t *f, const reloc_cloud_t *c, const double origin[3], reloc_hyp_t *out);

#ifdef __cplusplus
}
#endif
#endif
