/* eval_run: one world's run: the simulator (channel mode, on its own clock), odometry, localizer,
 * planner and behaviours as plain processes, the goals driven from here, the robot carried away
 * when asked, and what happened counted from the bus. */
#include "tools/eval/eval.h"

#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/pidfd.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "core/loop.h"
#include "core/time.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_types.h"

extern char **environ;

#define NPROG 5

/* SIGTERM or SIGINT: the run ends, its programs are stopped, and no world follows. */
static bool stopped;

bool eval_stopped(void)
{
    return stopped;
}

static void on_stop(marie_loop_t *loop, int signo, void *user)
{
    stopped = true;
    marie_loop_quit(loop);
}

typedef struct {
    int64_t sim_us, truth_us;
    double truth[3];
    bool have_truth, have_pose;
    double err_sq;
    int64_t nerr;
    eval_result_t *res;
    /* the goal being driven to: the path is summed and the arrival seen per truth message */
    marie_goal_t goal;
    bool driving, reached, refused;
    int64_t t0, limit_us;       /* sim time */
    double travelled;
    bool asked;                 /* the localizer gave up and asks for a pose */
    const char *world;
    lcm_t *lcm;
} live_t;

static void on_truth(live_t *L, const marie_pose_cov_t *m)
{
    if (L->driving) {
        double step = hypot(m->pose.x - L->truth[0], m->pose.y - L->truth[1]);
        L->travelled += step < 1.0 ? step : 0;      /* a kidnapping is not driving */
        L->reached = hypot(m->pose.x - L->goal.pose.x, m->pose.y - L->goal.pose.y) < L->goal.tolerance;
        L->driving = !L->reached;
    }
    L->truth[0] = m->pose.x, L->truth[1] = m->pose.y, L->truth[2] = m->pose.theta;
    L->truth_us = L->sim_us = m->utime;
    L->have_truth = true;
}

static void on_counters(live_t *L, const marie_heartbeat_t *hb)
{
    eval_result_t *r = L->res;
    for (int i = 0; i < hb->ncounters; i++) {
        const char *n = hb->counters[i].name;
        int64_t v = hb->counters[i].value;
        if (!strcmp(hb->component, "sim") && !strcmp(n, "collisions"))
            r->collisions = v;
        else if (!strcmp(hb->component, "behaviours") && !strcmp(n, "recoveries"))
            r->recoveries = v;
        else if (!strcmp(hb->component, "localizer") && !strcmp(n, "kidnaps_detected"))
            r->lost = v;
        else if (!strcmp(hb->component, "localizer") && !strcmp(n, "relocalizations"))
            r->found = v;
        else if (!strcmp(hb->component, "localizer") && !strcmp(n, "relocalizations_failed")) {
            L->asked |= v > r->asked;
            r->asked = v;
        }
    }
}

static void on_msg(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    live_t *L = user;
    union {
        marie_pose_cov_t pose;
        marie_heartbeat_t hb;
        marie_path_t path;
    } m;
    if (!strcmp(ch, "SIM_TRUTH") && marie_decode_checked(&marie_type_pose_cov_t, rb->data, rb->data_size, &m) >= 0) {
        on_truth(L, &m.pose);
        marie_pose_cov_t_decode_cleanup(&m.pose);
    } else if (!strcmp(ch, "POSE") && marie_decode_checked(&marie_type_pose_cov_t, rb->data, rb->data_size, &m) >= 0) {
        /* Against the newest truth (50 Hz: at 0.5 m/s at most 1 cm behind). */
        if (L->have_truth && llabs(m.pose.utime - L->truth_us) < 100000) {
            double e = hypot(m.pose.pose.x - L->truth[0], m.pose.pose.y - L->truth[1]);
            L->err_sq += e * e;
            L->nerr++;
        }
        L->have_pose = true;
        marie_pose_cov_t_decode_cleanup(&m.pose);
    } else if (!strcmp(ch, "PATH") && marie_decode_checked(&marie_type_path_t, rb->data, rb->data_size, &m) >= 0) {
        /* The planner refusing a goal the evaluation picked as free is the evaluation's fault. */
        if (L->driving && m.path.goal_id == L->goal.id && m.path.status == MARIE_PATH_T_STATUS_INVALID_GOAL)
            L->refused = true;
        marie_path_t_decode_cleanup(&m.path);
    } else if (!strcmp(ch, "MARIE_HEARTBEAT") && marie_decode_checked(&marie_type_heartbeat_t, rb->data, rb->data_size, &m) >= 0) {
        on_counters(L, &m.hb);
        marie_heartbeat_t_decode_cleanup(&m.hb);
    }
}

