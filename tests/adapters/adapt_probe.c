/* adapt_probe: watches a running robot application on the bus and judges it: localization
 * error of POSE against SIM_TRUTH, mission events, motor commands. Used by the adapters'
 * integration tests. Exit 0 when the criteria given hold. */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <lcm/lcm.h>

#include "core/time.h"
#include "lcmtypes/marie_types.h"

#define RING 4096

typedef struct {
    int64_t t[RING];
    double x[RING], y[RING];
    int n, head;
    double sum2, max;
    int64_t npose;
    int reached, missed, done, resumed, collisions;
    int64_t estop_utime, estop_cmd_utime;   /* sim time the e-stop was seen pressed, and obeyed */
    int64_t cmds, arbs;
    int64_t win_follow, win_avoid, win_idle, win_estop, win_teleop;
    int64_t arb_bad;             /* decision records that contradict themselves */
    int64_t teleop_cmds;         /* motor commands decided by teleop */
    int64_t pulls;               /* pull requests seen on *.PULL channels */
    double last_pose_age;        /* pose input age in the last decision record */
    double sum_v;
    double settle_s;
    int64_t first_truth;
    int verbose;
} probe_t;

static void on_truth(const lcm_recv_buf_t *rb, const char *ch, const marie_pose_cov_t *m, void *u)
{
    probe_t *p = u;
    if (!p->first_truth)
        p->first_truth = m->utime;
    p->t[p->head] = m->utime;
    p->x[p->head] = m->pose.x;
    p->y[p->head] = m->pose.y;
    p->head = (p->head + 1) % RING;
    if (p->n < RING)
        p->n++;
}

static void on_pose(const lcm_recv_buf_t *rb, const char *ch, const marie_pose_cov_t *m, void *u)
{
    probe_t *p = u;
    /* Truth sample nearest in time to the estimate. */
    int best = -1;
    int64_t bd = INT64_MAX;
    for (int k = 0; k < p->n; k++) {
        int64_t d = llabs(p->t[k] - m->utime);
        if (d < bd) { bd = d; best = k; }
    }
    if (best < 0 || bd > 50000 || m->utime - p->first_truth < (int64_t)(p->settle_s * 1e6))
        return;
    double e = hypot(m->pose.x - p->x[best], m->pose.y - p->y[best]);
    p->sum2 += e * e;
    if (e > p->max)
        p->max = e;
    p->npose++;
    if (p->verbose && p->npose % 50 == 0)
        fprintf(stderr, "probe: t=%.1f est (%.2f, %.2f) truth (%.2f, %.2f) err %.3f\n", (m->utime - p->first_truth) / 1e6,
                m->pose.x, m->pose.y, p->x[best], p->y[best], e);
}

static void on_event(const lcm_recv_buf_t *rb, const char *ch, const marie_event_t *m, void *u)
{
    probe_t *p = u;
    if (strcmp(m->kind, "goal_reached") == 0)
        p->reached++;
    else if (strcmp(m->kind, "goal_missed") == 0)
        p->missed++;
    else if (strcmp(m->kind, "mission_done") == 0)
        p->done = 1;
    else if (strcmp(m->kind, "mission_resumed") == 0)
        p->resumed++;
    else if (strcmp(m->kind, "collision") == 0)
        p->collisions++;
    if (p->verbose && m->severity >= MARIE_EVENT_T_SEV_INFO)
        fprintf(stderr, "probe: event %s %s: %s\n", m->source, m->kind, m->text);
}

static void on_cmd(const lcm_recv_buf_t *rb, const char *ch, const marie_motor_command_t *m, void *u)
{
    probe_t *p = u;
    p->cmds++;
    if (strcmp(m->source, "teleop") == 0 && fabs(m->v - 0.2) < 1e-9 && fabs(m->omega - 0.1) < 1e-9)
        p->teleop_cmds++;
    if (p->estop_utime && !p->estop_cmd_utime && strcmp(m->source, "estop") == 0 && m->v == 0 && m->omega == 0)
        p->estop_cmd_utime = m->utime;
}

