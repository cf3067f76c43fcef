/* marie-behaviours: follow path, avoid obstacles, e-stop, teleop and face the speaker behaviours arbitrated by
 * priority at a fixed rate; each cycle pulls its inputs from Mailboxes (or uses subscribed
 * copies) and publishes the motor command and the decision record. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/behaviours/arbiter.h"
#include "adapters/behaviours/behaviours_params.h"
#include "adapters/behaviours/recovery.h"
#include "core/component.h"
#include "core/typeinfo.h"

enum { IN_POSE = 0, IN_PATH, IN_SCAN, IN_ESTOP, IN_PULLED, IN_TELEOP = IN_PULLED, IN_RELOC, IN_FACE, IN_COUNT };
static const bhv_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }

static const char *const in_ports[IN_COUNT] = { "pose", "path", "scan", "estop", "teleop", "relocalize", "face" };

typedef struct beh beh_t;

typedef struct {
    beh_t *b;
    int which;
    int64_t stamp;              /* component clock time the value describes; INT64_MIN: none */
    marie_bus_sub_t *sub;    /* subscribe mode */
} input_t;

struct beh {
    marie_component_t *c;
    arb_params_t p;
    arb_state_t st;
    rec_params_t rp;
    rec_state_t rs;
    bool pull;
    input_t in[IN_COUNT];
    int outstanding;            /* pulls of this cycle still unanswered */
    int64_t cycle;
    /* latest values */
    double pose[3];
    double *path; int npath, path_cap, path_status; int32_t path_goal;
    float *ranges; int nranges, ranges_cap; double angle_min, angle_inc, range_min, range_max;
    bool estop_pressed;
    double teleop_v, teleop_w;
    double reloc_v, reloc_w;
    double face_heading; int32_t face_id;
};

/* When a message was true, on the component's clock: its own stamp when plausible, else the
 * moment it was received (stamps from another clock would make ages meaningless). */
static int64_t stamp_of(beh_t *b, int64_t utime, int64_t recv_age_us)
{
    int64_t now = marie_component_now(b->c);
    if (utime > 0 && utime <= now + 1000000 && now - utime < 3600LL * 1000000)
        return utime;
    return now - (recv_age_us > 0 ? recv_age_us : 0);
}

static void store(beh_t *b, int which, const void *msg, int64_t recv_age_us)
{
    marie_component_t *c = b->c;
    int64_t utime = 0;
    switch (which) {
    case IN_POSE: {
        const marie_pose_cov_t *m = msg;
        if (!isfinite(m->pose.x) || !isfinite(m->pose.y) || !isfinite(m->pose.theta)) {
            marie_component_bad_input(c, "bad_pose", "pose is not finite");
            return;
        }
        b->pose[0] = m->pose.x; b->pose[1] = m->pose.y; b->pose[2] = m->pose.theta;
        utime = m->utime;
        break;
    }
    case IN_PATH: {
        const marie_path_t *m = msg;
        if (m->nposes < 0 || m->nposes > 100000) {
            marie_component_bad_input(c, "bad_path", "path with %d poses", m->nposes);
            return;
        }
        if (m->nposes > b->path_cap) {
            double *n = realloc(b->path, sizeof(double) * 3 * m->nposes);
            if (!n)
                return;
            b->path = n;
            b->path_cap = m->nposes;
        }
        for (int i = 0; i < m->nposes; i++) {
            b->path[3 * i] = m->poses[i].x;
            b->path[3 * i + 1] = m->poses[i].y;
            b->path[3 * i + 2] = m->poses[i].theta;
        }
        b->npath = m->nposes;
        b->path_status = m->status;
        b->path_goal = m->goal_id;
        utime = m->utime;
        break;
    }
    case IN_SCAN: {
        const marie_laser_scan_t *m = msg;
        if (m->nranges < 0 || m->nranges > 10000 || !isfinite(m->angle_min) || !isfinite(m->angle_increment)) {
            marie_component_bad_input(c, "bad_scan", "scan with %d beams", m->nranges);
            return;
        }
        if (m->nranges > b->ranges_cap) {
            float *n = realloc(b->ranges, sizeof(float) * m->nranges);
            if (!n)
                return;
            b->ranges = n;
            b->ranges_cap = m->nranges;
        }
        memcpy(b->ranges, m->ranges, sizeof(float) * m->nranges);
        b->nranges = m->nranges;
        b->angle_min = m->angle_min;
        b->angle_inc = m->angle_increment;
        b->range_min = m->range_min;
        b->range_max = m->range_max;
        utime = m->utime;
        break;
    }
    case IN_ESTOP: {
        const marie_estop_t *m = msg;
        b->estop_pressed = m->pressed;
        utime = m->utime;
        break;
    }
    case IN_TELEOP: {
        const marie_motor_command_t *m = msg;
        b->teleop_v = m->v;
        b->teleop_w = m->omega;
        utime = 0;              /* an operator's clock is not ours: age from receipt */
        break;
    }
    case IN_RELOC: {
        const marie_motor_command_t *m = msg;
        b->reloc_v = m->v;
        b->reloc_w = m->omega;
        utime = m->utime;
        break;
    }
    case IN_FACE: {
        /* The speaker's azimuth is in the robot frame of when it was heard: held as a map
         * heading from the pose known now (the robot stands still while it listens). */
        const marie_sound_sources_t *m = msg;
        if (m->count < 1 || !isfinite(m->sources[0].azimuth) || b->in[IN_POSE].stamp == INT64_MIN) {
            marie_component_count(c, "face_ignored", 1);
            return;
        }
        b->face_heading = b->pose[2] + m->sources[0].azimuth;
        b->face_id++;
        utime = m->utime;
        break;
    }
    }
    b->in[which].stamp = stamp_of(b, utime, recv_age_us);
}

