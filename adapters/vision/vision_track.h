/* vision_track: follows tag ids over frames: track ids, first/last seen, smoothed pose. */
#ifndef VISION_TRACK_H
#define VISION_TRACK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "adapters/vision/vision_detect.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct vision_tracker vision_tracker_t;

typedef struct {
    int track_id;           /* new for every appearance of a tag */
    int tag_id;
    int64_t first_seen_us, last_seen_us;
    int hits;               /* frames the tag was seen in during this appearance */
    bool confirmed;         /* hits reached min_hits */
    bool pose_valid;
    vision_pose_t pose;     /* exponentially smoothed */
} vision_track_t;

typedef struct {
    double alpha;           /* weight of a new pose in the smoothed one, 0 < alpha <= 1; default 0.3 */
    int64_t lost_after_us;  /* unseen this long ends the track; default 500000 */
    int min_hits;           /* frames before a track is confirmed; default 2 */
} vision_tracker_opts_t;

typedef enum {
    VISION_TRACK_NEW = 0,
    VISION_TRACK_CONFIRMED,
    VISION_TRACK_LOST,
} vision_track_event_t;
typedef void (*vision_track_cb_t)(void *user, const vision_track_t *t, vision_track_event_t ev);

void vision_tracker_opts_default(vision_tracker_opts_t *o);
vision_tracker_t *vision_tracker_create(const vision_tracker_opts_t *o);
void vision_tracker_destroy(vision_tracker_t *t);       /* NULL is a no-op */

/* Feeds one frame's detections at time now_us. out (n entries, may be NULL) receives each
 * detection's track, valid until the next call. cb (may be NULL) hears about new,
 * confirmed and lost tracks. Returns 0, or -1 with errno ENOMEM. A repeated id in one frame joins the
 * same track; only its first sighting updates the pose. */
int vision_tracker_update(vision_tracker_t *t, int64_t now_us, const vision_detection_t *dets, int n,
                          const vision_track_t **out, vision_track_cb_t cb, void *user);
/* Ends tracks unseen since now_us - lost_after_us (also done by update). */
void vision_tracker_expire(vision_tracker_t *t, int64_t now_us, vision_track_cb_t cb, void *user);
size_t vision_tracker_count(const vision_tracker_t *t);
const vision_track_t *vision_tracker_get(const vision_tracker_t *t, size_t i);

#ifdef __cplusplus
}
#endif
#endif
