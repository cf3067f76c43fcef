/* mapeval: a built map against the ground-truth world, both in the same frame: precision and
 * recall of occupied cells within one cell, coverage of the reachable free space. The measure
 * behind `marie map compare`, the mapper's tests and the explore demo (docs/mapping.md). */
#ifndef MARIE_MAP_MAPEVAL_H
#define MARIE_MAP_MAPEVAL_H

#include "map/occmap.h"

typedef struct {
    double precision, recall, coverage;
    long map_occupied, truth_walls, truth_free;
} mapeval_t;

/* Precision: built occupied cells with a true wall within one cell. Recall: true wall cells
 * the robot could see (a 4-neighbour is free in the truth and in the built map) with a built
 * occupied cell within one cell. Coverage: free cells reachable from (sx, sy) in the truth that
 * the built map knows free. */
void mapeval_compare(const occmap_t *truth, const occmap_t *map, double sx, double sy, mapeval_t *e);

/* The rigid transform (rotation th about the map frame's origin, then dx, dy) within +-max_xy m
 * and +-max_th rad that puts the most built occupied cells within one cell of a true wall: the
 * "aligned" of the comparison. Returns the aligned copy of map (free it), NULL on failure. */
occmap_t *mapeval_align(const occmap_t *truth, const occmap_t *map, double max_xy, double max_th, double *odx,
                        double *ody, double *oth);

/* The whole judgement `marie map compare` prints: as built, and aligned within 0.5 m and
 * 0.03 rad (compared at that transform, the built map not resampled). -1 when out of memory (the aligned figures are then zero). */
typedef struct {
    mapeval_t raw, aligned;
    double dx, dy, th;          /* the alignment */
} mapeval_judgement_t;
int mapeval_judge(const occmap_t *truth, const occmap_t *map, double sx, double sy, mapeval_judgement_t *j);

#endif