static int live_ready(void *user) { return ((live_t *)user)->have_pose && ((live_t *)user)->have_truth; }

/* Reached, out of simulated time, or the robot asks for help. */
static int goal_over(void *user)
{
    live_t *L = user;
    return L->reached || L->asked || L->sim_us - L->t0 >= L->limit_us;
}

static int sim_passed(void *user)
{
    live_t *L = user;
    return L->reached || L->sim_us - L->t0 >= 5000000;
}

static int sim_passed_2s(void *user)
{
    live_t *L = user;
    return L->sim_us - L->t0 >= 2000000;
}

/* Repeated, as the mission does. */
static void publish_goal(live_t *L)
{
    L->goal.utime = L->sim_us;
    marie_goal_t_publish(L->lcm, "GOAL", &L->goal);
}

static void on_goal_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user) { publish_goal(user); }

/* ---- processes ---- */
static pid_t spawn(const char *log, char *const argv[])
{
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&fa, 1, 2);
    pid_t pid = -1;
    if (posix_spawn(&pid, argv[0], &fa, NULL, argv, environ) != 0)
        pid = -1;
    posix_spawn_file_actions_destroy(&fa);
    return pid;
}

/* A program's pidfd is readable once it has exited: it is reaped then. */
static void on_exit_fd(marie_loop_t *loop, int fd, short revents, void *user)
{
    pid_t *pid = user;
    if (waitpid(*pid, NULL, WNOHANG) == *pid)
        *pid = -1;
    marie_loop_remove_fd(loop, fd);
}

typedef struct {
    const pid_t *pids;
    int n;
} kids_t;

static int none_left(void *user)
{
    const kids_t *k = user;
    for (int i = 0; i < k->n; i++)
        if (k->pids[i] > 0)
            return 0;
    return 1;
}

/* SIGTERM to every program, SIGKILL to those still there 5 s later. The wait runs a loop of its
 * own over the programs' pidfds: the run's loop has quit when a signal ended the run, and the
 * programs still get their 5 s. */
static void stop_all(pid_t *pids, int n)
{
    marie_loop_t *loop = marie_loop_create();
    int fds[NPROG];
    for (int i = 0; i < n; i++) {
        fds[i] = -1;
        if (pids[i] <= 0)
            continue;
        kill(pids[i], SIGTERM);
        if (loop && (fds[i] = pidfd_open(pids[i], 0)) >= 0 &&
            marie_loop_add_fd(loop, fds[i], POLLIN, on_exit_fd, &pids[i]) < 0) {
            close(fds[i]);
            fds[i] = -1;
        }
    }
    if (loop)
        marie_loop_run_until(loop, 5000, none_left, &(kids_t){ pids, n });
    for (int i = 0; i < n; i++) {
        if (pids[i] > 0 && waitpid(pids[i], NULL, WNOHANG) == 0) {
            kill(pids[i], SIGKILL);
            waitpid(pids[i], NULL, 0);
        }
        pids[i] = -1;
        if (fds[i] >= 0)
            close(fds[i]);
    }
    marie_loop_destroy(loop);
}

/* The five programs' command lines, their logs in dir. */
typedef struct {
    char store[48][1100];
    int nstore;
    char *argv[NPROG][40];
    char log[NPROG][1200];
} progs_t;

typedef struct {
    progs_t *p;
    int prog, k;
} argb_t;

static void vput(argb_t *b, const char *fmt, va_list ap)
{
    vsnprintf(b->p->store[b->p->nstore], sizeof b->p->store[0], fmt, ap);
    b->p->argv[b->prog][b->k++] = b->p->store[b->p->nstore++];
}

