/* vision_landmark: a tag seen by a robot-mounted camera, placed in the map frame from the
 * robot's pose at the image time. */
#ifndef VISION_LANDMARK_H
#define VISION_LANDMARK_H

#include "camera/vision_geom.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The camera on the robot, as the simulator's camera mounts it (vision_simcam_opts_t): x
 * forward, y left, z up from the robot's origin on the floor, m; yaw turns it left, pitch
 * tilts it down, rad. */
typedef struct {
    double x, y, z, yaw, pitch;
} vision_mount_t;

typedef struct {
    double x, y, z;     /* tag centre in the map frame, m */
    double yaw;         /* heading the printed face points to, rad */
    double range;       /* m from the camera */
    double bearing;     /* rad from the robot's heading, left positive */
} vision_landmark_t;

/* Places a tag whose pose in the camera's optical frame is tag_in_cam. */
void vision_landmark_place(const vision_mount_t *m, const double robot[3], const vision_pose_t *tag_in_cam,
                           vision_landmark_t *out);

#ifdef __cplusplus
}
#endif
#endif
