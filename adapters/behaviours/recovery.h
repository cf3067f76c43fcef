/* recovery: notices when the robot makes no progress along its path (two behaviours fighting,
 * an obstacle the planner does not know) and escalates: replan, back off, rotate, detour. */
#ifndef ADAPTERS_RECOVERY_H
#define ADAPTERS_RECOVERY_H

#include <stdbool.h>
#include <stdint.h>

#include "adapters/behaviours/arbiter.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double stuck_s;             /* s without min_progress along the path (0: off) */
    double min_progress;        /* m */
    double backoff_s, backoff_v;/* s, m/s (the laser sees only ahead: short and slow) */
    double rotate_s;            /* s at most turning to face the detour's target */
    double detour_s;            /* s at most driving to it under avoid, times the escalation level */
    double detour_ahead, detour_side;  /* m: the target, ahead towards the goal and to the side (times the level) */
    int max_level;              /* the detour grows up to this many times detour_s */
} rec_params_t;

void rec_params_default(rec_params_t *p);

enum { REC_NONE = 0, REC_REPLAN, REC_BACKOFF, REC_ROTATE, REC_DETOUR };

typedef struct {
    int32_t goal;               /* path goal being watched */
    double end[2];
    double best;                /* least path left to drive so far */
    double best_t;              /* when it did */
    int stage;
    double stage_end;
    int level;                  /* escalation: how many recoveries for this goal */
    double target[2];           /* where the detour heads: ahead along the way to the goal and
                                   off to the more open side, further at each level */
    int64_t recoveries;         /* all goals */
} rec_state_t;

void rec_state_reset(rec_state_t *s);

/* One cycle after arb_decide: `win` and votes[] are the arbitration's. Returns the stage in
 * force (REC_NONE: the arbitration's command stands); *v and *omega get the command then.
 * *replan is set on the cycle a recovery starts: ask the planner for a new path.
 * E-stop and teleop always win over a recovery, and avoid over its forward motion. */
int rec_step(const rec_params_t *p, rec_state_t *s, double now_s, const arb_params_t *ap, const arb_inputs_t *in,
             int win, const arb_vote_t votes[ARB_COUNT], double *v, double *omega, bool *replan);

const char *rec_stage_name(int stage);

#ifdef __cplusplus
}
#endif
#endif
