/* odo: dead reckoning for a differential drive: distance from the wheel encoders, heading from
 * the gyroscope (from the encoders while the gyro is silent or faulty), with covariance. */
#ifndef ADAPTERS_ODO_H
#define ADAPTERS_ODO_H

#include <stdbool.h>
#include <stdint.h>

#include "adapters/odometry/odo_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/* odo_params_t: the parameters, declared in odo.params.yaml; these are its defaults. */
void odo_params_default(odo_params_t *p);

typedef struct {
    odo_params_t p;
    /* encoders */
    bool have_enc;
    int64_t enc_utime;
    int32_t left, right;
    /* gyro integral: cumulative heading G(t) at the last sample and the rate since */
    bool have_gyro;
    int64_t gyro_utime;
    double gyro_sum, gyro_rate;
    double g_at_enc;            /* G at the last encoder time */
    bool g_valid;               /* g_at_enc came from a fresh gyro */
    /* output */
    double pose[3], v, omega, distance, cov[9];
    int64_t utime;
    int64_t steps, gyro_steps, glitches;
} odo_t;

void odo_init(odo_t *o, const odo_params_t *p);
/* The encoders' readings stopped meaning anything (a drive fault, its driver restarting): the
 * next sample is a new reference, not motion since the last one. The pose stays. */
void odo_encoders_lost(odo_t *o);
/* Feed a gyro sample (rad/s, bias already removed). status != 0 samples are ignored.
 * 0, or -1 with errno EINVAL for a non-finite rate or a time going backwards (ignored). */
int odo_gyro(odo_t *o, int64_t utime, double yaw_rate, int status);
/* Feed the cumulative encoder ticks (wrapping at int32). Returns 1 when the pose advanced,
 * 0 for the first sample, -1 with errno EINVAL for bad input (ignored; the next sample re-anchors). */
int odo_encoders(odo_t *o, int64_t utime, int32_t left, int32_t right, int32_t ticks_per_rev);

#ifdef __cplusplus
}
#endif
#endif
