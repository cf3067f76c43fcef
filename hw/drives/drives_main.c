/* marie-drives: the two CiA 402 wheel drives on CAN: motor command (v, omega) in through
 * differential-drive kinematics, wheel encoders out; stops the wheels on command timeout
 * and e-stop; faults counted in the heartbeat and reset. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/component.h"
#include "hw/can/can_link.h"
#include "hw/drives/drives_ctl.h"
#include "hw/drives/drives_params.h"

static const drives_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }

typedef struct {
    marie_component_t *c;
    drives_ctl_t *ctl;
    can_link_t *link;
    marie_port_t *out;
    marie_timer_t *sync_timer, *pub_timer;
    bool estop, started;
    bool start_pending;         /* started before the simulated clock was known */
    bool degraded;
    int64_t trouble_since;      /* a drive in trouble since (protocol clock), 0: none */
} drives_t;

static const marie_port_spec_t ports[] = {
    { "motor_command", &marie_type_motor_command_t, MARIE_IN, MARIE_PUSH, "MOTOR_COMMAND" },
    { "estop", &marie_type_estop_t, MARIE_IN, MARIE_PUSH, "ESTOP" },
    { "wheel_encoders", &marie_type_wheel_encoders_t, MARIE_OUT, MARIE_PUSH, "WHEEL_ENCODERS" },
    { NULL },
};

static const marie_param_spec_t params[] = DRIVES_PARAMS;

/* The protocol's clock: monotonic on the robot, simulated time under `--clock sim`, where the
 * virtual drives judge our heartbeat and RPDO deadlines on simulated time too. */
static int64_t now_us(const drives_t *d) { return marie_loop_mono(marie_component_loop(d->c)); }

static void send_frames(drives_t *d, struct can_frame *f, int n)
{
    if (n > 0)
        can_link_send(d->link, f, n);
}

static void on_frame(void *user, const struct can_frame *f)
{
    drives_t *d = user;
    struct can_frame tx[16];
    send_frames(d, tx, drives_ctl_feed(d->ctl, f, now_us(d), tx, 16));
}

static void on_link_event(void *user, const char *kind, const char *text)
{
    drives_t *d = user;
    marie_component_count(d->c, kind, 1);
    bool bad = strcmp(kind, "connected") != 0 && strcmp(kind, "bus_active") != 0;
    marie_component_event(d->c, bad ? MARIE_EVENT_T_SEV_WARN : MARIE_EVENT_T_SEV_INFO, kind, "%s", text);
    if (bad)
        marie_warn("%s", text);
    else
        marie_info("%s", text);
}

