/* marie-gyro: the CANopen yaw-rate gyro: samples from its TPDO out as marie.gyro_t with the
 * bias removed, the bias learned while the wheel encoders and motor commands say the robot
 * stands still. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/component.h"
#include "hw/can/can_link.h"
#include "hw/canopen/emcy.h"
#include "hw/canopen/sdo.h"
#include "hw/gyro/gyro_bias.h"
#include "hw/gyro/gyro_ctl.h"
#include "hw/gyro/gyro_params.h"

static const gyro_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }

typedef struct {
    marie_component_t *c;
    gyro_ctl_t *ctl;
    can_link_t *link;
    marie_port_t *out;
    marie_timer_t *poll_timer;
    gyro_bias_t bias;
    int64_t started_us;
    int64_t sample_us;              /* last sample (mono), or the start: for degraded_after */
    bool degraded;
    bool start_pending;         /* started before the simulated clock was known */
    int64_t enc_us, cmd_us;         /* last receipt (mono), 0 never */
    bool enc_still, cmd_still;
} gyro_t;

/* The device's clock: monotonic on the robot, simulated time under `--clock sim`. */
static int64_t now_us(const gyro_t *g) { return marie_loop_mono(marie_component_loop(g->c)); }

static const marie_port_spec_t ports[] = {
    { "wheel_encoders", &marie_type_wheel_encoders_t, MARIE_IN, MARIE_PUSH, "WHEEL_ENCODERS" },
    { "motor_command", &marie_type_motor_command_t, MARIE_IN, MARIE_PUSH, "MOTOR_COMMAND" },
    { "gyro", &marie_type_gyro_t, MARIE_OUT, MARIE_PUSH, "GYRO" },
    { NULL },
};

static const marie_param_spec_t params[] = GYRO_PARAMS;

#define FRESH_US 500000

static bool standstill(gyro_t *g, int64_t now)
{
    bool enc_fresh = g->enc_us && now - g->enc_us < FRESH_US;
    bool cmd_fresh = g->cmd_us && now - g->cmd_us < FRESH_US;
    if (enc_fresh)
        return g->enc_still && (!cmd_fresh || g->cmd_still);
    if (cmd_fresh)
        return g->cmd_still;
    /* Nothing tells us: only the configured start window counts as standstill. */
    return !g->enc_us && !g->cmd_us && now - g->started_us < (int64_t)(params_of(g->c)->assume_still_at_start * 1e6);
}

static void on_sample(void *user, double rate, uint8_t status)
{
    gyro_t *g = user;
    if (marie_component_state(g->c) != MARIE_STATE_RUNNING)
        return;
    int64_t now = now_us(g);
    g->sample_us = now;
    if (g->degraded) {
        g->degraded = false;
        marie_component_set_degraded(g->c, false, "gyro samples again");
    }
    double raw = params_of(g->c)->invert ? -rate : rate;
    if (status == 0)
        gyro_bias_feed(&g->bias, raw, standstill(g, now), now, gyro_ctl_period_s(g->ctl));
    marie_gyro_t m = {
        .utime = marie_component_now(g->c),
        .yaw_rate = g->bias.valid ? raw - g->bias.bias : raw,
        .bias = g->bias.valid ? g->bias.bias : 0,
        .bias_valid = g->bias.valid,
        .status = (int8_t)status,
    };
    marie_port_publish(g->out, &m);
}

static void on_gyro_event(void *user, gyro_ev_t ev, uint32_t code)
{
    gyro_t *g = user;
    marie_component_t *c = g->c;
    switch (ev) {
    case GYRO_EV_CONFIGURED:
        marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "gyro_configured", "gyro '%s' configured, started",
                              gyro_ctl_name(g->ctl));
        break;
    case GYRO_EV_CONFIG_FAILED:
        marie_component_count(c, "config_failures", 1);
        marie_warn_ratelimited(5, "gyro configuration failed: %s", co_sdo_abort_str(code));
        break;
    case GYRO_EV_EMCY:
        marie_component_count(c, "emcy", 1);
        marie_component_event(c, code ? MARIE_EVENT_T_SEV_WARN : MARIE_EVENT_T_SEV_INFO, "gyro_emcy",
                              "gyro EMCY 0x%04X %s", code, co_emcy_str((uint16_t)code));
        break;
    case GYRO_EV_HB_TIMEOUT:
        marie_component_count(c, "hb_timeouts", 1);
        marie_component_event(c, MARIE_EVENT_T_SEV_ERROR, "gyro_offline", "gyro heartbeat lost");
        marie_warn("gyro heartbeat lost");
        break;
    case GYRO_EV_BOOTUP:
        marie_component_count(c, "bootups", 1);
        break;
    case GYRO_EV_BAD_FRAME:
        marie_component_bad_input(c, "bad_frame", "gyro: malformed frame id 0x%03X", code);
        break;
    case GYRO_EV_UNEXPECTED:
        marie_component_bad_input(c, "unexpected_cob", "unexpected frame id 0x%03X", code);
        break;
    case GYRO_EV_LOST:
        marie_component_count(c, "lost_samples", code);
        marie_component_drop(c, code);
        break;
    case GYRO_EV_NOT_FOUND:
        marie_component_count(c, "not_found", 1);
        marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "gyro_not_found",
                              "no boot-up from gyro node %lld yet; resetting it every %g s",
                              (long long)params_of(c)->ctl.node, GYRO_BOOT_RETRY_US / 1e6);
        break;
    }
}

static void send_frames(gyro_t *g, struct can_frame *f, int n)
{
    if (n > 0)
        can_link_send(g->link, f, n);
}

