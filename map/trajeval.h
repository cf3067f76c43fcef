/* trajeval: an estimated trajectory against a reference one: the absolute trajectory error after
 * the best rigid SE(2) alignment (ATE) and relation errors over stretches of a given length of
 * path (Kuemmerle et al. 2009). The measure behind `marie map eval` and the mapper's bench on
 * real logs (docs/mapping.md). */
#ifndef MARIE_MAP_TRAJEVAL_H
#define MARIE_MAP_TRAJEVAL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int64_t utime;
    double x, y, th;
} traj_pose_t;

#define TRAJEVAL_MAX_REL 4

typedef struct {
    double dist;                /* m of reference path a relation spans (at least) */
    size_t n;                   /* relations */
    double trans_mean, trans_max, rot_mean, rot_max;    /* m, rad */
} trajeval_rel_t;

typedef struct {
    size_t pairs;               /* estimated poses with a reference pose at their instant */
    double ate_rms, ate_max;    /* m, after the alignment */
    double align[3];            /* reference = align (+) estimate: x, y, theta */
    double path;                /* m of reference path over the pairs */
    int nrel;
    trajeval_rel_t rel[TRAJEVAL_MAX_REL];
} trajeval_t;

/* Pairs each estimated pose (time order) with the reference at its instant: a reference pose at
 * the same utime, else interpolated between the two around it when they are at most max_gap_us
 * apart. Writes the pairs to est_out/ref_out (room for n_est each); returns how many. */
size_t trajeval_pair(const traj_pose_t *est, size_t n_est, const traj_pose_t *ref, size_t n_ref, int64_t max_gap_us,
                     traj_pose_t *est_out, traj_pose_t *ref_out);

/* The figures over n paired poses, with relations over each of the ndist path lengths (at most
 * TRAJEVAL_MAX_REL). 0, or -1 with errno (EINVAL: fewer than 2 pairs, bad lengths; ENOMEM). */
int trajeval_run(const traj_pose_t *est, const traj_pose_t *ref, size_t n, const double *dists, int ndist,
                 trajeval_t *out);


#ifdef __cplusplus
}
#endif
#endif