static double age_s(const beh_t *b, int which, int64_t now)
{
    int64_t s = b->in[which].stamp;
    if (s == INT64_MIN)
        return -1;
    return s > now ? 0 : (double)(now - s) / 1e6;
}

static void publish_safe(marie_component_t *c, const char *why)
{
    marie_motor_command_t cmd = { .utime = marie_component_now(c), .v = 0, .omega = 0, .source = (char *)why };
    marie_port_publish(marie_port(c, "cmd"), &cmd);
}

static void decide(beh_t *b)
{
    marie_component_t *c = b->c;
    int64_t now = marie_component_now(c);
    arb_inputs_t in = {
        .pose = { b->pose[0], b->pose[1], b->pose[2] }, .pose_age = age_s(b, IN_POSE, now),
        .path = b->path, .npath = b->npath, .path_status = b->path_status, .path_goal = b->path_goal,
        .path_age = age_s(b, IN_PATH, now),
        .ranges = b->ranges, .nranges = b->nranges, .angle_min = b->angle_min, .angle_increment = b->angle_inc,
        .range_min = b->range_min, .range_max = b->range_max, .scan_age = age_s(b, IN_SCAN, now),
        .estop_pressed = b->estop_pressed, .estop_age = age_s(b, IN_ESTOP, now),
        .teleop_v = b->teleop_v, .teleop_omega = b->teleop_w, .teleop_age = age_s(b, IN_TELEOP, now),
        .reloc_v = b->reloc_v, .reloc_omega = b->reloc_w, .reloc_age = age_s(b, IN_RELOC, now),
        .face_heading = b->face_heading, .face_id = b->face_id, .face_age = age_s(b, IN_FACE, now),
    };
    arb_vote_t votes[ARB_COUNT];
    int win = arb_decide(&b->p, &b->st, &in, votes);
    if (!isfinite(votes[win].v) || !isfinite(votes[win].omega)) {
        /* Never let a non-finite number reach the drives. */
        marie_component_bad_input(c, "non_finite_command", "%s voted a non-finite command", votes[win].name);
        votes[win].v = votes[win].omega = 0;
    }
    double v = votes[win].v, w = votes[win].omega;
    const char *winner = votes[win].name;
    bool replan = false;
    int64_t cut = b->rs.backoffs_cut;
    int stage = rec_step(&b->rp, &b->rs, (double)now / 1e6, &b->p, &in, win, votes, &v, &w, &replan);
    if (b->rs.backoffs_cut > cut) {
        marie_component_count(c, "back_off_cut", 1);
        marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "back_off_cut",
                              "goal %d: back-off stopped, a return seen %.2f m behind the footprint or less",
                              (int)in.path_goal, b->rp.backoff_clearance);
    }
    if (replan) {
        marie_component_count(c, "recoveries", 1);
        marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "no_progress",
                              "goal %d: no progress for %.0f s (%s winning), recovery %d: replan, back off, rotate, detour",
                              (int)in.path_goal, b->rp.stuck_s, votes[win].name, b->rs.level);
        marie_goal_t g = { .utime = now, .id = in.path_goal, .name = "" };
        marie_port_publish(marie_port(c, "replan"), &g);
    }
    if (stage != REC_NONE) {
        winner = "recovery";
        marie_component_count(c, rec_stage_name(stage), 1);
    }
    marie_motor_command_t cmd = { .utime = now, .v = v, .omega = w, .source = (char *)winner };
    marie_port_publish(marie_port(c, "cmd"), &cmd);

    /* The recovery overrides the arbitration's winner: in the record it is one more vote, just
     * above the vote it overrides, so the record still explains the command. */
    marie_behaviour_vote_t mv[ARB_COUNT + 1];
    for (int i = 0; i < ARB_COUNT; i++)
        mv[i] = (marie_behaviour_vote_t){ .name = (char *)votes[i].name, .priority = votes[i].priority,
                                          .active = votes[i].active, .v = votes[i].v, .omega = votes[i].omega,
                                          .reason = votes[i].reason };
    bool recovering = stage != REC_NONE;
    mv[ARB_COUNT] = (marie_behaviour_vote_t){ .name = "recovery", .priority = recovering ? votes[win].priority + 1 : 0,
                                              .active = recovering, .v = recovering ? v : 0, .omega = recovering ? w : 0,
                                              .reason = (char *)(recovering ? rec_stage_name(stage) : "making progress") };
    marie_input_age_t ages[IN_COUNT];
    for (int i = 0; i < IN_COUNT; i++)
        ages[i] = (marie_input_age_t){ .name = (char *)in_ports[i], .age = age_s(b, i, now) };
    marie_arbitration_t rec = { .utime = now, .cycle = b->cycle, .nvotes = ARB_COUNT + 1, .votes = mv,
                                .winner = (char *)winner, .v = cmd.v, .omega = cmd.omega,
                                .ninputs = IN_COUNT, .inputs = ages };
    marie_port_publish(marie_port(c, "arbitration"), &rec);
    marie_component_count(c, winner, 1);
}

