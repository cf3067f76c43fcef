/* recovery: notices when the robot makes no progress along its path (two behaviours fighting,
 * an obstacle the planner does not know) and escalates: replan, back off, rotate, detour. */
#ifndef ADAPTERS_RECOVERY_H
#define ADAPTERS_RECOVERY_H

#include <stdbool.h>
#include <stdint.h>

#include "adapters/behaviours/arbiter.h"
#include "adapters/behaviours/recovery_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/* rec_params_t: the parameters, declared in recovery.params.yaml; these are its defaults. */
void rec_params_default(rec_params_t *p);

enum { REC_NONE = 0, REC_REPLAN, REC_BACKOFF, REC_ROTATE, REC_DETOUR };

/* Returns of the recent scans near the robot, in the map frame: the laser sees only ahead, and
 * these are what a back-off must not drive into (a wall seen before the robot turned). */
#define REC_SEEN_MAX 512

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
    float seen[REC_SEEN_MAX][2];
    double seen_t[REC_SEEN_MAX];        /* when last seen; 0: empty */
    double last_scan_t;                 /* the scan last remembered */
    int64_t backoffs_cut;               /* back-offs stopped or skipped for what is behind */
} rec_state_t;

void rec_state_reset(rec_state_t *s);

/* One cycle after arb_decide: `win` and votes[] are the arbitration's. Returns the stage in
 * force (REC_NONE: the arbitration's command stands); *v and *omega get the command then.
 * *replan is set on the cycle a recovery starts: ask the planner for a new path.
 * E-stop and teleop always win over a recovery, and avoid over its forward motion. The back-off
 * stops (or is skipped) where a return seen within the last memory_s lies less than
 * backoff_clearance behind the footprint (ap->half_width to each side and behind). */
int rec_step(const rec_params_t *p, rec_state_t *s, double now_s, const arb_params_t *ap, const arb_inputs_t *in,
             int win, const arb_vote_t votes[ARB_COUNT], double *v, double *omega, bool *replan);

const char *rec_stage_name(int stage);

#ifdef __cplusplus
}
#endif
#endif
