/* gyro_bias: standstill bias estimator. */
#include "hw/gyro/gyro_bias.h"

#include <math.h>
#include <string.h>

void gyro_bias_init(gyro_bias_t *b, double settle_s, double tau_s, int min_samples, double max_rate)
{
    memset(b, 0, sizeof *b);
    b->settle_s = settle_s;
    b->tau_s = tau_s;
    b->min_samples = min_samples > 0 ? min_samples : 1;
    b->max_rate = max_rate;
    b->still_since = -1;
}

bool gyro_bias_feed(gyro_bias_t *b, double raw, bool still, int64_t now_us, double dt_s)
{
    if (!isfinite(raw))
        return false;
    /* Turning faster than any bias could explain: someone is moving the robot by hand. */
    double ref = b->valid ? b->bias : 0;
    if (still && b->max_rate > 0 && fabs(raw - ref) > b->max_rate)
        still = false;
    if (!still) {
        b->still_since = -1;
        return false;
    }
    if (b->still_since < 0)
        b->still_since = now_us;
    if ((double)(now_us - b->still_since) < b->settle_s * 1e6)
        return false;
    if (!b->valid) {
        b->sum += raw;
        b->n++;
        if (b->n >= b->min_samples) {
            b->bias = b->sum / (double)b->n;
            b->valid = true;
        }
        return true;
    }
    double a = b->tau_s > 0 ? dt_s / b->tau_s : 1;
    if (a > 1)
        a = 1;
    b->bias += a * (raw - b->bias);
    return true;
}
