/* ssl_track: multi-source tracking of SRP-PHAT potential sources: one Kalman filter per
 * source on azimuth and its rate, greedy gated association, track birth after repeated
 * sightings and death after a silence. */
#ifndef MARIE_SSL_TRACK_H
#define MARIE_SSL_TRACK_H
#include <stdbool.h>
#include <stdint.h>

#include "adapters/ssl/ssl_srp.h"
#include "adapters/ssl/ssl_track_params.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SSL_TRACK_MAX 8

/* ssl_track_cfg_t (ssl_track.params.yaml): min_energy (an observation weaker than this is noise),
 * birth_energy (a new or tentative track grows only on peaks this strong), gate_deg (an observation
 * this close may update a track), death_s (a confirmed track unseen this long dies), and dt, the s
 * between frames. */
void ssl_track_cfg_default(ssl_track_cfg_t *c);     /* dt: 0.016 s */

typedef struct {
    int id;                     /* > 0 once confirmed, 0 while tentative */
    bool confirmed;
    double azimuth, rate;       /* rad, rad/s */
    double elevation;
    double P[2][2];
    double energy, activity;
    int hits, age, misses;      /* frames */
    bool seen;                  /* updated in the last frame */
    int64_t first_utime, last_utime;
} ssl_track_t;

typedef struct {
    ssl_track_cfg_t cfg;
    ssl_track_t t[SSL_TRACK_MAX];
    int n;
    int next_id;
} ssl_tracker_t;

void ssl_tracker_init(ssl_tracker_t *k, const ssl_track_cfg_t *cfg);

/* One frame's potential sources (best first). */
void ssl_tracker_update(ssl_tracker_t *k, const ssl_potential_t *obs, int n, int64_t utime);

/* Wraps to (-pi, pi]. */
double ssl_wrap(double a);

#ifdef __cplusplus
}
#endif
#endif
