/* mission_request: a goal a person asked for joins the mission ahead of the others. */
#ifndef ADAPTERS_MISSION_REQUEST_H
#define ADAPTERS_MISSION_REQUEST_H

#include "adapters/mission/mission.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Adds g (its priority raised above every goal of the list) and sets the current goal back to
 * pending, so the next mission_update() starts the request; a finished mission starts again.
 * A goal with g's id already in the list is replaced if pending or active. 0, or -1 with
 * errno ENOSPC when the list is full. */
int mission_request_insert(mission_t *m, const mission_goal_t *g);

#ifdef __cplusplus
}
#endif
#endif
