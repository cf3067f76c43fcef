/* navrig: the navigation stack for tests (see navrig.h). */
#include "tests/nav/navrig.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/time.h>

#include "core/typeinfo.h"
#include "lcmtypes/marie_types.h"
#include "tests/proc.h"

static int goal_id;
static rig_t the_rig, *opened;
static double goal_xy[2];

static int64_t wall_us(void)
{
    struct timeval tv;
    gettimeofday(&tv, NULL);
    return (int64_t)tv.tv_sec * 1000000 + tv.tv_usec;
}

static void on_truth(rig_t *r, const marie_pose_cov_t *m)
{
    if (r->sim_us)
        r->turned += fabs(atan2(sin(m->pose.theta - r->truth[2]), cos(m->pose.theta - r->truth[2])));
    r->truth[0] = m->pose.x, r->truth[1] = m->pose.y, r->truth[2] = m->pose.theta;
    r->sim_us = m->utime;
}

static void on_pose(rig_t *r, const marie_pose_cov_t *m)
{
    r->pose[0] = m->pose.x, r->pose[1] = m->pose.y, r->pose[2] = m->pose.theta;
    r->pose_utime = m->utime;
    r->npose++;
    if (r->watch_found) {
        memcpy(r->found_pose, r->pose, sizeof r->pose);
        r->watch_found = false;
    }
}

static void on_heartbeat(rig_t *r, const marie_heartbeat_t *hb)
{
    for (int i = 0; i < hb->ncounters; i++)
        if (!strcmp(hb->component, "sim") && !strcmp(hb->counters[i].name, "collisions"))
            r->collisions = hb->counters[i].value;
    if (strcmp(hb->component, "localizer") != 0)
        return;
    if (hb->state == MARIE_LIFECYCLE_COMMAND_T_STATE_DEGRADED && !r->degraded_at)
        r->degraded_at = r->sim_us;
    if (hb->state == MARIE_LIFECYCLE_COMMAND_T_STATE_RUNNING && r->degraded_at && !r->running_again_at)
        r->running_again_at = r->sim_us;
    r->loc_state = hb->state;
    snprintf(r->loc_reason, sizeof r->loc_reason, "%s", hb->reason);
    for (int i = 0; i < hb->ncounters; i++) {
        const char *n = hb->counters[i].name;
        int64_t v = hb->counters[i].value;
        if (!strcmp(n, "kidnaps_detected"))
            r->lost = v;
        else if (!strcmp(n, "relocalizations"))
            r->found = v;
        else if (!strcmp(n, "relocalizations_failed"))
            r->asked = v;
    }
}

static void on_event(rig_t *r, const marie_event_t *e)
{
    snprintf(r->events[r->nevents % 64], sizeof r->events[0], "%s %s %s", e->source, e->kind, e->text);
    r->nevents++;
    if (!strcmp(e->kind, "relocalized")) {
        r->found_at = r->sim_us;
        r->watch_found = true;
    } else if (!strcmp(e->kind, "relocalization_failed")) {
        r->asked_at = r->sim_us;
    }
    printf("  [%.1f s] %s %s: %s\n", r->sim_us / 1e6, e->source, e->kind, e->text);
}

static void on_msg(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    rig_t *r = user;
    union {
        marie_pose_cov_t pose;
        marie_heartbeat_t hb;
        marie_event_t ev;
    } m;
    const marie_type_t *t = !strcmp(ch, "MARIE_HEARTBEAT") ? &marie_type_heartbeat_t
                          : !strcmp(ch, "MARIE_EVENT") ? &marie_type_event_t : &marie_type_pose_cov_t;
    if (marie_decode_checked(t, rb->data, rb->data_size, &m) < 0)
        return;
    if (!strcmp(ch, "SIM_TRUTH"))
        on_truth(r, &m.pose);
    else if (!strcmp(ch, "POSE"))
        on_pose(r, &m.pose);
    else if (t == &marie_type_heartbeat_t)
        on_heartbeat(r, &m.hb);
    else
        on_event(r, &m.ev);
    t->decode_cleanup(&m);
}

rig_t *rig_open(const char *name)
{
    rig_t *r = &the_rig;
    if (opened)
        rig_close(opened);
    memset(r, 0, sizeof *r);
    opened = r;
    r->loc_state = -1;
    goal_id = 0;
    const char *b = getenv("B") ? getenv("B") : "build";
    snprintf(r->dir, sizeof r->dir, "%s/test-logs/%s", b, name);
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf '%.256s'", r->dir);
    if (system(cmd) != 0 || mkdir(r->dir, 0755) != 0)
        fprintf(stderr, "rig: cannot make %s\n", r->dir);
    r->lcm = lcm_create(NULL);
    static const char *const chans[] = { "SIM_TRUTH", "POSE", "MARIE_HEARTBEAT", "MARIE_EVENT" };
    for (int i = 0; r->lcm && i < 4; i++)
        lcm_subscribe(r->lcm, chans[i], on_msg, r);
    return r;
}

