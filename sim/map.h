/* map: ROS map_server maps (map.yaml + PGM) as an occupancy grid, and walls merged into rectangles. */
#ifndef SIM_MAP_H
#define SIM_MAP_H

#include <stddef.h>
#include <stdint.h>

#include "core/config.h"
#include "sim/pgm.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SIM_MAP_FREE      0
#define SIM_MAP_OCCUPIED  100
#define SIM_MAP_UNKNOWN   (-1)

typedef struct sim_map {
    int width, height;          /* cells */
    double resolution;          /* m per cell */
    double origin_x, origin_y;  /* map-frame pose of the lower-left corner of cell (0,0) */
    double origin_yaw;          /* rad, counter-clockwise */
    int8_t *cells;              /* width*height, row-major from the bottom row (as
                                 * marie.occupancy_grid_t): 0 free, 100 occupied, -1 unknown */
} sim_map_t;

/* Thresholds and conventions of map_server's trinary interpretation. */
typedef struct {
    double resolution;
    double origin[3];
    int negate;
    double occupied_thresh, free_thresh;
} sim_map_info_t;

/* Load map.yaml and its image (path relative to the YAML file). NULL on failure, with
 * "file:line:col: reason" messages in errs. Free with sim_map_destroy. */
sim_map_t *sim_map_load(const char *yaml_path, marie_errors_t *errs);
/* Build a map from a decoded image (row 0 at the top, as in the file). NULL on ENOMEM. */
sim_map_t *sim_map_from_pgm(const sim_pgm_t *pgm, const sim_map_info_t *info);
void sim_map_destroy(sim_map_t *map);                   /* NULL is a no-op */

static inline int8_t sim_map_cell(const sim_map_t *m, int i, int j)
{
    if (i < 0 || j < 0 || i >= m->width || j >= m->height)
        return SIM_MAP_UNKNOWN;
    return m->cells[(size_t)j * m->width + i];
}

/* Map-frame centre of cell (i, j). */
void sim_map_cell_center(const sim_map_t *m, int i, int j, double *x, double *y);

/* Occupied cells merged into axis-aligned rectangles of cells (row runs, then identical runs
 * of consecutive rows stacked), so a straight wall becomes one box. */
typedef struct {
    int i, j;                   /* lower-left cell */
    int w, h;                   /* cells */
} sim_rect_t;
/* Returns the number of rectangles and sets *out (caller frees), or -ENOMEM. */
long sim_map_rects(const sim_map_t *m, sim_rect_t **out);

#ifdef __cplusplus
}
#endif
#endif
