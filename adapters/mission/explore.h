/* explore: frontier-based exploration on an occupancy grid: the frontiers (known free cells next
 * to unknown ones) the robot can reach, grouped, and ranked by travel cost and size. */
#ifndef ADAPTERS_MISSION_EXPLORE_H
#define ADAPTERS_MISSION_EXPLORE_H

#include "adapters/mission/explore_params.h"
#include "map/occmap.h"

#ifdef __cplusplus
extern "C" {
#endif

/* explore_params_t (robot_radius, escape_radius, info_weight, min_cells, blacklist_radius) is
 * generated from explore.params.yaml. */

typedef struct {
    double x, y;                /* goal: the frontier's reachable cell nearest its centroid */
    int cells;                  /* frontier length in cells */
    double path_m;              /* travel along free cells from the robot */
    double cost;
} explore_frontier_t;

/* The defaults of explore.params.yaml. */
void explore_params_default(explore_params_t *p);

/* Frontiers of m reachable from (rx, ry), cheapest first, at most max of them in out. Cells are
 * read as map_server does: 0..19 free, 65..100 occupied, anything else unknown. blacklist holds
 * nblack (x, y) pairs. The number found (0: nothing left to explore), or -1 with errno (EINVAL,
 * ENOMEM). */
int explore_frontiers(const occmap_t *m, const explore_params_t *p, double rx, double ry, const double *blacklist,
                      int nblack, explore_frontier_t *out, int max);

/* The way from (rx, ry) to (gx, gy) over the cells explore_frontiers() counts as passable, as
 * up to max (x, y) pairs in xy, robot first; the number of points, or -1 with errno ENOENT when
 * the goal cannot be reached. */
int explore_path(const occmap_t *m, const explore_params_t *p, double rx, double ry, double gx, double gy, double *xy,
                 int max);

#ifdef __cplusplus
}
#endif
#endif
