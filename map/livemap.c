/* livemap: full maps and the rectangles that changed since, as a reader holds them. */
#include "map/livemap.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"
#include "core/log.h"

int livemap_full(livemap_t *lm, const marie_occupancy_grid_t *m, char *why, size_t why_len)
{
    int64_t n = (int64_t)m->width * m->height;
    if (m->width <= 0 || m->height <= 0 || n != m->ncells || n > LIVEMAP_MAX_CELLS || !(m->resolution > 0) ||
        !isfinite(m->resolution) || !isfinite(m->origin.x) || !isfinite(m->origin.y) || !isfinite(m->origin.theta))
        return marie_fail_why(why, why_len, "map %dx%d with %d cells, resolution %g", m->width, m->height,
                              m->ncells, m->resolution);
    int8_t *cells = malloc((size_t)n);
    if (!cells) {
        snprintf(why, why_len, "no memory for a %dx%d map", m->width, m->height);
        return marie_fail(ENOMEM);
    }
    memcpy(cells, m->cells, (size_t)n);
    free(lm->map.cells);
    lm->map = *m;
    lm->map.cells = cells;
    return 0;
}

int livemap_update(livemap_t *lm, const marie_occupancy_grid_update_t *u, char *why, size_t why_len)
{
    if (u->width <= 0 || u->height <= 0 || (int64_t)u->width * u->height != u->ncells || u->x < 0 || u->y < 0)
        return marie_fail_why(why, why_len, "map update %dx%d at (%d, %d) with %d cells", u->width, u->height,
                              u->x, u->y, u->ncells);
    const marie_occupancy_grid_t *m = &lm->map;
    if (!m->cells || u->map_utime != m->utime)
        return 1;
    if ((int64_t)u->x + u->width > m->width || (int64_t)u->y + u->height > m->height)
        return marie_fail_why(why, why_len, "map update %dx%d at (%d, %d) outside its %dx%d map", u->width,
                              u->height, u->x, u->y, m->width, m->height);
    for (int r = 0; r < u->height; r++)
        memcpy(m->cells + (size_t)(u->y + r) * m->width + u->x, u->cells + (size_t)r * u->width, (size_t)u->width);
    return 0;
}

bool livemap_take_full(livemap_t *lm, marie_component_t *c, const marie_occupancy_grid_t *m)
{
    char why[128];
    if (livemap_full(lm, m, why, sizeof why) == 0)
        return true;
    marie_component_bad_input(c, "bad_map", "%s", why);
    return false;
}

bool livemap_take_update(livemap_t *lm, marie_component_t *c, const marie_occupancy_grid_update_t *u)
{
    char why[128];
    int r = livemap_update(lm, u, why, sizeof why);
    if (r < 0)
        marie_component_bad_input(c, "bad_map_update", "%s", why);
    else if (r > 0)
        marie_component_count(c, "map_updates_unmatched", 1);      /* the next whole map comes */
    else
        marie_component_count(c, "map_updates", 1);
    return r == 0;
}

occmap_t *livemap_occmap(const livemap_t *lm)
{
    const marie_occupancy_grid_t *m = &lm->map;
    if (!m->cells)
        return NULL;
    return occmap_from_cells(m->width, m->height, m->resolution, m->origin.x, m->origin.y, m->origin.theta, m->cells);
}

void livemap_free(livemap_t *lm)
{
    free(lm->map.cells);
    memset(lm, 0, sizeof(*lm));
}