void rig_start(rig_t *r, const char *prog, ...)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    char path[256], log[300], *argv[40];
    int k = 0;
    snprintf(path, sizeof path, "%s/bin/marie-%s", b, prog);
    snprintf(log, sizeof log, "%s/%s.log", r->dir, prog);
    argv[k++] = path;
    argv[k++] = "--name";
    argv[k++] = (char *)prog;
    if (strcmp(prog, "sim") != 0) {
        argv[k++] = "--clock";
        argv[k++] = "sim";
    }
    va_list ap;
    va_start(ap, prog);
    for (const char *p = va_arg(ap, const char *); p && k < 38; p = va_arg(ap, const char *)) {
        argv[k++] = "--param";
        argv[k++] = (char *)p;
    }
    va_end(ap);
    argv[k] = NULL;
    if (r->nprogs < RIG_MAX_PROGS)
        r->pids[r->nprogs++] = test_spawn(argv, log);
}

void rig_close(rig_t *r)
{
    for (int i = r->nprogs - 1; i >= 0; i--)
        test_stop(r->pids[i]);
    r->nprogs = 0;
    if (r->lcm)
        lcm_destroy(r->lcm);
    r->lcm = NULL;
}

int rig_teardown(void **state)
{
    if (opened)
        rig_close(opened);
    opened = NULL;
    return 0;
}

void rig_goal(rig_t *r, int id, double x, double y)
{
    goal_id = id;
    goal_xy[0] = x, goal_xy[1] = y;
}

static void send_goal(rig_t *r)
{
    marie_goal_t g = { .utime = r->sim_us, .id = goal_id, .name = "test", .pose = { goal_xy[0], goal_xy[1], 0 },
                       .tolerance = 0.3, .priority = 1 };
    marie_goal_t_publish(r->lcm, "GOAL", &g);
}

void rig_run(rig_t *r, double sim_s, bool drive, double v, double omega, int (*done)(const rig_t *))
{
    int64_t until = r->sim_us + (int64_t)(sim_s * 1e6), wall_end = wall_us() + (int64_t)(sim_s / 2 * 1e6) + 10000000;
    int64_t next_cmd = 0, next_goal = 0;
    while ((r->sim_us < until || r->sim_us == 0) && wall_us() < wall_end && !(done && done(r))) {
        if (drive && wall_us() >= next_cmd) {
            marie_motor_command_t cmd = { .utime = r->sim_us, .v = v, .omega = omega, .source = "test" };
            marie_motor_command_t_publish(r->lcm, "MOTOR_COMMAND", &cmd);
            next_cmd = wall_us() + 50000;
        }
        if (goal_id > 0 && wall_us() >= next_goal) {
            send_goal(r);
            next_goal = wall_us() + 1000000;
        }
        lcm_handle_timeout(r->lcm, 20);
    }
}

void rig_teleport(rig_t *r, double x, double y, double theta)
{
    marie_pose_cov_t t = { .utime = r->sim_us, .frame = "map", .pose = { x, y, theta } };
    marie_pose_cov_t_publish(r->lcm, "SIM_TELEPORT", &t);
}

double rig_error(const rig_t *r)
{
    return hypot(r->pose[0] - r->truth[0], r->pose[1] - r->truth[1]);
}

bool rig_event(const rig_t *r, const char *kind)
{
    int n = r->nevents < 64 ? r->nevents : 64;
    for (int i = 0; i < n; i++) {
        const char *sp = strchr(r->events[i], ' ');
        if (sp && !strncmp(sp + 1, kind, strlen(kind)) && sp[1 + strlen(kind)] == ' ')
            return true;
    }
    return false;
}

void rig_start_localizer(rig_t *r, const char *map, double x, double y, double th)
{
    char m[300], lx[64], ly[64], lt[64];
    snprintf(m, sizeof m, "map=%s", map);
    snprintf(lx, sizeof lx, "init_x=%g", x), snprintf(ly, sizeof ly, "init_y=%g", y);
    snprintf(lt, sizeof lt, "init_theta=%g", th);
    rig_start(r, "localizer", m, lx, ly, lt, "resume_max_age_s=0", NULL);
}

void rig_start_sim(rig_t *r, const char *world, double x, double y, double th, const char *speed)
{
    char w[300], sx[64], sy[64], st[64];
    snprintf(w, sizeof w, "world=%s", world);
    snprintf(sx, sizeof sx, "start_x=%g", x), snprintf(sy, sizeof sy, "start_y=%g", y);
    snprintf(st, sizeof st, "start_theta=%g", th);
    rig_start(r, "sim", w, "mode=channel", speed ? speed : "speed=4", sx, sy, st, NULL);
    rig_start(r, "odometry", NULL);
}
