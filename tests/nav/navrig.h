/* navrig: the navigation stack as plain processes on the simulator's clock over real LCM, for
 * tests: start the programs with their parameters, watch the truth, the poses, the localizer's
 * heartbeat and everyone's events, drive the robot or send it a goal. */
#ifndef TESTS_NAV_NAVRIG_H
#define TESTS_NAV_NAVRIG_H

#include <stdbool.h>
#include <stdint.h>
#include <sys/types.h>

#include <lcm/lcm.h>

#define RIG_MAX_PROGS 6

typedef struct {
    lcm_t *lcm;
    pid_t pids[RIG_MAX_PROGS];
    int nprogs;
    char dir[256];              /* logs: DIR/NAME.log */
    int64_t sim_us;             /* newest simulated time */
    double truth[3], pose[3];
    int64_t pose_utime, npose;
    int loc_state;              /* the localizer's heartbeat state, -1 before */
    char loc_reason[256];
    int64_t lost, found, asked, collisions;     /* counters */
    int64_t degraded_at, running_again_at;      /* sim us; 0: not seen */
    int64_t found_at, asked_at;                 /* sim us of the relocalized / relocalization_failed events */
    double found_pose[3];                       /* the pose the localizer published first after being found */
    bool watch_found;
    double turned;              /* rad the true heading turned, in all */
    char events[64][200];       /* "source kind text", the latest 64 */
    int nevents;
} rig_t;

/* The rig (one at a time), its bus open; logs go to $B/test-logs/NAME (made afresh). It is closed
 * by rig_teardown(), a cmocka teardown: a failed check leaves no program running. */
rig_t *rig_open(const char *name);
/* Starts $B/bin/marie-PROG --name PROG [--clock sim unless it is the simulator] and the given
 * "key=value" parameters (NULL-terminated). */
void rig_start(rig_t *r, const char *prog, ...) __attribute__((sentinel));
/* The localizer on MAP started at (x, y, th), its resume file ignored. */
void rig_start_localizer(rig_t *r, const char *map, double x, double y, double th);
/* marie-sim in WORLD (a name under sim/worlds) from (x, y, th) at SPEED ("speed=N"; NULL: 4x),
 * and the odometry. */
void rig_start_sim(rig_t *r, const char *world, double x, double y, double th, const char *speed);
void rig_close(rig_t *r);
int rig_teardown(void **state);

/* Handles traffic for `sim_s` simulated seconds (bounded in wall time: sim_s / 2 + 10 s), sending
 * v, omega on MOTOR_COMMAND at 20 Hz unless `drive` is false; stops early when done(r) holds. */
void rig_run(rig_t *r, double sim_s, bool drive, double v, double omega, int (*done)(const rig_t *));
/* A goal for the planner (repeated every second by rig_run while `goal_id` > 0). */
void rig_goal(rig_t *r, int id, double x, double y);
/* Carries the robot (SIM_TELEPORT). */
void rig_teleport(rig_t *r, double x, double y, double theta);
/* The pose error now, m. */
double rig_error(const rig_t *r);
/* Whether an event of this kind (from any source) was seen. */
bool rig_event(const rig_t *r, const char *kind);

#endif
