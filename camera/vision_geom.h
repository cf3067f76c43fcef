/* vision_geom: rigid poses, quaternions and pinhole projection shared by the vision modules. */
#ifndef VISION_GEOM_H
#define VISION_GEOM_H

#include <stdbool.h>

#ifdef __cplusplus
extern "C" {
#endif

/* A pinhole camera without distortion. Pixel centres sit at integer coordinates:
 * u = fx * X / Z + cx, v = fy * Y / Z + cy in the optical frame (x right, y down, z forward). */
typedef struct {
    int width, height;
    double fx, fy, cx, cy;
} vision_camera_t;

/* Pose of a child frame in a parent frame: p_parent = R * p_child + t (R row-major). */
typedef struct {
    double R[9];
    double t[3];
} vision_pose_t;

void vision_pose_identity(vision_pose_t *p);
/* out = a * b (b expressed in a's child frame); out may alias a or b. */
void vision_pose_compose(const vision_pose_t *a, const vision_pose_t *b, vision_pose_t *out);
void vision_pose_inverse(const vision_pose_t *p, vision_pose_t *out);
void vision_pose_apply(const vision_pose_t *p, const double in[3], double out[3]);

/* R = Rz(yaw) * Ry(pitch) * Rx(roll). */
void vision_rot_rpy(double roll, double pitch, double yaw, double R[9]);
void vision_rot_to_quat(const double R[9], double q[4]);        /* q = w, x, y, z; w >= 0 */
void vision_quat_to_rot(const double q[4], double R[9]);
/* Angle of the rotation that takes A to B, in radians. */
double vision_rot_angle_between(const double A[9], const double B[9]);

/* Pose of a tag fixed in the world (z up) at centre (x, y, z), facing viewers that look at
 * it along heading yaw + pi, i.e. its printed face points towards heading `yaw`. */
void vision_pose_tag_on_wall(double x, double y, double z, double yaw, vision_pose_t *out);
/* Optical-frame pose in the world for a camera at (x, y, z) looking along heading `yaw`,
 * tilted down by `pitch` radians (a robot's camera mount). */
void vision_pose_camera_in_world(double x, double y, double z, double yaw, double pitch, vision_pose_t *out);

/* Projects the four black-border corners of a tag of edge `size` (m) at pose `tag`
 * (in the camera frame) in libapriltag's corner order. False if any is behind the camera. */
bool vision_project_tag(const vision_camera_t *cam, const vision_pose_t *tag, double size, double px[4][2]);

/* Checks intrinsics for a frame of width x height: finite, positive focal lengths, principal
 * point inside the image. 0, or -1 with errno EINVAL with a reason. */
int vision_camera_check(const vision_camera_t *cam, const char **why);

#ifdef __cplusplus
}
#endif
#endif