static void on_pulled(marie_component_t *c, marie_port_t *p, int status, const void *msg, int64_t age_us, void *user)
{
    input_t *in = user;
    beh_t *b = in->b;
    if (status == 0 && msg)
        store(b, in->which, msg, age_us);
    else if (status == ETIMEDOUT)
        marie_component_count(c, "pull_timeouts", 1);
    else if (status == ENODATA)
        marie_component_count(c, "pull_empty", 1);
    else
        marie_component_count(c, "pull_errors", 1);
    if (b->outstanding > 0 && --b->outstanding == 0)
        decide(b);
}

/* pull_timeout_ms, cut so that answers come back within the cycle. */
static int pull_timeout_ms(const bhv_params_t *q)
{
    return q->pull_timeout_ms > 0.8e3 / q->rate_hz ? (int)(0.8e3 / q->rate_hz) : (int)q->pull_timeout_ms;
}

static void tick(marie_component_t *c, int64_t overruns)
{
    beh_t *b = marie_component_user(c);
    if (b->outstanding > 0) {
        /* The last cycle's answers are overdue: decide with what is known and move on. */
        marie_component_count(c, "cycles_incomplete", 1);
        b->outstanding = 0;
        decide(b);
    }
    b->cycle++;
    if (!b->pull) {
        decide(b);
        return;
    }
    b->outstanding = IN_PULLED + 1;   /* +1 holds the decision until every pull is sent */
    for (int i = 0; i < IN_PULLED; i++) {
        if (marie_port_pull_async(marie_port(c, in_ports[i]), pull_timeout_ms(params_of(c)), on_pulled, &b->in[i]) != 0) {
            marie_component_count(c, "pull_errors", 1);
            b->outstanding--;
        }
    }
    if (--b->outstanding == 0)
        decide(b);
}

static void on_teleop(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    store(marie_component_user(c), IN_TELEOP, msg, 0);
}

static void on_reloc(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    store(marie_component_user(c), IN_RELOC, msg, 0);
}

