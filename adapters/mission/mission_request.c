/* mission_request: a goal a person asked for joins the mission ahead of the others. */
#include "adapters/mission/mission_request.h"

#include <errno.h>

#include "core/err.h"

int mission_request_insert(mission_t *m, const mission_goal_t *g)
{
    int slot = -1;
    int32_t top = g->priority;
    for (int i = 0; i < m->n; i++) {
        if (m->goals[i].id == g->id && (m->state[i] == MISSION_PENDING || m->state[i] == MISSION_ACTIVE))
            slot = i;
        if (m->goals[i].priority >= top)
            top = m->goals[i].priority + 1;
    }
    if (slot < 0) {
        if (m->n >= MISSION_MAX_GOALS)
            return marie_fail(ENOSPC);
        slot = m->n++;
    }
    if (m->current >= 0 && m->current != slot)
        m->state[m->current] = MISSION_PENDING;
    m->current = -1;
    m->goals[slot] = *g;
    m->goals[slot].priority = top;
    m->goals[slot].deadline_s = 0;
    m->state[slot] = MISSION_PENDING;
    m->done = false;
    return 0;
}
