/* mission_signs: goals given by what a sign says ("the room whose sign says B"): the robot
 * searches along given points until the vision adapter reads the sign, then goes to it. */
#ifndef ADAPTERS_MISSION_SIGNS_H
#define ADAPTERS_MISSION_SIGNS_H

#include <stdbool.h>

#include "adapters/mission/mission.h"
#include "core/config.h"

#ifdef __cplusplus
extern "C" {
#endif

#define MISSION_SIGN_SEARCH_MAX 16

typedef struct {
    int goal;                   /* index in the mission's goals */
    char message[64];           /* the text the sign stands for (marie-vision's `messages`) */
    double approach;            /* m in front of the sign where the goal lies */
    double search[MISSION_SIGN_SEARCH_MAX][2];
    int nsearch, next;          /* search points, the one being driven to */
    bool read;                  /* the sign was read: the goal is in front of it */
} mission_sign_t;

typedef struct {
    mission_sign_t s[MISSION_MAX_GOALS];
    int n;
} mission_signs_t;

/* Reads a list of {message, search: [[x, y], ...], approach (1.0 m), name, priority, deadline,
 * tolerance, id} and appends one goal per entry to m, placed at its first search point.
 * NULL or an empty list: none. Returns how many, or -1 with "file:line:col: ..." in errs. */
int mission_signs_parse(mission_signs_t *ss, mission_t *m, const marie_node_t *seq, double default_tol,
                        marie_errors_t *errs);
/* A landmark whose message is `message` seen at (x, y) facing yaw, `range` m away: the goals waiting for it
 * move in front of it (approach m out, facing the sign). Returns how many goals moved. */
int mission_signs_read(mission_signs_t *ss, mission_t *m, const char *message, double x, double y, double yaw,
                       double range, mission_event_fn ev, void *user);
/* Before mission_update(): a current sign goal not read yet must not be "reached" at a search
 * point; when the robot is there, the goal moves to the next point, and after the last one
 * the goal is given up. Returns 1 when the current goal moved or ended, else 0. */
int mission_signs_steer(mission_signs_t *ss, mission_t *m, const double *pose, mission_event_fn ev, void *user);

#ifdef __cplusplus
}
#endif
#endif
