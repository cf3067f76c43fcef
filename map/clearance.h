/* clearance: how far each cell of a map lies from what blocks a robot, and where a robot of a given
 * radius fits. One definition for the planner's inflation and marie-eval's starts and goals. */
#ifndef MAP_CLEARANCE_H
#define MAP_CLEARANCE_H

#include <stdbool.h>
#include <stdint.h>

#include "map/occmap.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The distance in m from each cell's centre to the nearest blocked cell's edge (the exact
 * Euclidean distance between the two centres less half a cell; -resolution/2 in a blocked
 * cell): occupied cells block, and so do unknown ones (and 1..99, neither free nor occupied)
 * unless unknown_is_free. A map with nothing blocked gives (width + height) * resolution
 * everywhere. Returns width*height floats, malloc'd, the caller frees; NULL with errno ENOMEM. */
float *occmap_clearance(const occmap_t *m, bool unknown_is_free);

/* 1 where a robot centred on the cell keeps `radius` clear (clearance > radius), else 0:
 * width*height bytes, malloc'd, the caller frees; NULL with errno ENOMEM. */
uint8_t *occmap_passable(const occmap_t *m, double radius, bool unknown_is_free);

#ifdef __cplusplus
}
#endif
#endif
