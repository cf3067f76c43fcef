/* route_driver: drives the simulated robot along waypoints from its ground truth (a perfect
 * pilot, so the mapper is judged alone) and measures the mapper's pose against the truth:
 * prints "ate_rms M max M poses N" and "route done" or "route timeout". Exit 0 when done.
 * --hold S: then stands still for S seconds of wall time, sending stop commands (a simulator in
 * lockstep goes on at its speed). */
#include <math.h>
#include <stdbool.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "core/time.h"
#include "lcmtypes/marie_types.h"

#define RING 512
#define MAXWP 256

typedef struct {
    lcm_t *lcm;
    double wp[MAXWP][2];
    int nwp, next;
    int64_t t[RING];
    double x[RING], y[RING];
    int n, head;
    double sum2, max;
    long npose;
    bool posed;                 /* a POSE arrived: the mapper has its first scan */
    FILE *traj;
} drv_t;

static void on_truth(const lcm_recv_buf_t *rb, const char *ch, const marie_pose_cov_t *m, void *u)
{
    drv_t *d = u;
    d->t[d->head] = m->utime;
    d->x[d->head] = m->pose.x;
    d->y[d->head] = m->pose.y;
    d->head = (d->head + 1) % RING;
    if (d->n < RING)
        d->n++;
    double v = 0, w = 0;
    while (d->next < d->nwp && hypot(d->wp[d->next][0] - m->pose.x, d->wp[d->next][1] - m->pose.y) < 0.2)
        d->next++;
    /* The robot stands still until the mapper has seen it where its map frame starts. */
    if (d->posed && d->next < d->nwp) {
        double dx = d->wp[d->next][0] - m->pose.x, dy = d->wp[d->next][1] - m->pose.y;
        double herr = atan2(sin(atan2(dy, dx) - m->pose.theta), cos(atan2(dy, dx) - m->pose.theta));
        w = fmax(-0.8, fmin(0.8, 2.0 * herr));
        v = fabs(herr) > 0.4 ? 0.0 : 0.5;
    }
    marie_motor_command_t cmd = { .utime = m->utime, .v = v, .omega = w, .source = "route_driver" };
    marie_motor_command_t_publish(d->lcm, "MOTOR_COMMAND", &cmd);
}

static void on_pose(const lcm_recv_buf_t *rb, const char *ch, const marie_pose_cov_t *m, void *u)
{
    drv_t *d = u;
    d->posed = true;
    int best = -1;
    int64_t bd = INT64_MAX;
    for (int k = 0; k < d->n; k++) {
        int64_t dt = llabs(d->t[k] - m->utime);
        if (dt < bd) {
            bd = dt;
            best = k;
        }
    }
    if (best < 0 || bd > 30000)
        return;
    double e = hypot(m->pose.x - d->x[best], m->pose.y - d->y[best]);
    d->sum2 += e * e;
    d->max = fmax(d->max, e);
    d->npose++;
    if (d->traj)
        fprintf(d->traj, "%lld %.3f %.3f %.3f %.3f\n", (long long)m->utime, m->pose.x, m->pose.y, d->x[best], d->y[best]);
}

int main(int argc, char **argv)
{
    static drv_t d;
    double timeout = 120, hold = 0;
    const char *route = NULL;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--timeout") == 0 && i + 1 < argc)
            timeout = atof(argv[++i]);
        else if (strcmp(argv[i], "--hold") == 0 && i + 1 < argc)
            hold = atof(argv[++i]);
        else if (strcmp(argv[i], "--route") == 0 && i + 1 < argc)
            route = argv[++i];
        else if (strcmp(argv[i], "--traj") == 0 && i + 1 < argc)
            d.traj = fopen(argv[++i], "w");
    }
    for (const char *p = route; p && *p && d.nwp < MAXWP;) {
        if (sscanf(p, "%lf,%lf", &d.wp[d.nwp][0], &d.wp[d.nwp][1]) != 2)
            break;
        d.nwp++;
        p = strchr(p, ';');
        p = p ? p + 1 : NULL;
    }
    if (!d.nwp) {
        fprintf(stderr, "usage: route_driver --route 'x,y;x,y;...' [--timeout S] [--hold S] [--traj FILE]\n");
        return 2;
    }
    d.lcm = lcm_create(NULL);
    if (!d.lcm)
        return 1;
    marie_pose_cov_t_subscription_t *st = marie_pose_cov_t_subscribe(d.lcm, "SIM_TRUTH", on_truth, &d);
    marie_pose_cov_t_subscription_t *sp = marie_pose_cov_t_subscribe(d.lcm, "POSE", on_pose, &d);
    int64_t end = marie_mono_us() + (int64_t)(timeout * 1e6);
    while (d.next < d.nwp && marie_mono_us() < end) {
        struct pollfd pfd = { .fd = lcm_get_fileno(d.lcm), .events = POLLIN };
        if (poll(&pfd, 1, 100) > 0)
            lcm_handle(d.lcm);
    }
    marie_motor_command_t stop = { .utime = 0, .v = 0, .omega = 0, .source = "route_driver" };
    marie_motor_command_t_publish(d.lcm, "MOTOR_COMMAND", &stop);
    for (int64_t until = marie_mono_us() + (int64_t)(hold * 1e6); marie_mono_us() < until;) {
        usleep(50000);
        marie_motor_command_t_publish(d.lcm, "MOTOR_COMMAND", &stop);
    }
    printf("ate_rms %.3f max %.3f poses %ld\n", d.npose ? sqrt(d.sum2 / d.npose) : -1.0, d.max, d.npose);
    printf("route %s (%d of %d waypoints)\n", d.next >= d.nwp ? "done" : "timeout", d.next, d.nwp);
    if (d.traj)
        fclose(d.traj);
    marie_pose_cov_t_unsubscribe(d.lcm, st);
    marie_pose_cov_t_unsubscribe(d.lcm, sp);
    lcm_destroy(d.lcm);
    return d.next >= d.nwp ? 0 : 1;
}
