/* gyro_bias: yaw-rate bias estimation at standstill: while the robot is known to stand still
 * (for at least `settle_s`), the mean raw rate is the bias; it then follows slow drift with
 * a time constant. Pure: samples and the standstill flag in, bias out. */
#ifndef MARIE_HW_GYRO_BIAS_H
#define MARIE_HW_GYRO_BIAS_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double settle_s;        /* standstill this long before samples count (vibration dies out) */
    double tau_s;           /* drift-following time constant once the bias is known */
    int min_samples;        /* samples before the bias is valid */
    double max_rate;        /* |raw - bias| above this at "standstill" is not standstill (rad/s) */
    /* state */
    double bias;
    bool valid;
    int64_t still_since;    /* -1: moving */
    int64_t n;
    double sum;
} gyro_bias_t;

void gyro_bias_init(gyro_bias_t *b, double settle_s, double tau_s, int min_samples, double max_rate);
/* One sample of raw rate (rad/s) at time now_us, with the standstill judgement at that time
 * and the sample period. Returns true when the sample updated the bias. */
bool gyro_bias_feed(gyro_bias_t *b, double raw, bool still, int64_t now_us, double dt_s);

#ifdef __cplusplus
}
#endif
#endif