static void on_face(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    store(marie_component_user(c), IN_FACE, msg, 0);
}

/* The e-stop does not wait for the next cycle: a press seen on the bus stops the robot now
 * (an extra decision between cycles); the cycle keeps pulling the e-stop state as well. */
static void on_estop_now(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    beh_t *b = marie_component_user(c);
    const marie_estop_t *m = msg;
    bool was = b->estop_pressed && b->in[IN_ESTOP].stamp != INT64_MIN;
    store(b, IN_ESTOP, msg, 0);
    if (m->pressed && !was) {
        marie_component_count(c, "estop_immediate", 1);
        decide(b);
    }
}

/* Subscribe mode: the pull ports' channels are subscribed directly (no Mailbox needed). */
static void on_raw(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    input_t *in = user;
    beh_t *b = in->b;
    const marie_type_t *t = in->which == IN_POSE ? &marie_type_pose_cov_t : in->which == IN_PATH ? &marie_type_path_t
                          : in->which == IN_SCAN ? &marie_type_laser_scan_t : &marie_type_estop_t;
    union {
        marie_pose_cov_t pose;
        marie_path_t path;
        marie_laser_scan_t scan;
        marie_estop_t estop;
    } m;
    const char *why;
    if (marie_decode_input(t, rb->data, rb->data_size, &m, &why) < 0) {
        marie_component_bad_input(b->c, why, "%s: %u bytes: not a well-formed, finite %s", channel, rb->data_size,
                                  t->name);
        return;
    }
    store(b, in->which, &m, 0);
    t->decode_cleanup(&m);
}

static int stop_hook(marie_component_t *c)
{
    beh_t *b = marie_component_user(c);
    b->outstanding = 0;
    publish_safe(c, "stopped");
    return 0;
}

static void abort_hook(marie_component_t *c)
{
    publish_safe(c, "aborted");
}

static void quit(marie_component_t *c)
{
    beh_t *b = marie_component_user(c);
    /* Who drove, in one line: a livelock shows as avoid winning most cycles. */
    if (b->cycle > 0)
        marie_info("cycles %lld: estop %lld, avoid %lld, teleop %lld, relocalize %lld, face_speaker %lld, follow_path %lld, "
                   "idle %lld, recovery %lld (recoveries %lld)", (long long)b->cycle, (long long)marie_component_counter(c, "estop"),
                   (long long)marie_component_counter(c, "avoid"), (long long)marie_component_counter(c, "teleop"),
                   (long long)marie_component_counter(c, "relocalize"),
                   (long long)marie_component_counter(c, "face_speaker"),
                   (long long)marie_component_counter(c, "follow_path"), (long long)marie_component_counter(c, "idle"),
                   (long long)marie_component_counter(c, "recovery"), (long long)b->rs.recoveries);
    for (int i = 0; i < IN_COUNT; i++)
        if (b->in[i].sub) {
            marie_bus_unsubscribe(marie_component_lcm(c), b->in[i].sub);
            b->in[i].sub = NULL;
        }
    free(b->path);
    free(b->ranges);
    b->path = NULL;
    b->ranges = NULL;
    b->path_cap = b->ranges_cap = b->npath = b->nranges = 0;
}

/* With the immediate e-stop on the e-stop's own channel (the default binding), its push port
 * already stores every e-stop message: a second subscription would take (and count) each twice. */
static bool estop_pushed(marie_component_t *c)
{
    return params_of(c)->estop_immediate &&
           strcmp(marie_port_channel(marie_port(c, "estop")), marie_port_channel(marie_port(c, "estop_now"))) == 0;
}

