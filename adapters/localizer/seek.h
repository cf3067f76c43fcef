/* seek: what a lost robot does to find itself again. It turns on the spot to see all around,
 * searches the whole map for where the points it saw fit (reloc.h), and takes the best place only
 * when it fits clearly better than any other and contradicts no wall; otherwise it drives a few
 * metres towards the most open side and turns again: a place found from both spots (the drive
 * between them known from odometry) adds up its evidence, so look-alike places part as soon as
 * one spot tells them apart. After `attempts` places it stops and asks for a pose. Pure: scans
 * and odometry in, commands and verdicts out. */
#ifndef ADAPTERS_LOCALIZER_SEEK_H
#define ADAPTERS_LOCALIZER_SEEK_H

#include <stdbool.h>

#include "adapters/localizer/mcl.h"
#include "adapters/localizer/reloc.h"
#include "adapters/localizer/seek_params.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { SEEK_OFF = 0, SEEK_TURN, SEEK_FACE, SEEK_DRIVE, SEEK_VERIFY, SEEK_ASK } seek_phase_t;

typedef enum {
    SEEK_NOTHING = 0,
    SEEK_SEARCHED,      /* a search ran: out->found, out->best, out->second say what it gave */
    SEEK_FOUND,         /* verified: the filter tracks the robot at out->best's pose now */
    SEEK_GAVE_UP,       /* out->why: it stands still and waits for a pose */
} seek_event_t;

typedef struct {
    seek_event_t event;
    bool move;                  /* a command for the wheels this scan */
    double v, omega;
    bool update_filter;         /* verifying: the caller steps the filter with this scan (forced) */
    int nhyp;                   /* hypotheses of the last search */
    reloc_hyp_t best, second;   /* the frame's origin; best_now: the robot's pose now */
    double best_total, second_total;    /* their evidence over the turns */
    double best_now[3];
    char why[160];
} seek_out_t;

#define SEEK_HYPS 8

typedef struct {
    seek_params_t p;
    seek_phase_t phase;
    reloc_cloud_t *cloud;
    double mount[3];            /* the laser on the robot */
    double last_odom[3];
    double turned;              /* rad turned in this turn */
    int turn_dir;
    double face;                /* odometry heading to face before driving */
    double drive_from[2];
    double phase_s;             /* when the phase began */
    int attempts, verified, doubts;
    int64_t searches;           /* since the robot was lost */
    /* The last search's places (the origin of its turn's frame) and the evidence each has
     * gathered over the turns so far: a place seen from several spots sums its scores. */
    double origin_odom[3];      /* odometry pose where this turn's frame began */
    double prev_odom[3];
    reloc_hyp_t prev[SEEK_HYPS];
    double prev_total[SEEK_HYPS];
    int nprev;
} seek_t;

/* 0, or -1 with errno ENOMEM. seek_free() lets go of what seek_init() made. */
int seek_init(seek_t *s, const seek_params_t *p, const double laser_mount[3]);
void seek_free(seek_t *s);

/* Lost at odometry pose odom: start over (turning, nothing seen yet). */
void seek_begin(seek_t *s, const double odom[3], double now_s);
/* Stop seeking (a pose was given). */
void seek_end(seek_t *s);
bool seek_active(const seek_t *s);

/* One scan at odometry pose odom. Searches run in this call when a turn is complete; on a
 * clear answer the filter is set there (mcl_init_pose) and verified by the caller's updates. */
void seek_step(seek_t *s, mcl_t *f, const double odom[3], const mcl_scan_t *scan, double now_s, seek_out_t *out);

/* What the robot does now, for the heartbeat: "turning on the spot", ... */
const char *seek_doing(const seek_t *s);

#ifdef __cplusplus
}
#endif
#endif
