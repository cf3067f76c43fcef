/* vision_detect: AprilTag detection with libapriltag plus tag pose from camera intrinsics. */
#ifndef VISION_DETECT_H
#define VISION_DETECT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "adapters/vision/vision_detect_params.h"
#include "camera/vision_geom.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct vision_detector vision_detector_t;

/* vision_detector_opts_t (vision_detect.params.yaml): family (see vision_family_names), decimate
 * (libapriltag's quad_decimate), sigma (quad_sigma, px of blur before segmenting), threads,
 * refine_edges, sharpening (decode_sharpening), max_hamming (bits the decoder may correct, 0..2),
 * min_margin (detections with a lower decision margin are dropped). */
void vision_detector_opts_default(vision_detector_opts_t *o);

typedef struct {
    int id;
    int hamming;
    float margin;
    double center[2];
    double corners[4][2];
    bool pose_valid;
    vision_pose_t pose;     /* tag frame in the camera's optical frame (see vision_render.h) */
    double pose_err;
} vision_detection_t;

/* NULL on failure with a reason in err (unknown family, bad parameter, no memory). */
vision_detector_t *vision_detector_create(const vision_detector_opts_t *o, char *err, size_t errlen);
void vision_detector_destroy(vision_detector_t *d);     /* NULL is a no-op */
const char *vision_detector_family(const vision_detector_t *d);

/* Intrinsics and tag size for poses; without them detections carry no pose. The camera's
 * width/height are those the intrinsics were calibrated for. 0, or -1 with errno EINVAL with *why. */
int vision_detector_set_camera(vision_detector_t *d, const vision_camera_t *cam, double tag_size, const char **why);

/* Detects tags in an 8-bit grey image. Writes at most `max` detections to out, sorted by
 * id, and returns how many were found in total (may exceed max), or -1 with errno EINVAL for bad
 * arguments. When the frame's size differs from the camera's, poses are skipped and
 * *pose_skipped (if given) is set. */
int vision_detector_detect(vision_detector_t *d, const uint8_t *gray, int width, int height, int stride,
                           vision_detection_t *out, int max, bool *pose_skipped);

#ifdef __cplusplus
}
#endif
#endif
