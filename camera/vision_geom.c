/* vision_geom: rigid poses, quaternions and pinhole projection shared by the vision modules. */
#include "camera/vision_geom.h"

#include <errno.h>
#include <math.h>
#include <string.h>

#include "core/err.h"

void vision_pose_identity(vision_pose_t *p)
{
    memset(p, 0, sizeof *p);
    p->R[0] = p->R[4] = p->R[8] = 1.0;
}

void vision_pose_compose(const vision_pose_t *a, const vision_pose_t *b, vision_pose_t *out)
{
    vision_pose_t r;
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++)
            r.R[3 * i + j] = a->R[3 * i] * b->R[j] + a->R[3 * i + 1] * b->R[3 + j] + a->R[3 * i + 2] * b->R[6 + j];
        r.t[i] = a->R[3 * i] * b->t[0] + a->R[3 * i + 1] * b->t[1] + a->R[3 * i + 2] * b->t[2] + a->t[i];
    }
    *out = r;
}

void vision_pose_inverse(const vision_pose_t *p, vision_pose_t *out)
{
    vision_pose_t r;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r.R[3 * i + j] = p->R[3 * j + i];
    for (int i = 0; i < 3; i++)
        r.t[i] = -(r.R[3 * i] * p->t[0] + r.R[3 * i + 1] * p->t[1] + r.R[3 * i + 2] * p->t[2]);
    *out = r;
}

void vision_pose_apply(const vision_pose_t *p, const double in[3], double out[3])
{
    double o[3];
    for (int i = 0; i < 3; i++)
        o[i] = p->R[3 * i] * in[0] + p->R[3 * i + 1] * in[1] + p->R[3 * i + 2] * in[2] + p->t[i];
    memcpy(out, o, sizeof o);
}

void vision_rot_rpy(double roll, double pitch, double yaw, double R[9])
{
    double cr = cos(roll), sr = sin(roll), cp = cos(pitch), sp = sin(pitch);
    double cy = cos(yaw), sy = sin(yaw);
    R[0] = cy * cp; R[1] = cy * sp * sr - sy * cr; R[2] = cy * sp * cr + sy * sr;
    R[3] = sy * cp; R[4] = sy * sp * sr + cy * cr; R[5] = sy * sp * cr - cy * sr;
    R[6] = -sp;     R[7] = cp * sr;                R[8] = cp * cr;
}

void vision_rot_to_quat(const double R[9], double q[4])
{
    /* Shepperd's method: pick the largest diagonal term to stay well conditioned. */
    double tr = R[0] + R[4] + R[8];
    double w, x, y, z;
    if (tr > 0) {
        double s = sqrt(tr + 1.0) * 2;
        w = 0.25 * s; x = (R[7] - R[5]) / s; y = (R[2] - R[6]) / s; z = (R[3] - R[1]) / s;
    } else if (R[0] > R[4] && R[0] > R[8]) {
        double s = sqrt(1.0 + R[0] - R[4] - R[8]) * 2;
        w = (R[7] - R[5]) / s; x = 0.25 * s; y = (R[1] + R[3]) / s; z = (R[2] + R[6]) / s;
    } else if (R[4] > R[8]) {
        double s = sqrt(1.0 + R[4] - R[0] - R[8]) * 2;
        w = (R[2] - R[6]) / s; x = (R[1] + R[3]) / s; y = 0.25 * s; z = (R[5] + R[7]) / s;
    } else {
        double s = sqrt(1.0 + R[8] - R[0] - R[4]) * 2;
        w = (R[3] - R[1]) / s; x = (R[2] + R[6]) / s; y = (R[5] + R[7]) / s; z = 0.25 * s;
    }
    double n = sqrt(w * w + x * x + y * y + z * z);
    if (w < 0)
        n = -n;
    q[0] = w / n; q[1] = x / n; q[2] = y / n; q[3] = z / n;
}

