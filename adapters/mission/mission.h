/* mission: a list of navigation goals with priorities and deadlines, scheduled one at a time
 * (the highest priority goal still reachable in time), with progress as events. */
#ifndef ADAPTERS_MISSION_H
#define ADAPTERS_MISSION_H

#include <stdbool.h>
#include <stdint.h>

#include "core/config.h"

#ifdef __cplusplus
extern "C" {
#endif

#define MISSION_MAX_GOALS 64

typedef enum { MISSION_PENDING = 0, MISSION_ACTIVE, MISSION_REACHED, MISSION_MISSED } mission_goal_state_t;

typedef struct {
    int32_t id;
    char name[48];
    double x, y, theta;
    double tolerance;           /* m */
    int32_t priority;           /* higher first */
    double deadline_s;          /* s after the mission's start; 0: none */
} mission_goal_t;

typedef struct {
    mission_goal_t goals[MISSION_MAX_GOALS];
    mission_goal_state_t state[MISSION_MAX_GOALS];
    int n;
    int current;                /* goal being pursued, -1: none */
    bool started, done;
    int64_t start_utime;
    int64_t reached, missed;
} mission_t;

/* Progress: kind is goal_started, goal_reached, goal_missed or mission_done. */
typedef void (*mission_event_fn)(void *user, const char *kind, const mission_goal_t *g, const char *text);

void mission_init(mission_t *m);
/* Parse a YAML sequence of goals: each a map with x, y and optional name, theta, priority,
 * deadline (s after start), tolerance, id. Adds "file:line:col: ..." to errs on bad input.
 * Returns the number of goals, or -1. */
int mission_parse(mission_t *m, const marie_node_t *seq, double default_tolerance, marie_errors_t *errs);
/* The options a goal entry may give (id, priority, deadline, tolerance, name) into o; errors
 * with file:line go to errs. */
void mission_goal_options(const marie_node_t *g, mission_goal_t *o, marie_errors_t *errs);
/* Advance the mission at time now, given the robot's pose (NULL when unknown): start, declare
 * the current goal reached or missed, skip goals whose deadline has passed, pick the next. */
void mission_update(mission_t *m, int64_t now, const double *pose, mission_event_fn ev, void *user);
/* Continue a mission from saved progress: the goal ids must match this mission's list.
 * 0, or -1 (then nothing changed). */
int mission_restore(mission_t *m, int64_t start_utime, int current, const int32_t *ids, const int8_t *states, int n);
/* The current goal cannot be reached (no path): mark it missed now. */
void mission_give_up(mission_t *m, const char *why, mission_event_fn ev, void *user);
/* Deadline of goal i in absolute time (0: none). */
int64_t mission_deadline(const mission_t *m, int i);

#ifdef __cplusplus
}
#endif
#endif
