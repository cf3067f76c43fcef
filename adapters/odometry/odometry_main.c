/* marie-odometry: fuses wheel encoders (distance) and the gyroscope (heading) into odometry,
 * published at a fixed rate. */
#include <errno.h>
#include <math.h>
#include <string.h>

#include "adapters/odometry/odo.h"
#include "adapters/odometry/odometry_params.h"
#include "core/component.h"

typedef struct {
    odo_t o;
    int64_t published_utime;
    double sign_l, sign_r;
} odom_t;

static void on_encoders(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    odom_t *s = marie_component_user(c);
    const marie_wheel_encoders_t *m = msg;
    if (m->status == MARIE_WHEEL_ENCODERS_T_STATUS_FAULT) {
        /* What a faulted drive reports, and where its wheels went meanwhile, is no motion to
         * add up: the first sample after the fault starts afresh. */
        marie_component_count(c, "encoder_faults", 1);
        odo_encoders_lost(&s->o);
        return;
    }
    int32_t l = s->sign_l < 0 ? (int32_t)(0u - (uint32_t)m->left_ticks) : m->left_ticks;
    int32_t r = s->sign_r < 0 ? (int32_t)(0u - (uint32_t)m->right_ticks) : m->right_ticks;
    if (odo_encoders(&s->o, m->utime, l, r, m->ticks_per_rev) < 0)
        marie_component_bad_input(c, "bad_encoders", "encoder sample at %lld refused (ticks_per_rev %d, "
                                  "jump or time going back)", (long long)m->utime, m->ticks_per_rev);
}

static void on_gyro(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    odom_t *s = marie_component_user(c);
    const odom_params_t *q = marie_component_params(c);
    const marie_gyro_t *m = msg;
    if (m->status != 0) {
        marie_component_count(c, "gyro_faults", 1);
        return;
    }
    /* Until its driver has seen the robot stand still long enough, the rate carries the gyro's
     * raw bias (0.01 rad/s on the simulator's device: 9 degrees a quarter of an hour); the
     * encoders give the heading meanwhile. */
    if (!m->bias_valid && !q->gyro_uncalibrated) {
        marie_component_count(c, "gyro_uncalibrated", 1);
        return;
    }
    if (odo_gyro(&s->o, m->utime, m->yaw_rate, 0) < 0)
        marie_component_bad_input(c, "bad_gyro", "gyro sample at %lld refused (rate %g)", (long long)m->utime, m->yaw_rate);
}

static void tick(marie_component_t *c, int64_t overruns)
{
    odom_t *s = marie_component_user(c);
    if (!s->o.have_enc || s->o.utime == s->published_utime)
        return;                 /* nothing new since the last message */
    s->published_utime = s->o.utime;
    marie_odometry_t m = { .utime = s->o.utime, .pose = { s->o.pose[0], s->o.pose[1], s->o.pose[2] },
                           .v = s->o.v, .omega = s->o.omega, .distance = s->o.distance };
    memcpy(m.cov, s->o.cov, sizeof(m.cov));
    marie_port_publish(marie_port(c, "odom"), &m);
}

static int init(marie_component_t *c)
{
    odom_t *s = marie_component_user(c);
    const odom_params_t *q = marie_component_params(c);
    const odo_params_t *p = &q->odo;
    if (!(p->wheel_radius > 0) || !(p->track > 0) || !(q->rate_hz > 0 && q->rate_hz <= 1000)) {
        marie_component_fail_reason(c, "wheel_radius and track must be > 0, rate_hz in (0, 1000]");
        return -1;
    }
    odo_init(&s->o, p);
    s->published_utime = 0;
    s->sign_l = q->invert_left ? -1 : 1;
    s->sign_r = q->invert_right ? -1 : 1;
    if (marie_port_on_message(marie_port(c, "encoders"), on_encoders) ||
        marie_port_on_message(marie_port(c, "gyro"), on_gyro)) {
        marie_component_fail_reason(c, "cannot subscribe to inputs");
        return -1;
    }
    return marie_component_every(c, q->rate_hz, tick) ? 0 : -1;
}

static const marie_port_spec_t ports[] = {
    { "encoders", &marie_type_wheel_encoders_t, MARIE_IN, MARIE_PUSH, "WHEEL_ENCODERS" },
    { "gyro", &marie_type_gyro_t, MARIE_IN, MARIE_PUSH, "GYRO" },
    { "odom", &marie_type_odometry_t, MARIE_OUT, MARIE_PUSH, "ODOMETRY" },
    { 0 },
};

static const marie_param_spec_t params[] = ODOM_PARAMS;

static const marie_component_def_t def = {
    .kind = "odometry", .ports = ports, .params = params, .params_size = sizeof(odom_params_t), .on_init = init,
};

int main(int argc, char **argv)
{
    odom_t s = { 0 };
    return marie_main(&def, argc, argv, &s);
}