static int init(marie_component_t *c)
{
    beh_t *b = marie_component_user(c);
    b->c = c;
    arb_params_default(&b->p);
    arb_state_reset(&b->st);
    const bhv_params_t *q = params_of(c);
    const char *mode = q->input_mode;
    if (strcmp(mode, "pull") != 0 && strcmp(mode, "subscribe") != 0) {
        marie_component_fail_reason(c, "input_mode: expected pull or subscribe, got '%s'", mode);
        return -1;
    }
    b->pull = strcmp(mode, "pull") == 0;
    double hz = q->rate_hz;
    if (!(hz > 0 && hz <= 1000) || q->pull_timeout_ms < 1) {
        marie_component_fail_reason(c, "rate_hz must be in (0, 1000], pull_timeout_ms >= 1");
        return -1;
    }
    b->p = q->arb;
    /* The avoid corridor follows the robot's size unless set on its own: the footprint and half
     * its clearance to the side, and the same ahead of the laser before stopping. */
    double radius = q->robot_radius, margin = q->robot_clearance / 2;
    if (b->p.half_width <= 0)
        b->p.half_width = radius + margin;
    if (b->p.stop_distance <= 0)
        b->p.stop_distance = radius + margin;
    if (b->p.slow_distance <= 0)
        b->p.slow_distance = b->p.stop_distance + 0.25;
    b->rp = q->rec;
    rec_state_reset(&b->rs);
    if (b->p.slow_distance <= b->p.stop_distance) {
        marie_component_fail_reason(c, "slow_distance must be greater than stop_distance");
        return -1;
    }
    for (int i = 0; i < IN_COUNT; i++) {
        b->in[i].b = b;
        b->in[i].which = i;
        b->in[i].stamp = INT64_MIN;
    }
    if (!b->pull) {
        for (int i = 0; i < IN_PULLED; i++) {
            if (b->in[i].sub || (i == IN_ESTOP && estop_pushed(c)))
                continue;
            b->in[i].sub = marie_bus_subscribe(marie_component_lcm(c), marie_port_channel(marie_port(c, in_ports[i])),
                                         on_raw, &b->in[i]);
            if (!b->in[i].sub) {
                marie_component_fail_reason(c, "cannot subscribe to %s", marie_port_channel(marie_port(c, in_ports[i])));
                return -1;
            }
        }
    }
    if (marie_port_on_message(marie_port(c, "teleop"), on_teleop) || marie_port_on_message(marie_port(c, "face"), on_face) ||
        marie_port_on_message(marie_port(c, "relocalize"), on_reloc)) {
        marie_component_fail_reason(c, "cannot subscribe to teleop, relocalize or face");
        return -1;
    }
    /* Both are idempotent: an init that runs again after a failure asks again. */
    if (q->estop_immediate && marie_port_on_message(marie_port(c, "estop_now"), on_estop_now)) {
        marie_component_fail_reason(c, "cannot subscribe to the e-stop");
        return -1;
    }
    if (!marie_component_every(c, hz, tick)) {
        marie_component_fail_reason(c, "cannot create the %g Hz timer", hz);
        return -1;
    }
    return 0;
}

static const marie_port_spec_t ports[] = {
    { "pose", &marie_type_pose_cov_t, MARIE_IN, MARIE_PULL, "POSE" },
    { "path", &marie_type_path_t, MARIE_IN, MARIE_PULL, "PATH" },
    { "scan", &marie_type_laser_scan_t, MARIE_IN, MARIE_PULL, "LASER" },
    { "estop", &marie_type_estop_t, MARIE_IN, MARIE_PULL, "ESTOP" },
    { "teleop", &marie_type_motor_command_t, MARIE_IN, MARIE_PUSH, "TELEOP" },
    { "relocalize", &marie_type_motor_command_t, MARIE_IN, MARIE_PUSH, "RELOCALIZE" },
    { "estop_now", &marie_type_estop_t, MARIE_IN, MARIE_PUSH, "ESTOP" },
    { "face", &marie_type_sound_sources_t, MARIE_IN, MARIE_PUSH, "SPEAKER" },
    { "cmd", &marie_type_motor_command_t, MARIE_OUT, MARIE_PUSH, "MOTOR_COMMAND" },
    { "arbitration", &marie_type_arbitration_t, MARIE_OUT, MARIE_PUSH, "ARBITRATION" },
    { "replan", &marie_type_goal_t, MARIE_OUT, MARIE_PUSH, "REPLAN" },
    { 0 },
};

static const marie_param_spec_t params[] = BHV_PARAMS;

static const marie_component_def_t def = {
    .kind = "behaviours", .ports = ports, .params = params, .params_size = sizeof(bhv_params_t), .on_init = init, .on_stop = stop_hook,
    .on_pause = stop_hook, .on_abort = abort_hook, .on_quit = quit,
};

int main(int argc, char **argv)
{
    beh_t b = { 0 };
    return marie_main(&def, argc, argv, &b);
}
