/* vision_landmark: a tag seen by a robot-mounted camera, placed in the map frame. */
#include "adapters/vision/vision_landmark.h"

#include <math.h>

/* The camera's optical frame in the map with the robot at robot = (x, y, theta). */
static void vision_mount_camera_pose(const vision_mount_t *m, const double robot[3], vision_pose_t *out)
{
    double c = cos(robot[2]), s = sin(robot[2]);
    vision_pose_camera_in_world(robot[0] + c * m->x - s * m->y, robot[1] + s * m->x + c * m->y, m->z,
                                robot[2] + m->yaw, m->pitch, out);
}

void vision_landmark_place(const vision_mount_t *m, const double robot[3], const vision_pose_t *tag_in_cam,
                           vision_landmark_t *out)
{
    vision_pose_t cam, tag;
    vision_mount_camera_pose(m, robot, &cam);
    vision_pose_compose(&cam, tag_in_cam, &tag);
    out->x = tag.t[0];
    out->y = tag.t[1];
    out->z = tag.t[2];
    /* The tag's z axis points into the tag: its face looks the other way. */
    out->yaw = atan2(-tag.R[5], -tag.R[2]);
    const double *t = tag_in_cam->t;
    out->range = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    out->bearing = remainder(atan2(tag.t[1] - robot[1], tag.t[0] - robot[0]) - robot[2], 2 * M_PI);
}
