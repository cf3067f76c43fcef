/* walls: the cells of a map that are not known free merged into rectangles, one physics box each. */
#ifndef SIM_WALLS_H
#define SIM_WALLS_H

#include "map/occmap.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The cells that are not known free (occupied, unknown, map_server's in-between values) merged
 * into axis-aligned rectangles of cells (row runs, then identical runs of consecutive rows
 * stacked), so a straight wall becomes one box. */
typedef struct {
    int i, j;                   /* lower-left cell */
    int w, h;                   /* cells */
} sim_rect_t;
/* Returns the number of rectangles and sets *out (caller frees), or -1 with errno ENOMEM. */
long sim_walls_rects(const occmap_t *m, sim_rect_t **out);

#ifdef __cplusplus
}
#endif
#endif