static void on_frame(void *user, const struct can_frame *f)
{
    gyro_t *g = user;
    struct can_frame tx[8];
    send_frames(g, tx, gyro_ctl_feed(g->ctl, f, now_us(g), tx, 8));
}

static void on_link_event(void *user, const char *kind, const char *text)
{
    gyro_t *g = user;
    marie_component_count(g->c, kind, 1);
    marie_component_event(g->c, MARIE_EVENT_T_SEV_WARN, kind, "%s", text);
    marie_info("%s", text);
}

static void begin(gyro_t *g)
{
    struct can_frame tx[8];
    g->start_pending = false;
    g->started_us = g->sample_us = now_us(g);
    send_frames(g, tx, gyro_ctl_start(g->ctl, g->started_us, tx, 8));
}

static void on_poll(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    gyro_t *g = user;
    if (marie_component_state(g->c) != MARIE_STATE_RUNNING)
        return;
    if (g->start_pending)
        begin(g);
    struct can_frame tx[8];
    int64_t now = now_us(g);
    send_frames(g, tx, gyro_ctl_poll(g->ctl, now, tx, 8));
    if (!g->degraded && now - g->sample_us > (int64_t)(params_of(g->c)->degraded_after * 1e6)) {
        g->degraded = true;
        marie_component_set_degraded(g->c, true, "no gyro sample for %.1f s (%s)", (now - g->sample_us) / 1e6,
                                     gyro_ctl_running(g->ctl) ? "configured" : "not configured");
    }
}

static void on_encoders(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    gyro_t *g = marie_component_user(c);
    const marie_wheel_encoders_t *m = msg;
    double still = params_of(c)->still_wheel_velocity;
    g->enc_us = now_us(g);
    g->enc_still = m->status == MARIE_WHEEL_ENCODERS_T_STATUS_OK || m->status == MARIE_WHEEL_ENCODERS_T_STATUS_DISABLED ||
                   m->status == MARIE_WHEEL_ENCODERS_T_STATUS_ESTOP
                   ? fabs(m->left_velocity) < still && fabs(m->right_velocity) < still
                   : false;
}

static void on_command(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    gyro_t *g = marie_component_user(c);
    const marie_motor_command_t *m = msg;
    g->cmd_us = now_us(g);
    g->cmd_still = m->v == 0 && m->omega == 0;
}

static int on_init(marie_component_t *c)
{
    gyro_t *g = calloc(1, sizeof *g);
    if (!g) {
        marie_component_fail_reason(c, "out of memory");
        return -1;
    }
    g->c = c;
    marie_component_set_user(c, g);
    const gyro_params_t *p = params_of(c);
    if (p->ctl.node < 1 || p->ctl.node > 127 || !(p->ctl.rate_hz >= 1 && p->ctl.rate_hz <= 1000) ||
        p->ctl.heartbeat_ms < 0 || p->ctl.heartbeat_ms > 65535) {
        marie_component_fail_reason(c, "bad parameters: node 1..127, rate_hz 1..1000, heartbeat_ms 0..65535");
        goto err;
    }
    gyro_bias_init(&g->bias, p->standstill_window, p->bias_tau, (int)p->bias_min_samples, p->max_still_rate);
    g->ctl = gyro_ctl_create(&p->ctl, on_sample, on_gyro_event, g);
    if (!g->ctl) {
        marie_component_fail_reason(c, "gyro controller: %s", strerror(errno));
        goto err;
    }
    struct can_filter flt[2];
    int nf = gyro_ctl_filters(g->ctl, flt, 2);
    const char *url = p->can;
    g->link = can_link_open(marie_component_loop(c), url, flt, (size_t)nf, on_frame, on_link_event, g);
    if (!g->link) {
        marie_component_fail_reason(c, "cannot open CAN bus %s: %s", url, strerror(errno));
        goto err;
    }
    g->out = marie_port(c, "gyro");
    marie_port_on_message(marie_port(c, "wheel_encoders"), on_encoders);
    marie_port_on_message(marie_port(c, "motor_command"), on_command);
    g->poll_timer = marie_loop_add_timer(marie_component_loop(c), 50000, on_poll, g);
    if (!g->poll_timer) {
        marie_component_fail_reason(c, "timer: %s", strerror(errno));
        goto err;
    }
    return 0;
err:
    can_link_close(g->link);
    gyro_ctl_destroy(g->ctl);
    free(g);
    marie_component_set_user(c, NULL);
    return -1;
}

static int on_start(marie_component_t *c)
{
    gyro_t *g = marie_component_user(c);
    if (g->degraded) {
        g->degraded = false;
        marie_component_set_degraded(c, false, "started");
    }
    /* On the sim clock, SDO deadlines taken before the first clock message would expire at it:
     * the first poll after it starts the gyro. */
    if (!marie_loop_clock_known(marie_component_loop(c)))
        g->start_pending = true;
    else
        begin(g);
    return 0;
}

static void on_quit(marie_component_t *c)
{
    gyro_t *g = marie_component_user(c);
    if (!g)
        return;
    marie_loop_remove_timer(marie_component_loop(c), g->poll_timer);
    can_link_close(g->link);
    gyro_ctl_destroy(g->ctl);
    free(g);
    marie_component_set_user(c, NULL);
}

static const marie_component_def_t def = {
    .kind = "marie-gyro",
    .ports = ports,
    .params = params, .params_size = sizeof(gyro_params_t),
    .on_init = on_init,
    .on_start = on_start,
    .on_quit = on_quit,
};

int main(int argc, char **argv) { return marie_main(&def, argc, argv, NULL); }