/* Each event: its counter, its kind and severity on MARIE_EVENT, the text drives_ctl gives it. */
static void on_drive_event(void *user, int axis, drives_ev_t ev, uint32_t code)
{
    drives_t *d = user;
    marie_component_t *c = d->c;
    static const struct { const char *kind, *counter; int sev; } evs[] = {
        [DRIVES_EV_CONFIGURED] = { "drive_configured", NULL, MARIE_EVENT_T_SEV_INFO },
        [DRIVES_EV_CONFIG_FAILED] = { "drive_config_failed", "config_failures", MARIE_EVENT_T_SEV_WARN },
        [DRIVES_EV_FAULT] = { "drive_fault", "faults", MARIE_EVENT_T_SEV_ERROR },
        [DRIVES_EV_FAULT_RESET] = { "drive_fault_reset", "fault_resets", MARIE_EVENT_T_SEV_INFO },
        [DRIVES_EV_RECOVERED] = { "drive_recovered", NULL, MARIE_EVENT_T_SEV_INFO },
        [DRIVES_EV_EMCY] = { "drive_emcy", "emcy", MARIE_EVENT_T_SEV_WARN },
        [DRIVES_EV_EMCY_STORM] = { NULL, "emcy", 0 },
        [DRIVES_EV_HB_TIMEOUT] = { "drive_offline", "hb_timeouts", MARIE_EVENT_T_SEV_ERROR },
        [DRIVES_EV_BOOTUP] = { NULL, "bootups", 0 },
        [DRIVES_EV_BAD_FRAME] = { NULL, NULL, 0 },
        [DRIVES_EV_UNEXPECTED] = { NULL, NULL, 0 },
        [DRIVES_EV_EMCY_QUIET] = { NULL, "emcy", 0 },
        [DRIVES_EV_OPTIONAL_MISSING] = { "drive_optional_missing", NULL, MARIE_EVENT_T_SEV_INFO },
        [DRIVES_EV_WATCH] = { "drive_watch", NULL, MARIE_EVENT_T_SEV_INFO },
        [DRIVES_EV_HOLD] = { "drive_hold", NULL, MARIE_EVENT_T_SEV_INFO },
        [DRIVES_EV_NOT_FOUND] = { "drive_not_found", NULL, MARIE_EVENT_T_SEV_WARN },
    };
    char text[400];
    drives_ctl_event_text(d->ctl, axis, ev, code, text, sizeof text);
    int sev = evs[ev].sev;
    if (ev == DRIVES_EV_WATCH && code != DRIVES_WATCH_RPDO_ONLY)
        sev = code == DRIVES_WATCH_NONE_REFUSED ? MARIE_EVENT_T_SEV_ERROR : MARIE_EVENT_T_SEV_WARN;
    if (evs[ev].counter)
        marie_component_count(c, evs[ev].counter, 1);
    if (ev == DRIVES_EV_EMCY && code == 0)
        return;                 /* an error reset: counted, not told */
    /* a drive failing alike every retry is told once, then only counted and logged */
    if (ev == DRIVES_EV_CONFIG_FAILED && drives_ctl_axis(d->ctl, axis)->fail.repeats) {
        marie_warn_ratelimited(5, "%s", text);
        return;
    }
    if (ev == DRIVES_EV_EMCY_STORM)
        marie_component_bad_input(c, "emcy_storm", "%s", text);
    else if (ev == DRIVES_EV_BAD_FRAME)
        marie_component_bad_input(c, "bad_frame", "%s", text);
    else if (ev == DRIVES_EV_UNEXPECTED)
        marie_component_bad_input(c, "unexpected_cob", "%s", text);
    if (!evs[ev].kind)
        return;
    marie_component_event(c, sev, evs[ev].kind, "%s", text);
    if (sev >= MARIE_EVENT_T_SEV_WARN)
        marie_warn("%s", text);
}

static void begin(drives_t *d)
{
    struct can_frame tx[16];
    d->started = true;
    d->start_pending = false;
    send_frames(d, tx, drives_ctl_start(d->ctl, now_us(d), tx, 16));
}

static void on_sync(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    drives_t *d = user;
    if (d->start_pending && marie_loop_clock_known(loop))
        begin(d);
    /* Once started the drives are ours until quit: stopped or paused we keep them disabled,
     * and our heartbeat and RPDOs going, or they would (rightly) take us for dead. */
    if (!d->started)
        return;
    struct can_frame tx[16];
    send_frames(d, tx, drives_ctl_cycle(d->ctl, now_us(d), tx, 16));
}

/* Why a drive's position is not known, or why it cannot drive: NULL when it is fine. */
static const char *trouble(const drives_axis_t *a)
{
    switch (a->phase) {
    case DRIVES_AX_BOOT:
        return a->fail.index ? "configuration failed" : "not booted (no answer to reset communication)";
    case DRIVES_AX_CONFIG: return "being configured";
    case DRIVES_AX_OFFLINE: return "heartbeat lost";
    case DRIVES_AX_RUN: break;
    }
    if (a->refused)
        return "kept disabled: it cannot watch marie-drives (no 0x1016, no 0x1400:05)";
    return a->have_tpdo ? NULL : "no position yet";
}

/* The heartbeat says degraded while a drive has been in trouble for degraded_after. */
static void health(drives_t *d, const char *why[DRIVES_N])
{
    int64_t now = now_us(d);
    if (!why[0] && !why[1]) {
        d->trouble_since = 0;
        if (d->degraded)
            marie_component_set_degraded(d->c, false, "both drives configured and reporting");
        d->degraded = false;
        return;
    }
    if (!d->trouble_since)
        d->trouble_since = now;
    if (now - d->trouble_since < (int64_t)(params_of(d->c)->degraded_after * 1e6))
        return;
    d->degraded = true;
    marie_component_set_degraded(d->c, true, "%s%s%s%s%s", why[0] ? "left drive: " : "", why[0] ? why[0] : "",
                                 why[0] && why[1] ? "; " : "", why[1] ? "right drive: " : "", why[1] ? why[1] : "");
}

