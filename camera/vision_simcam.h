/* vision_simcam: a robot-mounted synthetic camera looking at tags fixed in a 2D world, as
 * the simulator needs it: robot pose in, marie.image_t out. */
#ifndef VISION_SIMCAM_H
#define VISION_SIMCAM_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "camera/vision_render.h"
#include "core/config.h"
#include "lcmtypes/marie_image_t.h"
#include "map/occmap.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct vision_simcam vision_simcam_t;

typedef struct {
    const char *family;             /* default "tag36h11" */
    vision_camera_t cam;            /* default 640x480, fx = fy = 500, centred */
    /* Mount on the robot (x forward, y left, z up from the robot's origin on the floor), m;
     * yaw turns the camera left, pitch tilts it down, rad. Default (0.2, 0, 0.5), 0, 0. */
    double mount_x, mount_y, mount_z, mount_yaw, mount_pitch;
    vision_render_opts_t render;    /* noise, blur, background; seed advances per frame */
    int format;                     /* MARIE_IMAGE_T_FORMAT_GRAY8 (default), RGB8 or JPEG */
    int jpeg_quality;               /* default 90 */
    double wall_height;             /* m, walls of vision_simcam_set_walls (default 2.5) */
    double max_range;               /* m, walls farther are not drawn (default 20) */
} vision_simcam_opts_t;

void vision_simcam_opts_default(vision_simcam_opts_t *o);

/* Reads a `camera` map (width, height, fx, fy, cx, cy, mount_x, mount_y, mount_z, mount_yaw,
 * mount_pitch, noise, blur, background, format, family; all optional) into o, and a `tags`
 * list of {id, x, y, z, yaw, size} (yaw: the heading the printed face points to) into a
 * malloc'd array. Either node may be NULL. 0, or -1 with errno EINVAL with file:line:col errors in errs. */
int vision_simcam_parse(const marie_node_t *camera, const marie_node_t *tags, vision_simcam_opts_t *o,
                        vision_tag_t **out, size_t *nout, marie_errors_t *errs);

/* Copies the options (family name included) and the tags. NULL with a reason in err. */
vision_simcam_t *vision_simcam_create(const vision_simcam_opts_t *o, const vision_tag_t *tags, size_t n,
                                      char *err, size_t errlen);
void vision_simcam_destroy(vision_simcam_t *s);      /* NULL is a no-op */

/* Walls: the occupied cells of `map` (copied) stand wall_height tall; the camera sees them
 * (floor, wall and ceiling shades, panel seams every metre) and a tag whose centre is behind
 * a wall is not drawn. Walls are drawn per image column, exact for mount_pitch = 0 and
 * shifted by the pitch otherwise. 0, or -1 with errno ENOMEM. */
int vision_simcam_set_walls(vision_simcam_t *s, const occmap_t *map);

/* Whether tag i (0..n-1 as given to create) is in front of the camera, inside its field of
 * view and not hidden by a wall, with the robot at (x, y, theta): the ground truth tests
 * compare detections with. */
bool vision_simcam_tag_visible(const vision_simcam_t *s, size_t i, double x, double y, double theta);

/* The camera's optical frame in the world with the robot at (x, y, theta). */
void vision_simcam_camera_pose(const vision_simcam_t *s, double x, double y, double theta, vision_pose_t *out);
const vision_simcam_opts_t *vision_simcam_opts(const vision_simcam_t *s);

/* Renders what the camera sees with the robot at (x, y, theta) into *img, stamped utime.
 * img->data belongs to the simcam and stays valid until the next call. Returns the number of
 * tags drawn, or a negative errno. */
int vision_simcam_render(vision_simcam_t *s, double x, double y, double theta, int64_t utime, marie_image_t *img);

#ifdef __cplusplus
}
#endif
#endif