static void on_pull(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    marie_pull_request_t r;
    if (marie_pull_request_t_decode(rb->data, 0, (int)rb->data_size, &r) < 0)
        return;
    if (strstr(r.requester, "behaviours"))
        ((probe_t *)u)->pulls++;
    marie_pull_request_t_decode_cleanup(&r);
}

static void on_estop(const lcm_recv_buf_t *rb, const char *ch, const marie_estop_t *m, void *u)
{
    probe_t *p = u;
    if (m->pressed && !p->estop_utime)
        p->estop_utime = m->utime;
}

static void on_arb(const lcm_recv_buf_t *rb, const char *ch, const marie_arbitration_t *m, void *u)
{
    probe_t *p = u;
    p->arbs++;
    p->sum_v += m->v;
    /* The record must explain the decision: every behaviour (the seven and the recovery) and
     * input present, the winner the highest-priority active vote, the command the winner's. */
    int best = -1;
    for (int i = 0; i < m->nvotes; i++)
        if (m->votes[i].active && (best < 0 || m->votes[i].priority > m->votes[best].priority))
            best = i;
    for (int i = 0; i < m->ninputs; i++)
        if (strcmp(m->inputs[i].name, "pose") == 0)
            p->last_pose_age = m->inputs[i].age;
    if (m->nvotes != 8 || m->ninputs != 7 || best < 0 || strcmp(m->votes[best].name, m->winner) != 0 ||
        m->votes[best].v != m->v || m->votes[best].omega != m->omega) {
        if (p->arb_bad++ == 0)
            fprintf(stderr, "probe: inconsistent decision record in cycle %lld (winner %s)\n", (long long)m->cycle, m->winner);
    }
    if (strcmp(m->winner, "follow_path") == 0) p->win_follow++;
    else if (strcmp(m->winner, "avoid") == 0) p->win_avoid++;
    else if (strcmp(m->winner, "idle") == 0) p->win_idle++;
    else if (strcmp(m->winner, "estop") == 0) p->win_estop++;
    else if (strcmp(m->winner, "teleop") == 0) p->win_teleop++;
    if (p->verbose > 1)
        for (int i = 0; i < m->nvotes; i++)
            if (m->votes[i].active || strcmp(m->votes[i].name, "follow_path") == 0)
                fprintf(stderr, "probe: cycle %lld %s%s v %.2f w %.2f: %s\n", (long long)m->cycle, m->votes[i].name,
                        strcmp(m->votes[i].name, m->winner) == 0 ? "*" : "", m->votes[i].v, m->votes[i].omega,
                        m->votes[i].reason);
}

