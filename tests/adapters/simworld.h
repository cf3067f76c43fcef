/* simworld: a tiny kinematic robot with noisy odometry and a ray-cast laser, for adapter tests. */
#ifndef TESTS_ADAPTERS_SIMWORLD_H
#define TESTS_ADAPTERS_SIMWORLD_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "map/occmap.h"

typedef struct {
    uint64_t s;
} simrng_t;

static inline double sim_uniform(simrng_t *r)
{
    r->s ^= r->s << 13; r->s ^= r->s >> 7; r->s ^= r->s << 17;
    return (r->s >> 11) * (1.0 / 9007199254740992.0);
}

static inline double sim_gauss(simrng_t *r, double sigma)
{
    double u = sim_uniform(r), v = sim_uniform(r);
    if (u < 1e-12) u = 1e-12;
    return sigma * sqrt(-2 * log(u)) * cos(2 * M_PI * v);
}

typedef struct {
    double truth[3];            /* true pose */
    double odom[3];             /* dead-reckoned pose (drifts) */
    double v_scale, gyro_bias;  /* systematic odometry errors */
    double v_noise, w_noise;    /* per-step noise */
    simrng_t rng;
} simrobot_t;

/* Advance by dt with body velocities v, w; odometry sees a distorted version. */
static inline void sim_move(simrobot_t *r, const occmap_t *m, double v, double w, double dt)
{
    double nx = r->truth[0] + v * dt * cos(r->truth[2] + w * dt / 2);
    double ny = r->truth[1] + v * dt * sin(r->truth[2] + w * dt / 2);
    if (!m || !occmap_occupied_at(m, nx, ny)) {
        r->truth[0] = nx;
        r->truth[1] = ny;
    } else {
        v = 0;
    }
    r->truth[2] = atan2(sin(r->truth[2] + w * dt), cos(r->truth[2] + w * dt));
    double ov = v * r->v_scale + sim_gauss(&r->rng, r->v_noise);
    double ow = w + r->gyro_bias + sim_gauss(&r->rng, r->w_noise);
    r->odom[0] += ov * dt * cos(r->odom[2] + ow * dt / 2);
    r->odom[1] += ov * dt * sin(r->odom[2] + ow * dt / 2);
    r->odom[2] = atan2(sin(r->odom[2] + ow * dt), cos(r->odom[2] + ow * dt));
}

/* A 181-beam, 180 degree scan from the true pose with Gaussian noise and some clutter. */
static inline void sim_scan(simrobot_t *r, const occmap_t *m, float *ranges, int n, double range_max,
                            double noise, double clutter)
{
    for (int k = 0; k < n; k++) {
        double a = -M_PI / 2 + k * M_PI / (n - 1);
        double d = occmap_raycast(m, r->truth[0], r->truth[1], r->truth[2] + a, range_max);
        if (d < range_max)
            d += sim_gauss(&r->rng, noise);
        if (sim_uniform(&r->rng) < clutter)
            d = d * sim_uniform(&r->rng);
        if (d < 0.02)
            d = 0.02;
        ranges[k] = (float)(d > range_max ? range_max : d);
    }
}

#endif
