/* ssl_track: multi-source tracking of SRP-PHAT potential sources (see ssl_track.h). */
#include "adapters/ssl/ssl_track.h"

#include <math.h>
#include <string.h>

/* The filter and the birth rule: constants, not parameters. */
#define BIRTH_RATIO 0.0         /* a weaker peak than this times the frame's best starts no track
                                   (the array's sidelobes reach about 0.6 of their source) */
#define UPDATE_RATIO 0.0        /* nor does a peak weaker than this times the best update one */
#define BIRTH_HITS 3            /* sightings within BIRTH_WINDOW frames confirm a track */
#define BIRTH_WINDOW 8
#define MEAS_STD (3 * M_PI / 180)   /* rad, azimuth measurement noise */
#define ACCEL_STD 1.0           /* rad/s^2, how fast a source may change its angular rate */

void ssl_track_cfg_default(ssl_track_cfg_t *c)
{
    *c = (ssl_track_cfg_t)SSL_TRACK_CFG_DEFAULTS;
    c->dt = 0.016;
}

static double gate(const ssl_track_cfg_t *c)
{
    return c->gate_deg * M_PI / 180;
}

void ssl_tracker_init(ssl_tracker_t *k, const ssl_track_cfg_t *cfg)
{
    memset(k, 0, sizeof(*k));
    k->cfg = *cfg;
    k->next_id = 1;
}

double ssl_wrap(double a)
{
    a = fmod(a + M_PI, 2 * M_PI);
    if (a <= 0)
        a += 2 * M_PI;
    return a - M_PI;
}

static void predict(ssl_track_t *t, const ssl_track_cfg_t *c)
{
    double dt = c->dt, q = ACCEL_STD * ACCEL_STD;
    t->azimuth = ssl_wrap(t->azimuth + t->rate * dt);
    double p00 = t->P[0][0] + 2 * dt * t->P[0][1] + dt * dt * t->P[1][1] + q * dt * dt * dt * dt / 4;
    double p01 = t->P[0][1] + dt * t->P[1][1] + q * dt * dt * dt / 2;
    double p11 = t->P[1][1] + q * dt * dt;
    t->P[0][0] = p00;
    t->P[0][1] = t->P[1][0] = p01;
    t->P[1][1] = p11;
}

static void correct(ssl_track_t *t, const ssl_potential_t *o, const ssl_track_cfg_t *c, int64_t utime)
{
    double r = MEAS_STD * MEAS_STD, s = t->P[0][0] + r;
    double k0 = t->P[0][0] / s, k1 = t->P[1][0] / s, y = ssl_wrap(o->azimuth - t->azimuth);
    t->azimuth = ssl_wrap(t->azimuth + k0 * y);
    t->rate += k1 * y;
    double p00 = (1 - k0) * t->P[0][0], p01 = (1 - k0) * t->P[0][1], p11 = t->P[1][1] - k1 * t->P[0][1];
    t->P[0][0] = p00;
    t->P[0][1] = t->P[1][0] = p01;
    t->P[1][1] = p11;
    t->elevation += 0.2 * (o->elevation - t->elevation);
    t->energy = o->energy;
    t->hits++;
    t->misses = 0;
    t->seen = true;
    t->last_utime = utime;
}

static void spawn(ssl_tracker_t *k, const ssl_potential_t *o, int64_t utime)
{
    if (k->n == SSL_TRACK_MAX)
        return;
    ssl_track_t *t = &k->t[k->n++];
    memset(t, 0, sizeof(*t));
    t->azimuth = o->azimuth;
    t->elevation = o->elevation;
    t->energy = o->energy;
    t->P[0][0] = MEAS_STD * MEAS_STD;
    t->P[1][1] = 1.0;
    t->hits = 1;
    t->seen = true;
    t->first_utime = t->last_utime = utime;
}

/* Tracks that stay apart: two tracks on one source (after a crossing) keep the older. */
static void merge(ssl_tracker_t *k)
{
    for (int i = 0; i < k->n; i++)
        for (int j = i + 1; j < k->n; j++) {
            ssl_track_t *a = &k->t[i], *b = &k->t[j];
            if (fabs(ssl_wrap(a->azimuth - b->azimuth)) > gate(&k->cfg) / 2)
                continue;
            bool keep_a = a->confirmed != b->confirmed ? a->confirmed : a->first_utime <= b->first_utime;
            (keep_a ? b : a)->misses = 1 << 20;
        }
}

static void reap(ssl_tracker_t *k)
{
    int frames_dead = (int)ceil(k->cfg.death_s / k->cfg.dt);
    int w = 0;
    for (int i = 0; i < k->n; i++) {
        ssl_track_t *t = &k->t[i];
        bool dead = t->confirmed ? t->misses > frames_dead
                                 : (t->age >= BIRTH_WINDOW && t->hits < BIRTH_HITS) || t->misses > BIRTH_WINDOW;
        if (!dead)
            k->t[w++] = *t;
    }
    k->n = w;
}

void ssl_tracker_update(ssl_tracker_t *k, const ssl_potential_t *obs, int n, int64_t utime)
{
    bool used[SSL_TRACK_MAX * 2] = { false };
    if (n > SSL_TRACK_MAX * 2)
        n = SSL_TRACK_MAX * 2;
    for (int i = 0; i < k->n; i++) {
        predict(&k->t[i], &k->cfg);
        k->t[i].seen = false;
        k->t[i].age++;
    }
    /* Strongest observation first, each to the nearest free track inside the gate. */
    for (int o = 0; o < n; o++) {
        if (obs[o].energy < k->cfg.min_energy || obs[o].energy < UPDATE_RATIO * obs[0].energy)
            continue;
        /* The nearest track takes it; if that one already has this frame's observation, the
         * weaker one is its echo or sidelobe and must not pull a neighbour toward it. */
        int best = -1;
        double bd = gate(&k->cfg);
        for (int i = 0; i < k->n; i++) {
            double d = fabs(ssl_wrap(obs[o].azimuth - k->t[i].azimuth));
            if (d < bd) {
                bd = d;
                best = i;
            }
        }
        if (best >= 0 && k->t[best].seen) {
            used[o] = true;
            continue;
        }
        /* A tentative track grows only on a frame's strongest peak: the weaker ones are
         * often the array's sidelobes of that peak. */
        if (best >= 0 && (k->t[best].confirmed || (obs[o].energy >= k->cfg.birth_energy &&
                          (o == 0 || obs[o].energy >= BIRTH_RATIO * obs[0].energy)))) {
            correct(&k->t[best], &obs[o], &k->cfg, utime);
            used[o] = true;
        }
    }
    int nbefore = k->n;
    for (int o = 0; o < n; o++)
        if (!used[o] && obs[o].energy >= k->cfg.birth_energy &&
            (o == 0 || obs[o].energy >= BIRTH_RATIO * obs[0].energy))
            spawn(k, &obs[o], utime);
    for (int i = 0; i < nbefore; i++) {
        ssl_track_t *t = &k->t[i];
        if (!t->seen) {
            t->misses++;
            t->rate *= 0.95;    /* a silent source is more likely to stand than to keep turning */
        }
        t->activity += 0.1 * ((t->seen ? 1.0 : 0.0) - t->activity);
        if (!t->confirmed && t->hits >= BIRTH_HITS) {
            t->confirmed = true;
            t->id = k->next_id++;
        }
    }
    merge(k);
    reap(k);
}