/* Malformed and absurd input on every channel the adapters read: they must count it and go on. */
static void send_garbage(lcm_t *lcm)
{
    static const char *const chans[] = { "WHEEL_ENCODERS", "GYRO", "LASER", "ODOMETRY", "POSE", "PATH", "GOAL",
                                         "TELEOP", "INITIALPOSE", "POSE.PULL", "MAP", "ESTOP" };
    uint8_t buf[256];
    unsigned seed = 7;
    for (int round = 0; round < 5; round++)
        for (size_t k = 0; k < sizeof(chans) / sizeof(chans[0]); k++) {
            size_t n = rand_r(&seed) % sizeof(buf);
            for (size_t i = 0; i < n; i++)
                buf[i] = (uint8_t)rand_r(&seed);
            lcm_publish(lcm, chans[k], buf, (unsigned)n);
        }
    float ranges[3] = { NAN, -1, INFINITY };
    marie_laser_scan_t scan = { .utime = 1, .angle_min = NAN, .angle_increment = 0, .range_max = -1, .nranges = 3,
                                .ranges = ranges };
    marie_odometry_t odo = { .utime = 1, .pose = { NAN, 0, 0 } };
    marie_pose2d_t poses[2] = { { 0, 0, 0 }, { NAN, INFINITY, 0 } };
    marie_path_t path = { .utime = 1, .goal_id = 99, .nposes = 2, .poses = poses };
    marie_goal_t goal = { .utime = 1, .id = 99, .name = "bad", .pose = { NAN, 1, 0 } };
    marie_motor_command_t tele = { .utime = 1, .v = NAN, .omega = INFINITY, .source = "bad" };
    marie_wheel_encoders_t enc = { .utime = 1, .ticks_per_rev = 0 };
    marie_gyro_t gyro = { .utime = 1, .yaw_rate = NAN };
    marie_pose_cov_t ip = { .utime = 1, .frame = "map", .pose = { INFINITY, 0, 0 } };
    int8_t cells[4] = { 0, 100, -1, 50 };
    marie_occupancy_grid_t map = { .utime = 1, .resolution = 0.05f, .width = 1000, .height = 1000, .ncells = 4,
                                   .cells = cells };
    for (int i = 0; i < 3; i++) {
        marie_laser_scan_t_publish(lcm, "LASER", &scan);
        marie_odometry_t_publish(lcm, "ODOMETRY", &odo);
        marie_path_t_publish(lcm, "PATH", &path);
        marie_goal_t_publish(lcm, "GOAL", &goal);
        marie_motor_command_t_publish(lcm, "TELEOP", &tele);
        marie_wheel_encoders_t_publish(lcm, "WHEEL_ENCODERS", &enc);
        marie_gyro_t_publish(lcm, "GYRO", &gyro);
        marie_pose_cov_t_publish(lcm, "INITIALPOSE", &ip);
        marie_occupancy_grid_t_publish(lcm, "MAP", &map);
    }
}

