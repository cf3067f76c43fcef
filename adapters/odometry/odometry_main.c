/* marie-odometry: fuses wheel encoders (distance) and the gyroscope (heading) into odometry,
 * published at a fixed rate. */
#include <errno.h>
#include <math.h>
#include <string.h>

#include "adapters/odometry/odo.h"
#include "core/component.h"

typedef struct {
    odo_t o;
    int64_t published_utime;
    bool timer_made;
    double sign_l, sign_r;
} odom_t;

static void on_encoders(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    odom_t *s = marie_component_user(c);
    const marie_wheel_encoders_t *m = msg;
    if (m->status == MARIE_WHEEL_ENCODERS_T_STATUS_FAULT) {
        marie_component_count(c, "encoder_faults", 1);
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
    const marie_gyro_t *m = msg;
    if (m->status != 0) {
        marie_component_count(c, "gyro_faults", 1);
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
    odo_params_t p;
    odo_params_default(&p);
    p.wheel_radius = marie_param_double(c, "wheel_radius");
    p.track = marie_param_double(c, "track");
    p.use_gyro = marie_param_bool(c, "use_gyro");
    p.gyro_timeout_s = marie_param_double(c, "gyro_timeout_s");
    p.k_dist = marie_param_double(c, "k_dist");
    p.k_gyro = marie_param_double(c, "k_gyro");
    p.k_enc_heading = marie_param_double(c, "k_enc_heading");
    double hz = marie_param_double(c, "rate_hz");
    if (!(p.wheel_radius > 0) || !(p.track > 0) || !(hz > 0 && hz <= 1000)) {
        marie_component_fail_reason(c, "wheel_radius and track must be > 0, rate_hz in (0, 1000]");
        return -1;
    }
    odo_init(&s->o, &p);
    s->published_utime = 0;
    s->sign_l = marie_param_bool(c, "invert_left") ? -1 : 1;
    s->sign_r = marie_param_bool(c, "invert_right") ? -1 : 1;
    if (marie_port_on_message(marie_port(c, "encoders"), on_encoders) ||
        marie_port_on_message(marie_port(c, "gyro"), on_gyro)) {
        marie_component_fail_reason(c, "cannot subscribe to inputs");
        return -1;
    }
    if (!s->timer_made) {
        if (!marie_component_every(c, hz, tick))
            return -1;
        s->timer_made = true;
    }
    return 0;
}

static const marie_port_spec_t ports[] = {
    { "encoders", &marie_type_wheel_encoders_t, MARIE_IN, MARIE_PUSH, "WHEEL_ENCODERS" },
    { "gyro", &marie_type_gyro_t, MARIE_IN, MARIE_PUSH, "GYRO" },
    { "odom", &marie_type_odometry_t, MARIE_OUT, MARIE_PUSH, "ODOMETRY" },
    { 0 },
};

static const marie_param_spec_t params[] = {
    { "wheel_radius", MARIE_PARAM_DOUBLE, "0.1", "m" },
    { "track", MARIE_PARAM_DOUBLE, "0.4", "m between the wheels" },
    { "rate_hz", MARIE_PARAM_DOUBLE, "10", "odometry publishing rate" },
    { "use_gyro", MARIE_PARAM_BOOL, "true", "heading from the gyro (else from the encoders)" },
    { "gyro_timeout_s", MARIE_PARAM_DOUBLE, "0.3", "s: older gyro data falls back to encoder heading" },
    { "k_dist", MARIE_PARAM_DOUBLE, "0.001", "m^2 position variance per m" },
    { "k_gyro", MARIE_PARAM_DOUBLE, "1e-5", "rad^2 heading variance per s on the gyro" },
    { "k_enc_heading", MARIE_PARAM_DOUBLE, "0.01", "rad^2 heading variance per rad on the encoders" },
    { "invert_left", MARIE_PARAM_BOOL, "false", "left ticks count backwards when driving forward" },
    { "invert_right", MARIE_PARAM_BOOL, "false", "right ticks count backwards when driving forward" },
    { 0 },
};

static const marie_component_def_t def = {
    .kind = "odometry", .ports = ports, .params = params, .on_init = init,
};

int main(int argc, char **argv)
{
    odom_t s = { 0 };
    return marie_main(&def, argc, argv, &s);
}
