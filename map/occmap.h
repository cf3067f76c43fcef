/* occmap: marie's one occupancy grid: ROS map_server files (docs/map.md), ray casting, test worlds.
 * Used by the simulator, the adapters, the viewer and the demo alike. */
#ifndef MARIE_MAP_OCCMAP_H
#define MARIE_MAP_OCCMAP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/config.h"
#include "map/pgm.h"

#ifdef __cplusplus
extern "C" {
#endif

#define OCCMAP_FREE      0
#define OCCMAP_OCCUPIED  100
#define OCCMAP_UNKNOWN   (-1)

/* Row-major cells from the origin cell (0,0) at the lower-left corner, as in ROS: row 0 is the
 * bottom of the map (the last line of the PGM image). Values as in marie.occupancy_grid_t:
 * OCCMAP_FREE, OCCMAP_OCCUPIED, OCCMAP_UNKNOWN, or 1..99 in map_server's scale and raw modes
 * (neither free nor occupied: consumers treat them as unknown). The grid is always aligned with
 * the map frame: a map file whose origin has a yaw is resampled when it is loaded. */
typedef struct occmap {
    int width, height;          /* cells */
    double resolution;          /* m per cell */
    double origin_x, origin_y;  /* map-frame position of cell (0,0)'s corner */
    int8_t *cells;
} occmap_t;

/* A map of free cells. NULL on failure (errno). occmap_destroy(NULL) is a no-op. */
occmap_t *occmap_create(int width, int height, double resolution, double origin_x, double origin_y);
void occmap_destroy(occmap_t *m);
occmap_t *occmap_clone(const occmap_t *m);

/* How a map.yaml turns pixels into cells (map_server's semantics, docs/map.md). */
typedef enum { OCCMAP_TRINARY, OCCMAP_SCALE, OCCMAP_RAW } occmap_mode_t;
typedef struct {
    double resolution;
    double origin_x, origin_y, origin_yaw;
    occmap_mode_t mode;
    bool negate;
    double occupied_thresh, free_thresh;
    int image_line, image_col;  /* where the map.yaml names its image, for messages */
} occmap_meta_t;

/* The map of a decoded image (row 0 at the top, as in the file) under meta's rules, resampled
 * to the map frame when origin_yaw is not 0. NULL with errno (EINVAL: bad geometry; ENOMEM). */
occmap_t *occmap_from_image(const pgm_t *img, const occmap_meta_t *meta);
/* A copy of width*height cells whose cell (0,0) corner is at (origin_x, origin_y) and whose rows
 * run along origin_yaw (a marie.occupancy_grid_t, say), resampled to the map frame when
 * origin_yaw is not 0. NULL with errno (EINVAL, ENOMEM). */
occmap_t *occmap_from_cells(int width, int height, double resolution, double origin_x, double origin_y,
                            double origin_yaw, const int8_t *cells);
/* Load a ROS map_server map: map.yaml and the PGM image it names. NULL with the reasons
 * (file:line:col) in errs. Free with occmap_destroy. */
occmap_t *occmap_load(const char *yaml_path, marie_errors_t *errs);
/* The map.yaml of a world: NAME (no '/', no .yaml) is looked up in $MARIE_SIM_WORLDS, sim/worlds
 * and /usr/local/share/marie/worlds (sim/worlds/NAME.yaml when none has it); a path is kept. */
void occmap_world_path(const char *name, char *out, size_t len);

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
/* Map-frame centre of cell (cx, cy). */
static inline void occmap_cell_center(const occmap_t *m, int cx, int cy, double *x, double *y)
{
    *x = m->origin_x + (cx + 0.5) * m->resolution;
    *y = m->origin_y + (cy + 0.5) * m->resolution;
}
/* Value of a cell; outside the map is OCCMAP_UNKNOWN. */
static inline int8_t occmap_get(const occmap_t *m, int cx, int cy)
{
    if (cx < 0 || cy < 0 || cx >= m->width || cy >= m->height)
        return OCCMAP_UNKNOWN;
    return m->cells[(size_t)cy * m->width + cx];
}
bool occmap_occupied_at(const occmap_t *m, double x, double y);  /* outside: true */

/* Where a robot may stand. occmap_footprint_clear: no occupied cell under the rectangle of
 * length lx and width ly centred at (x, y) heading th, and the cell under its centre known free.
 * occmap_nearest_clear: the centre of the free cell nearest (x, y) around which every cell within
 * radius is known free; 0, or -1 with errno ENOENT when the map has none. */
bool occmap_footprint_clear(const occmap_t *m, double x, double y, double th, double lx, double ly);
int occmap_nearest_clear(const occmap_t *m, double x, double y, double radius, double *ox, double *oy);

/* A copy at cells of `res` m (coarser than m's), same origin: a cell is occupied when any cell of
 * m whose centre lies in it is, free when all of them are free, else unknown (what a mapper with
 * coarse cells draws of the same walls). NULL with errno (EINVAL, ENOMEM). */
occmap_t *occmap_coarsen(const occmap_t *m, double res);
/* Set every cell of the map-frame rectangle [x0,x1]x[y0,y1] to value. */
void occmap_fill_rect(occmap_t *m, double x0, double y0, double x1, double y1, int8_t value);
/* Distance along a ray to the first occupied cell, or max_range when none is hit (cells
 * outside the map stop the ray as well). */
double occmap_raycast(const occmap_t *m, double x, double y, double angle, double max_range);
/* Write m as a map_server pair: yaml_path (ending in .yaml) and the PGM beside it with the same
 * stem, in map_saver's trinary form (occupied 0, free 254..255, unknown 205; thresholds 0.65 and
 * 0.196), each written to a temporary file and renamed. 0, or -1 with errno (EINVAL, I/O). */
int occmap_save(const occmap_t *m, const char *yaml_path);
/* The PGM value occmap_save() writes for a cell (0..100 as occupancy, anything else unknown). */
uint8_t occmap_save_pixel(int8_t v);
/* An office-like test world: outer walls, a corridor, rooms with doors, some furniture. */
occmap_t *occmap_make_office(double width_m, double height_m, double resolution, uint32_t seed);

#ifdef __cplusplus
}
#endif
#endif
