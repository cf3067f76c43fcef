/* occmap: occupancy grid maps for the adapters: ROS map_server files, ray casting, test worlds. */
#ifndef ADAPTERS_OCCMAP_H
#define ADAPTERS_OCCMAP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/config.h"

#ifdef __cplusplus
extern "C" {
#endif

#define OCCMAP_FREE      0
#define OCCMAP_OCCUPIED  100
#define OCCMAP_UNKNOWN   (-1)

/* Row-major cells from the origin cell (0,0) at the lower-left corner, as in ROS: row 0 is the
 * bottom of the map (the last line of the PGM image). */
typedef struct occmap {
    int width, height;          /* cells */
    double resolution;          /* m per cell */
    double origin_x, origin_y;  /* map-frame position of cell (0,0)'s corner */
    int8_t *cells;              /* OCCMAP_FREE, OCCMAP_OCCUPIED or OCCMAP_UNKNOWN */
} occmap_t;

/* A map of free cells. NULL on failure (errno). occmap_destroy(NULL) is a no-op. */
occmap_t *occmap_create(int width, int height, double resolution, double origin_x, double origin_y);
void occmap_destroy(occmap_t *m);
occmap_t *occmap_clone(const occmap_t *m);

/* Thresholds and mode of a map.yaml (trinary interpretation). */
typedef struct {
    double resolution, origin_x, origin_y;
    bool negate;
    double occupied_thresh, free_thresh;
} occmap_meta_t;

/* Decode a binary (P5) or ASCII (P2) PGM image held in buf. NULL on bad input with a reason
 * in err. Pure: no I/O. */
occmap_t *occmap_from_pgm(const uint8_t *buf, size_t len, const occmap_meta_t *meta,
                          char *err, size_t errlen);
/* Load a ROS map_server map: map.yaml (image, resolution, origin, negate, occupied_thresh,
 * free_thresh) and the image it names (relative to the yaml's folder). NULL with the
 * reasons (file:line:col) in errs. */
occmap_t *occmap_load(const char *yaml_path, marie_errors_t *errs);

/* Cell of a map-frame point; false when outside. */
static inline bool occmap_cell(const occmap_t *m, double x, double y, int *cx, int *cy)
{
    double fx = (x - m->origin_x) / m->resolution, fy = (y - m->origin_y) / m->resolution;
    if (fx < 0 || fy < 0 || fx >= m->width || fy >= m->height)
        return false;
    *cx = (int)fx;
    *cy = (int)fy;
    return true;
}
/* Value of a cell; outside the map is OCCMAP_UNKNOWN. */
static inline int8_t occmap_get(const occmap_t *m, int cx, int cy)
{
    if (cx < 0 || cy < 0 || cx >= m->width || cy >= m->height)
        return OCCMAP_UNKNOWN;
    return m->cells[(size_t)cy * m->width + cx];
}
bool occmap_occupied_at(const occmap_t *m, double x, double y);  /* outside: true */

/* Set every cell of the map-frame rectangle [x0,x1]x[y0,y1] to value. */
void occmap_fill_rect(occmap_t *m, double x0, double y0, double x1, double y1, int8_t value);
/* Distance along a ray to the first occupied cell, or max_range when none is hit (cells
 * outside the map stop the ray as well). */
double occmap_raycast(const occmap_t *m, double x, double y, double angle, double max_range);
/* An office-like test world: outer walls, a corridor, rooms with doors, some furniture. */
occmap_t *occmap_make_office(double width_m, double height_m, double resolution, uint32_t seed);

#ifdef __cplusplus
}
#endif
#endif
