/* planner: path planning (A* on the grid, or OMPL sampling) on an occupancy map inflated by the
 * robot radius, with a layer of obstacles seen by the laser that are not in the map. */
#ifndef ADAPTERS_PLANNER_H
#define ADAPTERS_PLANNER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "adapters/planner/planner_params.h"
#include "map/occmap.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct planner planner_t;

/* RRTConnect and PRM sample (OMPL); GRID searches the inflated grid with A* and shortcuts the
 * cells by line of sight (map/gridpath.h): the shortest path on the grid, every time. */
typedef enum { PLANNER_RRTCONNECT = 0, PLANNER_PRM, PLANNER_GRID } planner_algo_t;

/* planner_params_t: the parameters, declared in planner.params.yaml; these are its defaults.
 * Its algorithm is one of the names planner_algorithm() knows. */
void planner_params_default(planner_params_t *p);

/* The algorithm called grid, rrtconnect or prm; -1 with errno EINVAL for any other name. */
int planner_algorithm(const char *name);

/* NULL on failure (errno). planner_destroy(NULL) is a no-op. The map is copied. */
planner_t *planner_create(const occmap_t *map, const planner_params_t *p, uint64_t seed);
void planner_destroy(planner_t *pl);

/* Whether the robot fits at a map-frame point (inflated map plus the obstacle layer). */
bool planner_free(const planner_t *pl, double x, double y);

/* Plan from start to goal (x, y, theta). On success returns 0 and *poses (x,y,theta triples,
 * malloc'ed, the caller frees) with *n >= 2; the last pose is the goal. -1 with errno EINVAL when the
 * start or goal is not free (either is first moved to the nearest free cell within a robot
 * radius; planner_blocked() says which), -1 with errno ENOENT when no path was found in time. */
int planner_plan(planner_t *pl, const double start[3], const double goal[3], double **poses, int *n);

/* Which ends planner_plan() refuses: PLANNER_START_BLOCKED, PLANNER_GOAL_BLOCKED or both; 0 when
 * neither; with PLANNER_BY_LASER when every end refused is free on the map and only the laser's
 * obstacles cover it. For each blocked end its reason goes to why (NULL: not wanted): "inside a
 * wall", "0.12 m from a wall (the robot needs 0.40 m)", "in unknown space", "off the map", "in
 * an obstacle seen by the laser". */
enum { PLANNER_START_BLOCKED = 1, PLANNER_GOAL_BLOCKED = 2, PLANNER_BY_LASER = 4 };
int planner_blocked(const planner_t *pl, const double start[3], const double goal[3], char *why, size_t why_len);

/* Add laser returns (map-frame points at time now_s) that are not explained by the map to the
 * obstacle layer; points older than obstacle_ttl are forgotten. Returns how many were new. */
int planner_add_obstacles(planner_t *pl, const double *xy, int npoints, double now_s);
void planner_clear_obstacles(planner_t *pl);
int planner_obstacle_count(const planner_t *pl);

/* First index i >= from such that the segment poses[i]..poses[i+1] is not free, checked
 * along at most horizon m from the point nearest to (x, y); -1 when the path is clear. */
int planner_path_blocked(const planner_t *pl, const double *poses, int n, double x, double y, double horizon);

/* First segment of the path along which the robot's footprint circle (robot_radius, without
 * the clearance) would touch an obstacle of this planner's map, checked every half cell; -1
 * when it is clear. Used when the map changes under a planned path. */
int planner_path_collides(const planner_t *pl, const double *poses, int n);

#ifdef __cplusplus
}
#endif
#endif