static void arg(argb_t *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void arg(argb_t *b, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vput(b, fmt, ap);
    va_end(ap);
}

static void param(argb_t *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void param(argb_t *b, const char *fmt, ...)
{
    va_list ap;
    b->p->argv[b->prog][b->k++] = "--param";
    va_start(ap, fmt);
    vput(b, fmt, ap);
    va_end(ap);
}

static void programs(progs_t *p, const eval_opts_t *o, const eval_world_t *w, const eval_site_t *s, const char *dir)
{
    static const char *const names[NPROG] = { "sim", "odometry", "localizer", "planner", "behaviours" };
    memset(p, 0, sizeof *p);
    for (int i = 0; i < NPROG; i++) {
        argb_t b = { p, i, 0 };
        snprintf(p->log[i], sizeof p->log[i], "%s/%s.log", dir, names[i]);
        arg(&b, "%s/marie-%s", o->bin, names[i]);
        arg(&b, "--name");
        arg(&b, "%s", names[i]);
        if (i == 0) {
            param(&b, "mode=channel");
            param(&b, "world=%s", s->world_yaml);
            param(&b, "speed=%g", o->speed);
            param(&b, "start_x=%.3f", s->start[0]);
            param(&b, "start_y=%.3f", s->start[1]);
            param(&b, "start_theta=%.3f", s->start[2]);
            param(&b, "seed=%llu", (unsigned long long)(o->seed % 1000000 + 1));
        } else {
            arg(&b, "--clock");
            arg(&b, "sim");
        }
        if (i <= 1) {
            param(&b, "track=%g", w->track);
            param(&b, "wheel_radius=%g", w->wheel);
        }
        if (i == 2 || i == 3)
            param(&b, "map=%s", s->map_yaml);
        if (i == 2) {
            param(&b, "init_x=%.3f", s->start[0]);
            param(&b, "init_y=%.3f", s->start[1]);
            param(&b, "init_theta=%.3f", s->start[2]);
            param(&b, "resume_max_age_s=0");
        }
        if (i != 1)
            param(&b, "robot_radius=%g", w->radius);
        if (i >= 3)
            param(&b, "robot_clearance=%g", w->clearance);
        if (i == 4)
            param(&b, "input_mode=subscribe");
    }
}

static void teleport(live_t *L, const double pose[3])
{
    marie_pose_cov_t t = { .utime = L->sim_us, .frame = "map", .pose = { pose[0], pose[1], pose[2] } };
    marie_pose_cov_t_publish(L->lcm, "SIM_TELEPORT", &t);
}

/* Runs the loop until done or `sim_s` more simulated seconds (bounded in wall time as well:
 * three times what the simulator's speed gives, and 20 s). */
static void run_for(marie_loop_t *loop, const eval_opts_t *o, double sim_s, int (*done)(void *), live_t *L)
{
    double wall_s = sim_s / o->speed * 3 + 20;
    marie_loop_run_until(loop, wall_s > 86400 ? 86400000 : (int)(wall_s * 1000), done, L);
}

/* A robot that asks for a pose gets the true one, as an operator would answer: its goal is
 * missed, the next ones are not lost with it. */
static void answer(live_t *L, marie_loop_t *loop, const eval_opts_t *o)
{
    marie_pose_cov_t p = { .utime = L->sim_us, .frame = "map", .pose = { L->truth[0], L->truth[1], L->truth[2] },
                           .cov = { 0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.01 } };
    marie_pose_cov_t_publish(L->lcm, "INITIALPOSE", &p);
    L->asked = false;
    L->t0 = L->sim_us;
    run_for(loop, o, 2, sim_passed_2s, L);
}

/* Goal k: published (and repeated) until reached or out of time. A kidnapping goal carries the
 * robot, 5 s after it set off, to a spot from which the goal can still be reached, and allows
 * 120 s more. false when no goal could be picked. */
static bool drive_goal(live_t *L, marie_loop_t *loop, const eval_opts_t *o, const eval_site_t *s, int k)
{
    eval_result_t *r = L->res;
    double from[2] = { L->truth[0], L->truth[1] }, g[2];
    double len = eval_pick_goal(s, from, g);
    if (len < 0) {
        fprintf(stderr, "eval: no reachable goal from (%.2f, %.2f)\n", from[0], from[1]);
        return false;
    }
    r->tried++;
    L->goal = (marie_goal_t){ .id = k, .name = "eval", .pose = { g[0], g[1], 0 }, .tolerance = o->tolerance, .priority = 1 };
    L->t0 = L->sim_us;
    L->limit_us = (int64_t)((60 + 4 * len / 0.5) * 1e6);
    L->travelled = 0;
    L->reached = L->refused = false;
    L->driving = true;
    publish_goal(L);
    marie_timer_t *repeat = marie_loop_add_wall_timer(loop, 1000000, on_goal_timer, L);
    bool carried = false;
    if (o->kidnap > 0 && k % o->kidnap == 0) {
        run_for(loop, o, 5, sim_passed, L);
        double pose[3], here[2] = { L->truth[0], L->truth[1] }, left = L->reached ? -1 : eval_pick_kidnap(s, here, g, pose);
        if (left >= 0) {
            teleport(L, pose);
            carried = true;
            r->kidnapped++;
            L->limit_us = L->sim_us - L->t0 + (int64_t)((180 + 4 * left / 0.5) * 1e6);
        }
    }
    run_for(loop, o, (L->limit_us - (L->sim_us - L->t0)) / 1e6, goal_over, L);
    marie_loop_remove_timer(loop, repeat);
    L->driving = false;
    if (stopped && !L->reached) {
        r->tried--;             /* interrupted, not missed */
        return false;
    }
    double dt = (L->sim_us - L->t0) / 1e6;
    if (L->reached) {
        r->time_s[r->nres++] = dt;
        if (!carried)       /* the way from where it was carried to is not the goal's shortest */
            r->ratio[r->nratio++] = L->travelled / fmax(len - o->tolerance, 0.1);
        r->reached++;
    }
    r->refused += L->refused;
    bool asked = L->asked;
    if (asked)
        answer(L, loop, o);
    if (!o->tsv)
        printf("eval: %-9s goal %2d/%lld (%6.2f, %6.2f): %s in %5.1f s, %5.1f m driven, shortest %5.1f m%s%s, "
               "robot at (%.2f, %.2f)\n", L->world, k, (long long)o->goals, g[0], g[1],
               L->reached ? "reached" : "MISSED ", dt, L->travelled, len, carried ? ", carried away" : "",
               asked ? ", asked for a pose (given)" : "", L->truth[0], L->truth[1]);
    fflush(stdout);
    return true;
}

int eval_run(const eval_opts_t *o, const eval_world_t *w, eval_result_t *r)
{
    memset(r, 0, sizeof *r);
    char dir[1100];
    snprintf(dir, sizeof dir, "%s/%s", o->out, w->name);
    mkdir(o->out, 0755);
    mkdir(dir, 0755);
    eval_site_t s;
    r->time_s = calloc((size_t)o->goals + 1, sizeof(double));
    r->ratio = calloc((size_t)o->goals + 1, sizeof(double));
    if (!r->time_s || !r->ratio || eval_site_make(&s, w, o, dir) < 0) {
        eval_site_free(&s);
        return -1;
    }
    progs_t *p = malloc(sizeof *p);
    lcm_t *l = marie_bus_create(NULL);
    marie_loop_t *loop = marie_loop_create();
    live_t L = { .lcm = l, .res = r };
    pid_t pids[NPROG] = { -1, -1, -1, -1, -1 };
    int rc = -1;
    if (!p || !l || !loop || marie_loop_add_bus(loop, l, 64) < 0 || marie_loop_catch_signals(loop, on_stop, NULL) < 0)
        goto out;
    programs(p, o, w, &s, dir);
    for (int i = 0; i < NPROG; i++)
        pids[i] = spawn(p->log[i], p->argv[i]);
    static const char *const channels[] = { "SIM_TRUTH", "POSE", "PATH", "MARIE_HEARTBEAT" };
    for (int i = 0; i < 4; i++)
        marie_bus_subscribe(l, channels[i], on_msg, &L);
    marie_loop_run_until(loop, 30000, live_ready, &L);
    if (!L.have_pose && !stopped) {
        fprintf(stderr, "eval: %s: no pose within 30 s (see %s)\n", w->name, dir);
        goto out;
    }
    L.world = w->name;
    for (int k = 1; k <= o->goals && !stopped && drive_goal(&L, loop, o, &s, k); k++)
        ;
    /* Last counters: a heartbeat or two more. */
    marie_loop_run_until(loop, 1500, NULL, NULL);
    rc = 0;
out:
    stop_all(pids, NPROG);
    r->rms = L.nerr ? sqrt(L.err_sq / L.nerr) : NAN;
    if (loop)
        marie_loop_catch_signals(loop, NULL, NULL);
    marie_loop_destroy(loop);
    if (l)
        marie_bus_destroy(l);
    free(p);
    eval_site_free(&s);
    return rc;
}
