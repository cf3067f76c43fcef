/* map_tool: the pieces of marie-map (tools/map): `eval`, and the picture it draws. */
#ifndef TOOLS_MAP_MAP_TOOL_H
#define TOOLS_MAP_MAP_TOOL_H

#include <stddef.h>

#include "map/occmap.h"
#include "map/trajeval.h"

#ifdef __cplusplus
extern "C" {
#endif

/* `marie map eval RUN.lcm [...]`: argv[0] is "eval". An exit status (proto/am_proto.h). */
int map_eval_main(int argc, char **argv);

/* The map (map_saver's grey levels: occupied black, free white, unknown grey) with the estimate
 * (red) and the reference (green) over it, n poses each, the reference brought into the map's
 * frame by the inverse of `align` (reference = align (+) estimate); written as PNG. 0 or -1. */
int map_picture_write(const char *path, const occmap_t *m, const traj_pose_t *est, const traj_pose_t *ref, size_t n,
                      const double align[3]);

#ifdef __cplusplus
}
#endif
#endif
