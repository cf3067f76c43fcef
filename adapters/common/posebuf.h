/* posebuf: a short time-indexed buffer of 2D poses (odometry), interpolated at any instant,
 * and SE(2) composition: what TF does in ROS for the pose at a scan's timestamp. */
#ifndef ADAPTERS_POSEBUF_H
#define ADAPTERS_POSEBUF_H

#include <stdbool.h>
#include <stdint.h>

#include "lcmtypes/marie_odometry_t.h"

#ifdef __cplusplus
extern "C" {
#endif

#define POSEBUF_CAP 64          /* 6.4 s of odometry at 10 Hz */

typedef struct {
    int64_t utime[POSEBUF_CAP];
    double pose[POSEBUF_CAP][3];
    int n, head;                /* head: the next slot to write */
} posebuf_t;

void posebuf_clear(posebuf_t *b);
/* Adds a sample; the oldest goes when full. Samples must come in time order (the caller
 * decides what an older one means: see the localizer's odometry restart). */
void posebuf_add(posebuf_t *b, int64_t utime, const double pose[3]);
/* The pose at time t, interpolated between the samples around it, clamped to the oldest and
 * newest; false when the buffer is empty. */
bool posebuf_at(const posebuf_t *b, int64_t t, double out[3]);
int64_t posebuf_newest(const posebuf_t *b);        /* INT64_MIN when empty */
/* Whether t lies within the samples, or at most `slack` us after the newest. */
bool posebuf_covers(const posebuf_t *b, int64_t t, int64_t slack);
/* The newest sample's pose; false when empty. */
bool posebuf_last(const posebuf_t *b, double out[3]);

/* out = a (+) b: pose b given in frame a. out may alias neither. */
void pose2d_compose(const double a[3], const double b[3], double out[3]);
/* out = a^-1 (+) b: pose b seen from pose a. */
void pose2d_between(const double a[3], const double b[3], double out[3]);

/* Whether odometry message m starts a new frame after the buffer's newest sample: time going
 * back (a replayed log), its distance shrinking below last_distance (a restarted odometry counts
 * from zero again) or a jump no robot makes. *jump gets the distance jumped (0 when empty). */
bool posebuf_frame_changed(const posebuf_t *b, const marie_odometry_t *m, double last_distance, double *jump);

#ifdef __cplusplus
}
#endif
#endif
