/* odo: encoder distance + gyro heading dead reckoning with first-order covariance propagation. */
#include "adapters/odometry/odo.h"

#include <errno.h>
#include <math.h>
#include <string.h>

#include "core/err.h"

void odo_params_default(odo_params_t *p)
{
    *p = (odo_params_t)ODO_PARAMS_DEFAULTS;
}

void odo_init(odo_t *o, const odo_params_t *p)
{
    memset(o, 0, sizeof(*o));
    o->p = *p;
}

/* Cumulative gyro heading at time t, extrapolating the last rate a little past the sample. */
static double gyro_at(const odo_t *o, int64_t t)
{
    double dt = (double)(t - o->gyro_utime) / 1e6;
    if (dt > o->p.gyro_timeout_s)
        dt = o->p.gyro_timeout_s;
    return o->gyro_sum + o->gyro_rate * dt;
}

static bool gyro_fresh(const odo_t *o, int64_t t)
{
    return o->p.use_gyro && o->have_gyro && fabs((double)(t - o->gyro_utime) / 1e6) <= o->p.gyro_timeout_s;
}

int odo_gyro(odo_t *o, int64_t utime, double yaw_rate, int status)
{
    if (status != 0)
        return 0;
    if (!isfinite(yaw_rate) || fabs(yaw_rate) > 100 || (o->have_gyro && utime < o->gyro_utime))
        return marie_fail(EINVAL);
    if (o->have_gyro) {
        double dt = (double)(utime - o->gyro_utime) / 1e6;
        if (dt > o->p.gyro_timeout_s) {
            /* A gap: integrate nothing across it (the encoders covered the heading). */
            o->gyro_sum = gyro_at(o, o->gyro_utime);
        } else {
            o->gyro_sum += 0.5 * (o->gyro_rate + yaw_rate) * dt;   /* trapezoid */
        }
    }
    o->gyro_utime = utime;
    o->gyro_rate = yaw_rate;
    o->have_gyro = true;
    return 0;
}

void odo_encoders_lost(odo_t *o)
{
    o->have_enc = false;
}

int odo_encoders(odo_t *o, int64_t utime, int32_t left, int32_t right, int32_t tpr)
{
    if (tpr <= 0)
        return marie_fail(EINVAL);
    if (!o->have_enc || utime <= o->enc_utime) {
        bool back = o->have_enc && utime <= o->enc_utime;
        o->have_enc = true;
        o->enc_utime = utime;
        o->left = left;
        o->right = right;
        o->g_valid = gyro_fresh(o, utime);
        o->g_at_enc = o->g_valid ? gyro_at(o, utime) : 0;
        o->utime = utime;
        return back ? marie_fail(EINVAL) : 0;
    }
    double dt = (double)(utime - o->enc_utime) / 1e6;
    /* Tick differences wrap with the int32 counters. */
    int32_t dl_t = (int32_t)((uint32_t)left - (uint32_t)o->left);
    int32_t dr_t = (int32_t)((uint32_t)right - (uint32_t)o->right);
    double per_tick = 2 * M_PI / tpr;
    double max_ticks = o->p.max_wheel_speed * dt / per_tick + 2;
    o->enc_utime = utime;
    o->left = left;
    o->right = right;
    if (fabs((double)dl_t) > max_ticks || fabs((double)dr_t) > max_ticks) {
        o->glitches++;
        o->g_valid = gyro_fresh(o, utime);
        o->g_at_enc = o->g_valid ? gyro_at(o, utime) : 0;
        return marie_fail(EINVAL);
    }
    double dl = dl_t * per_tick * o->p.wheel_radius, dr = dr_t * per_tick * o->p.wheel_radius;
    double ds = 0.5 * (dl + dr);
    double dth;
    bool gyro = gyro_fresh(o, utime) && o->g_valid;
    double g_now = gyro_fresh(o, utime) ? gyro_at(o, utime) : 0;
    if (gyro)
        dth = g_now - o->g_at_enc;
    else
        dth = (dr - dl) / o->p.track;
    o->g_at_enc = g_now;
    o->g_valid = gyro_fresh(o, utime);

    double th0 = o->pose[2], thm = th0 + 0.5 * dth;
    o->pose[0] += ds * cos(thm);
    o->pose[1] += ds * sin(thm);
    o->pose[2] = atan2(sin(th0 + dth), cos(th0 + dth));
    o->distance += fabs(ds);
    o->v = dt > 0 ? ds / dt : 0;
    o->omega = dt > 0 ? dth / dt : 0;
    o->utime = utime;
    o->steps++;
    o->gyro_steps += gyro;

    /* P = F P F^T + Q, F the Jacobian of the step w.r.t. the previous pose. */
    double F[9] = { 1, 0, -ds * sin(thm), 0, 1, ds * cos(thm), 0, 0, 1 };
    double FP[9] = { 0 }, P[9] = { 0 };
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++)
                FP[r * 3 + c] += F[r * 3 + k] * o->cov[k * 3 + c];
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < 3; k++)
                P[r * 3 + c] += FP[r * 3 + k] * F[c * 3 + k];
    double q = o->p.k_dist * fabs(ds);
    P[0] += q;
    P[4] += q;
    P[8] += gyro ? o->p.k_gyro * dt : o->p.k_enc_heading * fabs(dth) + o->p.k_dist * fabs(ds);
    for (int r = 0; r < 3; r++)         /* keep it exactly symmetric */
        for (int c = r + 1; c < 3; c++)
            P[r * 3 + c] = P[c * 3 + r] = 0.5 * (P[r * 3 + c] + P[c * 3 + r]);
    memcpy(o->cov, P, sizeof(P));
    return 1;
}