/* WHEEL_ENCODERS at publish_hz whatever the drives do: a position not read from a drive yet (a
 * new process, a drive just configured, one that never came up) is sent as FAULT, which
 * odometry skips (it would take the jump to and from 0 for motion), and counted. */
static void publish(marie_component_t *c, int64_t overruns)
{
    drives_t *d = marie_component_user(c);
    const drives_axis_t *l = drives_ctl_axis(d->ctl, DRIVES_LEFT), *r = drives_ctl_axis(d->ctl, DRIVES_RIGHT);
    const char *why[DRIVES_N] = { trouble(l), trouble(r) };
    health(d, why);
    marie_wheel_encoders_t m = {
        .utime = marie_component_now(c),
        .left_ticks = l->position,
        .right_ticks = r->position,
        .ticks_per_rev = (int32_t)params_of(c)->ctl.ticks_per_rev,
        .left_velocity = drives_ctl_counts_to_rad(d->ctl, l->velocity),
        .right_velocity = drives_ctl_counts_to_rad(d->ctl, r->velocity),
    };
    bool fault = false;
    for (int i = 0; i < DRIVES_N; i++) {
        const drives_axis_t *a = drives_ctl_axis(d->ctl, i);
        if (why[i] || a->state == CIA402_FAULT || a->state == CIA402_FAULT_REACTION_ACTIVE)
            fault = true;
    }
    if (!l->have_tpdo || !r->have_tpdo)
        marie_component_count(c, "encoders_unknown", 1);
    if (fault || !can_link_up(d->link))
        m.status = MARIE_WHEEL_ENCODERS_T_STATUS_FAULT;
    else if (d->estop)
        m.status = MARIE_WHEEL_ENCODERS_T_STATUS_ESTOP;
    else if (!drives_ctl_all_enabled(d->ctl))
        m.status = MARIE_WHEEL_ENCODERS_T_STATUS_DISABLED;
    else
        m.status = MARIE_WHEEL_ENCODERS_T_STATUS_OK;
    marie_port_publish(d->out, &m);
}

static void on_command(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    drives_t *d = marie_component_user(c);
    const marie_motor_command_t *m = msg;
    if (!isfinite(m->v) || !isfinite(m->omega)) {
        marie_component_bad_input(c, "bad_command", "motor command with non-finite v/omega from '%s'",
                                  m->source ? m->source : "?");
        return;
    }
    /* Differential drive: each wheel's rim speed is v -/+ omega * half the track. */
    double half = params_of(c)->track_width / 2, radius = params_of(c)->wheel_radius;
    int64_t now = now_us(d);
    drives_ctl_set_wheels(d->ctl, (m->v - m->omega * half) / radius, (m->v + m->omega * half) / radius, now);
    /* Out at once (the drives apply RPDOs at the next SYNC) instead of up to a cycle later. */
    struct can_frame tx[4];
    send_frames(d, tx, drives_ctl_rpdo_now(d->ctl, now, tx, 4));
}

static void on_estop(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    drives_t *d = marie_component_user(c);
    const marie_estop_t *m = msg;
    if (m->pressed != d->estop) {
        marie_component_event(c, m->pressed ? MARIE_EVENT_T_SEV_WARN : MARIE_EVENT_T_SEV_INFO, "estop",
                              "e-stop %s (%s)", m->pressed ? "pressed" : "released", m->source ? m->source : "?");
        if (m->pressed)
            marie_component_count(c, "estops", 1);
    }
    bool edge = m->pressed && !d->estop;
    d->estop = m->pressed;
    drives_ctl_set_estop(d->ctl, d->estop);
    if (edge) {
        /* quick stop in RPDO1 now; the drives apply it at the next SYNC, which keeps its
         * period (an extra SYNC per e-stop message would not be one) */
        struct can_frame tx[4];
        send_frames(d, tx, drives_ctl_rpdo_now(d->ctl, now_us(d), tx, 4));
    }
}

