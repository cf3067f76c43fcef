/* livemap: a mapper's map as its readers hold it: the last full marie.occupancy_grid_t (MAP) with
 * the marie.occupancy_grid_update_t rectangles (MAP_UPDATE) sent since patched into it
 * (docs/mapping.md, "Map updates"). Used by every component that reads a live map. */
#ifndef MARIE_MAP_LIVEMAP_H
#define MARIE_MAP_LIVEMAP_H

#include <stdbool.h>
#include <stddef.h>

#include "core/component.h"
#include "lcmtypes/marie_occupancy_grid_t.h"
#include "lcmtypes/marie_occupancy_grid_update_t.h"
#include "map/occmap.h"

#ifdef __cplusplus
extern "C" {
#endif

#define LIVEMAP_MAX_CELLS (1 << 26)

typedef struct {
    marie_occupancy_grid_t map;     /* a copy; map.cells is owned (NULL: no map yet) */
} livemap_t;

/* A full map replaces the held one: 0, or -1 (nothing changed) with the reason in why when the
 * message contradicts itself (sizes, resolution, origin) or has more than LIVEMAP_MAX_CELLS. */
int livemap_full(livemap_t *lm, const marie_occupancy_grid_t *m, char *why, size_t why_len);
/* An update patched into the held map: 0; 1 when it belongs to another map than the one held
 * (or none is held yet: a reader that joined late waits for the next full map); -1 with the
 * reason in why when it contradicts itself or falls outside its map. */
int livemap_update(livemap_t *lm, const marie_occupancy_grid_update_t *u, char *why, size_t why_len);
/* The same for a component reading MAP and MAP_UPDATE: what is refused is c's bad input
 * (`bad_map`, `bad_map_update`), an update for another map counted `map_updates_unmatched`, one
 * patched in `map_updates`. True when the held map changed. */
bool livemap_take_full(livemap_t *lm, marie_component_t *c, const marie_occupancy_grid_t *m);
bool livemap_take_update(livemap_t *lm, marie_component_t *c, const marie_occupancy_grid_update_t *u);
/* The held map as an occmap (occmap_from_cells); NULL without a map or memory. */
occmap_t *livemap_occmap(const livemap_t *lm);
void livemap_free(livemap_t *lm);

#ifdef __cplusplus
}
#endif
#endif
