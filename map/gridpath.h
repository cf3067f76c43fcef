/* gridpath: shortest 8-connected path over a grid of passable cells (A*), the complete search
 * behind the planner's narrow passages and the evaluation's reference path length. */
#ifndef MAP_GRIDPATH_H
#define MAP_GRIDPATH_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Cells are y * w + x; pass[i] != 0 where the robot's centre may be. A diagonal step needs both
 * side cells passable, so the path never cuts a blocked corner. On success *cells (malloc'd,
 * start first) holds *n cells and the return is the path length in cells (1 per straight step,
 * sqrt 2 per diagonal); -1 with errno ENOENT when the goal cannot be reached, EINVAL for a
 * start or goal off the grid or blocked, ENOMEM. cells may be NULL when only the length is
 * wanted. */
double gridpath_find(int w, int h, const uint8_t *pass, int start, int goal, int **cells, int *n);

/* Drops the cells a straight line through passable cells makes redundant; returns the new count. */
int gridpath_shortcut(int w, int h, const uint8_t *pass, int *cells, int n);

#ifdef __cplusplus
}
#endif
#endif
