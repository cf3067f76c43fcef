/* ssl_track: multi-source tracking of SRP-PHAT potential sources: one Kalman filter per
 * source on azimuth and its rate, greedy gated association, track birth after repeated
 * sightings and death after a silence. */
#ifndef MARIE_SSL_TRACK_H
#define MARIE_SSL_TRACK_H
#include <stdbool.h>
#include <stdint.h>

#include "adapters/ssl/ssl_srp.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SSL_TRACK_MAX 8

typedef struct {
    double dt;                  /* s between frames */
    double min_energy;          /* an observation weaker than this is noise */
    double birth_ratio;         /* a weaker peak than this times the frame's best starts no track:
                                   the array's sidelobes reach about 0.6 of their source */
    double birth_energy;        /* a new or tentative track grows only on peaks this strong */
    double update_ratio;        /* nor does a peak weaker than this times the best update one */
    double gate;                /* rad: an observation this close may update a track */
    int birth_hits;             /* sightings within birth_window frames to confirm a track */
    int birth_window;
    double death_s;             /* a confirmed track unseen this long dies */
    double meas_std;            /* rad, azimuth measurement noise */
    double accel_std;           /* rad/s^2, how fast a source may change its angular rate */
} ssl_track_cfg_t;

void ssl_track_cfg_default(ssl_track_cfg_t *c);

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
