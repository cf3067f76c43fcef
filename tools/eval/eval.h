/* eval: marie-eval's parts: the worlds and what is done to them (eval_world.c), one world's run
 * (eval_run.c), the command line and the table (eval_main.c). */
#ifndef TOOLS_EVAL_EVAL_H
#define TOOLS_EVAL_EVAL_H

#include <stdbool.h>
#include <stdint.h>

#include "map/occmap.h"

/* A world to drive in: a map_server map and the robot that drives there. */
typedef struct {
    char name[64];              /* the table's row */
    char yaml[1024];
    double radius, clearance, track, wheel;
} eval_world_t;

typedef struct {
    const char *bin, *out;
    int64_t goals, boxes, walls, kidnap;
    double coarse, speed, tolerance;
    int64_t seed;
    bool tsv;
    char tag[64];               /* what was done to the worlds: "+boxes6+kidnap3" */
} eval_opts_t;

typedef struct {
    int tried, reached;
    double *time_s, *ratio;     /* per reached goal; ratio: those not carried away */
    int nres, nratio;
    double rms;
    int64_t collisions, recoveries, lost, found, asked, refused, kidnapped;
} eval_result_t;

/* One run's ground: the world the simulator runs (the map plus what the map lacks) and the map
 * the robot is given (the user's, or a coarser copy), with where a robot fits in each, measured
 * as the planner measures it (map/clearance.h). */
typedef struct {
    occmap_t *world, *map;
    uint8_t *map_pass, *map_goal;   /* the planner's inflation; goals keep 5 cm more */
    uint8_t *world_pass, *world_goal;
    char world_yaml[1100], map_yaml[1100];
    double start[3];
} eval_site_t;

/* Loads w's map, draws what o asks into a copy for the simulator (written into dir when it
 * differs), picks a start free in both. 0, or -1 with the reason on stderr. */
int eval_site_make(eval_site_t *s, const eval_world_t *w, const eval_opts_t *o, const char *dir);
void eval_site_free(eval_site_t *s);

/* A goal at least 2 m from `from` that the planner accepts on the map and that the robot can
 * really reach in the world: its shortest collision-free length in the world (the A* path on the
 * inflated world grid, straightened), or -1 when none was found. */
double eval_pick_goal(const eval_site_t *s, const double from[2], double goal[2]);
/* Where to carry a kidnapped robot: a spot at least 3 m from `from`, free in both, any heading,
 * from which the goal can be reached in the world: the shortest length from there, or -1 when
 * none was found. */
double eval_pick_kidnap(const eval_site_t *s, const double from[2], const double goal[2], double pose[3]);

/* The same seed gives the same worlds, starts and goals. */
void eval_rng_seed(uint64_t seed);

/* Drives o->goals goals in w; r gets the counts (free r->time_s and r->ratio). 0, or -1 when the
 * run could not start. SIGTERM or SIGINT meanwhile ends it (its programs stopped) and makes
 * eval_stopped() true. */
int eval_run(const eval_opts_t *o, const eval_world_t *w, eval_result_t *r);
bool eval_stopped(void);

#endif
