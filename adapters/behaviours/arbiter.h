/* arbiter: the robot's behaviours (e-stop, avoid, teleop, relocalize, face the speaker, follow path,
 * idle) and their priority arbitration, as pure functions of the inputs of one cycle. */
#ifndef ADAPTERS_ARBITER_H
#define ADAPTERS_ARBITER_H

#include <stdbool.h>
#include <stdint.h>

#include "adapters/behaviours/arbiter_params.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { ARB_ESTOP = 0, ARB_AVOID, ARB_TELEOP, ARB_RELOC, ARB_FACE, ARB_FOLLOW, ARB_IDLE, ARB_COUNT };

/* arb_params_t: the parameters, declared in arbiter.params.yaml; these are its defaults. */
void arb_params_default(arb_params_t *p);

/* Inputs of one cycle. Ages in seconds at decision time; negative: never received. */
typedef struct {
    double pose[3]; double pose_age;
    const double *path; int npath; int path_status; int32_t path_goal; double path_age;  /* path: x,y,theta triples */
    const float *ranges; int nranges; double angle_min, angle_increment, range_min, range_max; double scan_age;
    bool estop_pressed; double estop_age;
    double teleop_v, teleop_omega; double teleop_age;
    double reloc_v, reloc_omega; double reloc_age;          /* the lost localizer's search motion */
    double face_heading; int32_t face_id; double face_age;   /* map-frame heading toward the last speaker; id 0: none */
} arb_inputs_t;

typedef struct {
    const char *name;
    int priority;
    bool active;
    double v, omega;
    bool aside;                 /* avoid: what stops the robot is off to one side, and it turns away */
    char reason[64];
} arb_vote_t;

/* State carried across cycles: progress along the current path. */
typedef struct {
    int32_t path_goal;
    int npath;
    double path_end[2];
    int progress;               /* index of the path pose the robot has reached */
    bool done;                  /* current path finished */
    int32_t face_done;          /* face_id of the last speaker turned to */
} arb_state_t;

void arb_state_reset(arb_state_t *s);

/* Every behaviour votes; the active vote of highest priority wins (ties: lower index),
 * except that avoid does not override a turn in place. Returns the winner's index; votes[]
 * gets every vote. */
int arb_decide(const arb_params_t *p, arb_state_t *s, const arb_inputs_t *in, arb_vote_t votes[ARB_COUNT]);


/* The behaviours one by one (arb_decide calls these). */
void arb_follow(const arb_params_t *p, arb_state_t *s, const arb_inputs_t *in, arb_vote_t *out);

#ifdef __cplusplus
}
#endif
#endif
