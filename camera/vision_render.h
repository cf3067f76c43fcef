/* vision_render: a synthetic pinhole camera that draws AprilTags at known 3D poses, with
 * blur and noise, from the family's own codes (for tests, benchmarks and the simulator). */
#ifndef VISION_RENDER_H
#define VISION_RENDER_H

#include <stddef.h>
#include <stdint.h>

#include "camera/vision_geom.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct vision_render vision_render_t;

/* One tag to draw: `size` is the edge of its black border in metres (libapriltag's tag
 * size; the white quiet zone around it is drawn too), `pose` its frame (x right, y down as
 * printed, z into the tag, origin at the centre) in the camera's optical frame, or in the
 * world for vision_render_world(). */
typedef struct {
    int id;
    double size;
    vision_pose_t pose;
} vision_tag_t;

typedef enum {
    VISION_BG_FLAT = 0,     /* uniform bg_level */
    VISION_BG_GRADIENT,     /* left-to-right ramp around bg_level */
    VISION_BG_CLUTTER,      /* random boxes and discs, some with strong edges */
    VISION_BG_IMAGE,        /* bg_image: a scene drawn by the caller (the simulator's walls) */
} vision_bg_t;

typedef struct {
    vision_bg_t background;
    uint8_t bg_level;       /* default 128 */
    uint8_t black, white;   /* printed ink and paper levels, default 20 and 235 */
    double blur_sigma;      /* Gaussian blur, px (0: none) */
    double noise_sigma;     /* additive Gaussian noise, grey levels (0: none) */
    uint32_t seed;          /* noise and clutter are a function of the seed */
    int supersample;        /* anti-aliasing factor per axis, default 3 */
    int noise_table;        /* nonzero: noise is a seed-placed window of one stored field
                             * (fast, for the simulator) instead of drawn afresh */
    const uint8_t *bg_image;/* VISION_BG_IMAGE: width x height grey bytes, rows width apart
                             * (the caller's; read during the call only) */
} vision_render_opts_t;

void vision_render_opts_default(vision_render_opts_t *o);

/* A renderer for one family ("tag36h11", ...). NULL with errno = ENOENT if unknown. */
vision_render_t *vision_render_create(const char *family);
void vision_render_destroy(vision_render_t *r);     /* NULL is a no-op */
int vision_render_ncodes(const vision_render_t *r);
/* Cells per side of a tag image (the family's total width) and of its black border. */
int vision_render_total_cells(const vision_render_t *r);
int vision_render_border_cells(const vision_render_t *r);

/* Writes tag `id` as total x total cells, one byte each (0 black, 255 white), rows `stride`
 * apart. 0, or -1 with errno EINVAL for an id outside the family. */
int vision_render_tag_cells(const vision_render_t *r, int id, uint8_t *out, int stride);

/* Draws `n` tags seen by `cam` into `out` (cam->width x cam->height, `channels` 1 or 3
 * identical bytes per pixel, rows `stride` bytes apart). Tags are drawn far to near so
 * nearer ones occlude; a tag reaching behind the camera is skipped. Returns how many tags
 * were drawn at least partly inside the image, or -1 with errno EINVAL (bad camera, id or arguments). */
int vision_render_frame(vision_render_t *r, const vision_camera_t *cam, const vision_tag_t *tags, size_t n,
                        const vision_render_opts_t *o, uint8_t *out, int stride, int channels);

/* The same with tag poses in the world and the camera's optical frame at `cam_in_world`
 * (see vision_pose_camera_in_world and vision_pose_tag_on_wall). */
int vision_render_world(vision_render_t *r, const vision_camera_t *cam, const vision_pose_t *cam_in_world,
                        const vision_tag_t *tags, size_t n, const vision_render_opts_t *o,
                        uint8_t *out, int stride, int channels);

#ifdef __cplusplus
}
#endif
#endif
