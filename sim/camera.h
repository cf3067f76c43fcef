/* sim camera: the simulator's camera, rendered from the world file's walls and tag signs. */
#ifndef SIM_CAMERA_H
#define SIM_CAMERA_H

#include <stddef.h>
#include <stdint.h>

#include "core/component.h"
#include "lcmtypes/marie_image_t.h"
#include "map/occmap.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sim_camera sim_camera_t;

typedef struct {
    double hz;          /* frames per simulated second */
    double step;        /* physics step, s: frames fall on whole steps */
    int width, height;  /* 0: the world file's (or 640x480); intrinsics scale with the size */
    uint32_t seed;      /* noise */
} sim_camera_cfg_t;

/* Reads `camera:` and `tags:` from the world file `yaml` (the map.yaml the map came from; both
 * optional) and builds the camera over the map's walls. NULL with the reason (file:line:col
 * for mistakes in the file) in why. */
sim_camera_t *sim_camera_create(const char *yaml, const occmap_t *map, const sim_camera_cfg_t *cfg,
                                char *why, size_t len);
void sim_camera_destroy(sim_camera_t *c);      /* NULL is a no-op */

/* At physics step k: when a frame is due, renders it with the robot at (x, y, theta) and
 * returns 1 with *img (owned by the camera until the next call) stamped utime; 0 when no
 * frame is due; a negative errno when rendering failed. */
int sim_camera_step(sim_camera_t *c, int64_t k, double x, double y, double theta, int64_t utime, marie_image_t *img);
size_t sim_camera_tags(const sim_camera_t *c);

/* marie-sim's hook. From the parameters camera, camera_hz and camera_size: *out = NULL when
 * the camera is off; -1 after marie_component_fail_reason() on a mistake. */
int sim_camera_init(marie_component_t *c, const char *yaml, const occmap_t *map, double step, sim_camera_t **out);
/* Publishes a frame on port p when one is due (counted: camera_frames, camera_render_us). */
void sim_camera_publish(sim_camera_t *cam, marie_component_t *c, marie_port_t *p, int64_t k, double x, double y,
                        double theta, int64_t utime);

#ifdef __cplusplus
}
#endif
#endif