void vision_quat_to_rot(const double q[4], double R[9])
{
    double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
    R[0] = 1 - 2 * (y * y + z * z); R[1] = 2 * (x * y - z * w);     R[2] = 2 * (x * z + y * w);
    R[3] = 2 * (x * y + z * w);     R[4] = 1 - 2 * (x * x + z * z); R[5] = 2 * (y * z - x * w);
    R[6] = 2 * (x * z - y * w);     R[7] = 2 * (y * z + x * w);     R[8] = 1 - 2 * (x * x + y * y);
}

double vision_rot_angle_between(const double A[9], const double B[9])
{
    /* trace(A^T B) = 1 + 2 cos(angle) */
    double tr = 0;
    for (int i = 0; i < 9; i++)
        tr += A[i] * B[i];
    double c = (tr - 1) / 2;
    if (c > 1) c = 1;
    if (c < -1) c = -1;
    return acos(c);
}

static void set_axes(vision_pose_t *p, const double x[3], const double y[3], const double z[3])
{
    /* The columns of R are the child's axes in the parent frame. */
    for (int i = 0; i < 3; i++) {
        p->R[3 * i] = x[i];
        p->R[3 * i + 1] = y[i];
        p->R[3 * i + 2] = z[i];
    }
}

void vision_pose_tag_on_wall(double x, double y, double z, double yaw, vision_pose_t *out)
{
    /* z points into the tag (away from its viewers), y down, x = y cross z. */
    double zt[3] = { -cos(yaw), -sin(yaw), 0 };
    double yt[3] = { 0, 0, -1 };
    double xt[3] = { yt[1] * zt[2] - yt[2] * zt[1], yt[2] * zt[0] - yt[0] * zt[2], yt[0] * zt[1] - yt[1] * zt[0] };
    set_axes(out, xt, yt, zt);
    out->t[0] = x; out->t[1] = y; out->t[2] = z;
}

void vision_pose_camera_in_world(double x, double y, double z, double yaw, double pitch, vision_pose_t *out)
{
    /* Looking along heading yaw, tilted down by pitch; x right, y down, z forward. */
    double cp = cos(pitch), sp = sin(pitch);
    double zc[3] = { cos(yaw) * cp, sin(yaw) * cp, -sp };
    double xc[3] = { sin(yaw), -cos(yaw), 0 };
    double yc[3] = { zc[1] * xc[2] - zc[2] * xc[1], zc[2] * xc[0] - zc[0] * xc[2], zc[0] * xc[1] - zc[1] * xc[0] };
    set_axes(out, xc, yc, zc);
    out->t[0] = x; out->t[1] = y; out->t[2] = z;
}

bool vision_project_tag(const vision_camera_t *cam, const vision_pose_t *tag, double size, double px[4][2])
{
    /* libapriltag's corner order in the tag frame (x right, y down as printed). */
    static const double c[4][2] = { { -1, 1 }, { 1, 1 }, { 1, -1 }, { -1, -1 } };
    for (int i = 0; i < 4; i++) {
        double in[3] = { c[i][0] * size / 2, c[i][1] * size / 2, 0 }, p[3];
        vision_pose_apply(tag, in, p);
        if (p[2] <= 1e-6)
            return false;
        px[i][0] = cam->fx * p[0] / p[2] + cam->cx;
        px[i][1] = cam->fy * p[1] / p[2] + cam->cy;
    }
    return true;
}

int vision_camera_check(const vision_camera_t *cam, const char **why)
{
    const char *w = NULL;
    if (!isfinite(cam->fx) || !isfinite(cam->fy) || !isfinite(cam->cx) || !isfinite(cam->cy))
        w = "intrinsics are not finite numbers";
    else if (cam->fx <= 0 || cam->fy <= 0)
        w = "focal lengths fx, fy must be positive";
    else if (cam->width <= 0 || cam->height <= 0)
        w = "image size must be positive";
    else if (cam->cx < 0 || cam->cx > cam->width || cam->cy < 0 || cam->cy > cam->height)
        w = "principal point (cx, cy) lies outside the image";
    else if (cam->fx / cam->fy > 4 || cam->fy / cam->fx > 4)
        w = "fx and fy differ by more than 4x";
    if (why)
        *why = w;
    return w ? marie_fail(EINVAL) : 0;
}