static int on_init(marie_component_t *c)
{
    drives_t *d = calloc(1, sizeof *d);
    if (!d) {
        marie_component_fail_reason(c, "out of memory");
        return -1;
    }
    d->c = c;
    marie_component_set_user(c, d);
    const drives_params_t *p = params_of(c);
    char why[160];
    if (!(p->wheel_radius > 0) || !(p->track_width > 0) || !(p->sync_hz > 0 && p->sync_hz <= 1000) ||
        !(p->publish_hz > 0)) {
        marie_component_fail_reason(c, "bad parameters: positive radius, track and rates, sync_hz up to 1000");
        goto err;
    }
    if (drives_cfg_check(&p->ctl, why, sizeof why) < 0) {
        marie_component_fail_reason(c, "bad parameters: %s", why);
        goto err;
    }
    d->ctl = drives_ctl_create(&p->ctl, on_drive_event, d);
    if (!d->ctl) {
        marie_component_fail_reason(c, "drive controller: %s", strerror(errno));
        goto err;
    }
    struct can_filter flt[4];
    int nf = drives_ctl_filters(d->ctl, flt, 4);
    const char *url = p->can;
    d->link = can_link_open(marie_component_loop(c), url, flt, (size_t)nf, on_frame, on_link_event, d);
    if (!d->link) {
        marie_component_fail_reason(c, "cannot open CAN bus %s: %s", url, strerror(errno));
        goto err;
    }
    d->out = marie_port(c, "wheel_encoders");
    marie_port_on_message(marie_port(c, "motor_command"), on_command);
    marie_port_on_message(marie_port(c, "estop"), on_estop);
    d->sync_timer = marie_loop_add_timer(marie_component_loop(c), (int64_t)(1e6 / p->sync_hz), on_sync, d);
    d->pub_timer = marie_component_every(c, p->publish_hz, publish);
    if (!d->sync_timer || !d->pub_timer) {
        marie_component_fail_reason(c, "timers: %s", strerror(errno));
        goto err;
    }
    return 0;
err:
    can_link_close(d->link);
    drives_ctl_destroy(d->ctl);
    if (d->sync_timer)
        marie_loop_remove_timer(marie_component_loop(c), d->sync_timer);
    free(d);
    marie_component_set_user(c, NULL);
    return -1;
}

static int on_start(marie_component_t *c)
{
    drives_t *d = marie_component_user(c);
    drives_ctl_enable(d->ctl, true);
    if (d->started || d->start_pending)
        return 0;               /* restarted after a stop: the cycle never ceased */
    /* On the sim clock, SDO deadlines taken before the first clock message would expire at it. */
    if (!marie_loop_clock_known(marie_component_loop(c)))
        d->start_pending = true;
    else
        begin(d);
    return 0;
}

/* Power stages off: "disable voltage" in RPDO1 at once, applied at the next SYNC; the cycle
 * goes on holding them there. */
static void safe_stop(marie_component_t *c)
{
    drives_t *d = marie_component_user(c);
    if (!d)
        return;
    struct can_frame tx[4];
    drives_ctl_enable(d->ctl, false);
    send_frames(d, tx, drives_ctl_rpdo_now(d->ctl, now_us(d), tx, 4));
}

/* Stopped or paused (no cycle runs, the drives would keep their last target): powered down. */
static int on_stop(marie_component_t *c)
{
    safe_stop(c);
    return 0;
}

static int on_resume(marie_component_t *c)
{
    drives_t *d = marie_component_user(c);
    drives_ctl_enable(d->ctl, true);
    return 0;
}

static void on_abort(marie_component_t *c) { safe_stop(c); }

static void on_quit(marie_component_t *c)
{
    drives_t *d = marie_component_user(c);
    if (!d)
        return;
    if (d->started) {
        /* leave the drives disabled and stopped, not waiting for their heartbeat consumer */
        struct can_frame tx[8];
        send_frames(d, tx, drives_ctl_shutdown(d->ctl, now_us(d), tx, 8));
    }
    marie_loop_remove_timer(marie_component_loop(c), d->sync_timer);
    can_link_close(d->link);
    drives_ctl_destroy(d->ctl);
    free(d);
    marie_component_set_user(c, NULL);
}

static const marie_component_def_t def = {
    .kind = "marie-drives",
    .ports = ports,
    .params = params, .params_size = sizeof(drives_params_t),
    .on_init = on_init,
    .on_start = on_start,
    .on_stop = on_stop,
    .on_pause = on_stop,
    .on_resume = on_resume,
    .on_abort = on_abort,
    .on_quit = on_quit,
};

int main(int argc, char **argv) { return marie_main(&def, argc, argv, NULL); }