int main(int argc, char **argv)
{
    probe_t p = { 0 };
    double timeout = 60, max_rms = 0.15, max_err = 0.5;
    int want_goals = 0, want_done = 0, want_resumed = 0, estop_after_done = 0, garbage = 0, teleop = 0;
    static struct option opts[] = { { "timeout", 1, 0, 't' }, { "goals", 1, 0, 'g' }, { "done", 0, 0, 'd' },
                                    { "max-rms", 1, 0, 'r' }, { "max-err", 1, 0, 'm' }, { "settle", 1, 0, 's' },
                                    { "verbose", 0, 0, 'v' }, { "resumed", 0, 0, 'R' },
                                    { "estop-after-done", 0, 0, 'E' }, { "garbage", 0, 0, 'G' },
                                    { "teleop-after-done", 0, 0, 'T' }, { 0 } };
    int o;
    while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        switch (o) {
        case 't': timeout = atof(optarg); break;
        case 'g': want_goals = atoi(optarg); break;
        case 'd': want_done = 1; break;
        case 'r': max_rms = atof(optarg); break;
        case 'm': max_err = atof(optarg); break;
        case 's': p.settle_s = atof(optarg); break;
        case 'v': p.verbose++; break;
        case 'R': want_resumed = 1; break;
        case 'E': estop_after_done = 1; break;
        case 'G': garbage = 1; break;
        case 'T': teleop = 1; break;
        default: return 2;
        }
    }
    lcm_t *lcm = lcm_create(NULL);
    if (!lcm)
        return 2;
    marie_pose_cov_t_subscription_t *s_truth = marie_pose_cov_t_subscribe(lcm, "SIM_TRUTH", on_truth, &p);
    marie_pose_cov_t_subscription_t *s_pose = marie_pose_cov_t_subscribe(lcm, "POSE", on_pose, &p);
    marie_event_t_subscription_t *s_event = marie_event_t_subscribe(lcm, "MARIE_EVENT", on_event, &p);
    marie_motor_command_t_subscription_t *s_cmd = marie_motor_command_t_subscribe(lcm, "MOTOR_COMMAND", on_cmd, &p);
    marie_arbitration_t_subscription_t *s_arb = marie_arbitration_t_subscribe(lcm, "ARBITRATION", on_arb, &p);
    marie_estop_t_subscription_t *s_estop = marie_estop_t_subscribe(lcm, "ESTOP", on_estop, &p);
    lcm_subscription_t *s_pull = lcm_subscribe(lcm, ".*\\.PULL", on_pull, &p);
    p.last_pose_age = -1;
    if (garbage)
        send_garbage(lcm);
    int64_t end = marie_mono_us() + (int64_t)(timeout * 1e6);
    while (marie_mono_us() < end && !(want_done && p.done))
        lcm_handle_timeout(lcm, 50);
    if (teleop && p.done) {
        /* An operator drives for a second: teleop must win while its commands keep coming. */
        for (int i = 0; i < 10; i++) {
            marie_motor_command_t t = { .utime = marie_wall_us(), .v = 0.2, .omega = 0.1, .source = "joystick" };
            marie_motor_command_t_publish(lcm, "TELEOP", &t);
            int64_t until = marie_mono_us() + 100000;
            while (marie_mono_us() < until)
                lcm_handle_timeout(lcm, 20);
        }
        printf("probe: %lld commands from teleop\n", (long long)p.teleop_cmds);
    }
    if (estop_after_done && p.done) {
        /* Press the (simulated) e-stop button and wait until the arbitration obeys it. */
        marie_estop_t e = { .utime = marie_wall_us(), .pressed = 1, .source = "adapt_probe" };
        marie_estop_t_publish(lcm, "SIM_ESTOP", &e);
        int64_t e_end = marie_mono_us() + 5000000;
        while (marie_mono_us() < e_end && !p.estop_cmd_utime)
            lcm_handle_timeout(lcm, 20);
        printf("probe: e-stop seen at sim %.3f s, obeyed %.3f s later\n", p.estop_utime / 1e6,
               p.estop_cmd_utime ? (p.estop_cmd_utime - p.estop_utime) / 1e6 : -1.0);
    }
    double rms = p.npose ? sqrt(p.sum2 / p.npose) : INFINITY;
    printf("probe: goals reached %d missed %d done %d; localization rms %.3f m max %.3f m over %lld poses; "
           "%lld commands, %lld decisions\n", p.reached, p.missed, p.done, rms, p.max, (long long)p.npose,
           (long long)p.cmds, (long long)p.arbs);
    if (p.arbs)
        printf("probe: winners follow %lld avoid %lld idle %lld estop %lld teleop %lld; mean v %.2f m/s\n",
               (long long)p.win_follow, (long long)p.win_avoid, (long long)p.win_idle, (long long)p.win_estop,
               (long long)p.win_teleop, p.sum_v / p.arbs);
    fflush(stdout);
    marie_pose_cov_t_unsubscribe(lcm, s_truth);
    marie_pose_cov_t_unsubscribe(lcm, s_pose);
    marie_event_t_unsubscribe(lcm, s_event);
    marie_motor_command_t_unsubscribe(lcm, s_cmd);
    marie_arbitration_t_unsubscribe(lcm, s_arb);
    marie_estop_t_unsubscribe(lcm, s_estop);
    lcm_unsubscribe(lcm, s_pull);
    lcm_destroy(lcm);
    printf("probe: mission resumed %d time(s)\n", p.resumed);
    printf("probe: %lld inconsistent decision records\n", (long long)p.arb_bad);
    printf("probe: %d collisions\n", p.collisions);
    printf("probe: %lld pull requests; pose age in the last decision %.3f s\n", (long long)p.pulls, p.last_pose_age);
    int ok = p.npose > 0 && p.arb_bad == 0 && p.collisions == 0 && rms < max_rms && p.max < max_err && p.reached >= want_goals && (!want_done || p.done) &&
             (!want_resumed || p.resumed > 0) && (!teleop || p.teleop_cmds > 0) &&
             (!estop_after_done || (p.estop_cmd_utime && p.estop_cmd_utime - p.estop_utime <= 300000));
    return ok ? 0 : 1;
}
