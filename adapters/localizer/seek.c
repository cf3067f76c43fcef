/* seek: the lost robot's search: turn, search the map, take a clear answer or drive on and turn
 * again, give up after a few places. */
#include "adapters/localizer/seek.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

static double wrap(double a)
{
    return atan2(sin(a), cos(a));
}

int seek_init(seek_t *s, const seek_params_t *p, const double laser_mount[3])
{
    memset(s, 0, sizeof *s);
    s->p = *p;
    memcpy(s->mount, laser_mount, sizeof s->mount);
    s->cloud = reloc_cloud_create();
    return s->cloud ? 0 : -1;
}

void seek_free(seek_t *s)
{
    reloc_cloud_destroy(s->cloud);
    s->cloud = NULL;
    s->phase = SEEK_OFF;
}

static void enter(seek_t *s, seek_phase_t phase, double now_s)
{
    s->phase = phase;
    s->phase_s = now_s;
    s->turned = 0;
    s->verified = s->doubts = 0;
}

static void start_turn(seek_t *s, const double odom[3], double now_s);

void seek_begin(seek_t *s, const double odom[3], double now_s)
{
    memcpy(s->last_odom, odom, sizeof s->last_odom);
    s->attempts = 0;
    s->searches = 0;
    s->nprev = 0;
    s->turn_dir = 1;
    start_turn(s, odom, now_s);
}

void seek_end(seek_t *s)
{
    s->phase = SEEK_OFF;
}

bool seek_active(const seek_t *s)
{
    return s->phase != SEEK_OFF;
}

const char *seek_doing(const seek_t *s)
{
    static const char *const what[] = { "tracking", "turning on the spot to see all around",
                                        "turning towards an open side", "driving to another place",
                                        "checking the place found", "waiting for a pose (INITIALPOSE)" };
    return what[s->phase];
}

/* The third nearest return to the robot's centre within `half` rad of straight ahead (all:
 * M_PI): a stray reading or two does not make a wall. */
static double nearest(const seek_t *s, const mcl_scan_t *scan, double half)
{
    double best[3] = { INFINITY, INFINITY, INFINITY };
    for (int k = 0; k < scan->n; k++) {
        double r = scan->ranges[k], a = scan->angle_min + k * scan->angle_increment + s->mount[2];
        if (!isfinite(r) || r <= scan->range_min || r >= scan->range_max || fabs(wrap(a)) > half)
            continue;
        double d = hypot(s->mount[0] + r * cos(a), s->mount[1] + r * sin(a));
        for (int i = 0; i < 3; i++)
            if (d < best[i]) {
                double t = best[i];
                best[i] = d;
                d = t;
            }
    }
    return best[2];
}

/* The robot-frame heading of the scan's most open side: the beam whose neighbours (10 each way)
 * all reach farthest. */
static double most_open(const seek_t *s, const mcl_scan_t *scan)
{
    double best = -1, at = 0;
    for (int k = 0; k < scan->n; k++) {
        double low = INFINITY;
        for (int j = k - 10; j <= k + 10; j++) {
            double r = j >= 0 && j < scan->n && isfinite(scan->ranges[j]) ? scan->ranges[j] : 0;
            low = fmin(low, r <= scan->range_min ? scan->range_max : r);
        }
        if (low > best) {
            best = low;
            at = scan->angle_min + k * scan->angle_increment + s->mount[2];
        }
    }
    return at;
}

/* Where to drive when two places fit alike (the robot now at a or at b): the robot-frame heading,
 * of 16, that the map leaves free from both for the drive and whose end shows the two places most
 * apart (36 rays from each end, 8 m, compared). The scan's most open side when none does (a
 * place that is its own mirror image). */
static double telling_heading(const seek_t *s, const mcl_t *f, const mcl_scan_t *scan, const double a[3],
                              const double b[3])
{
    double best = 0, at = most_open(s, scan), reach = s->p.drive_distance + s->p.robot_radius + 0.3;
    for (int k = 0; k < 16; k++) {
        double d = -M_PI + k * M_PI / 8, la = a[2] + d, lb = b[2] + d, diff = 0;
        if (mcl_trace(f, a[0], a[1], la, reach) < reach || mcl_trace(f, b[0], b[1], lb, reach) < reach)
            continue;
        double ea[2] = { a[0] + s->p.drive_distance * cos(la), a[1] + s->p.drive_distance * sin(la) };
        double eb[2] = { b[0] + s->p.drive_distance * cos(lb), b[1] + s->p.drive_distance * sin(lb) };
        for (int j = 0; j < 36; j++)
            diff += fabs(mcl_trace(f, ea[0], ea[1], la + j * M_PI / 18, 8) - mcl_trace(f, eb[0], eb[1], lb + j * M_PI / 18, 8));
        if (diff > best + 1.0) {        /* a metre of difference over the 36 rays, at least */
            best = diff;
            at = d;
        }
    }
    return at;
}

/* Why no place was taken, for the operator. */
static void say_why(const seek_out_t *o, const seek_params_t *p, char *why, size_t len)
{
    if (o->nhyp == 0)
        snprintf(why, len, "nothing seen to search with");
    else if (o->best.hit < p->min_hit || o->best.contradiction > p->max_contradiction)
        snprintf(why, len, "no place of the map fits: the best, (%.2f, %.2f), puts %.0f%% of the points on walls",
                 o->best_now[0], o->best_now[1], 100 * o->best.hit);
    else
        snprintf(why, len, "several places fit alike: the robot at (%.2f, %.2f) or where (%.2f, %.2f, %.2f) puts "
                 "this turn's start, %.3f apart (%.3f needed)", o->best_now[0], o->best_now[1], o->second.x,
                 o->second.y, o->second.theta, o->best_total - o->second_total, p->margin);
}

/* Each place's evidence: its score, plus what the place it continues (the last search's, moved
 * by the odometry between the two turns) had gathered. A place no earlier one leads to starts
 * below all of them. Sorts h by it, best first. */
static void add_evidence(seek_t *s, reloc_hyp_t *h, double *total, int n)
{
    double floor = INFINITY, step[3];
    for (int i = 0; i < s->nprev; i++)
        floor = fmin(floor, s->prev_total[i]);
    floor = s->nprev ? floor - s->p.margin : 0;
    double c = cos(-s->prev_odom[2]), sn = sin(-s->prev_odom[2]);
    double dx = s->origin_odom[0] - s->prev_odom[0], dy = s->origin_odom[1] - s->prev_odom[1];
    step[0] = c * dx - sn * dy;
    step[1] = sn * dx + c * dy;
    step[2] = wrap(s->origin_odom[2] - s->prev_odom[2]);
    for (int j = 0; j < n; j++) {
        total[j] = h[j].score + floor;
        for (int i = 0; i < s->nprev; i++) {
            const reloc_hyp_t *q = &s->prev[i];
            double px = q->x + cos(q->theta) * step[0] - sin(q->theta) * step[1];
            double py = q->y + sin(q->theta) * step[0] + cos(q->theta) * step[1];
            if (hypot(px - h[j].x, py - h[j].y) < 1.0 && fabs(wrap(q->theta + step[2] - h[j].theta)) < 0.35)
                total[j] = fmax(total[j], h[j].score + s->prev_total[i]);
        }
    }
    for (int j = 1; j < n; j++)             /* insertion sort by total */
        for (int k = j; k > 0 && total[k] > total[k - 1]; k--) {
            reloc_hyp_t th = h[k];
            double tt = total[k];
            h[k] = h[k - 1], total[k] = total[k - 1];
            h[k - 1] = th, total[k - 1] = tt;
        }
    memcpy(s->prev, h, sizeof(reloc_hyp_t) * (size_t)n);
    memcpy(s->prev_total, total, sizeof(double) * (size_t)n);
    memcpy(s->prev_odom, s->origin_odom, sizeof s->prev_odom);
    s->nprev = n;
}

static void search(seek_t *s, mcl_t *f, const double odom[3], const mcl_scan_t *scan, double now_s, seek_out_t *out)
{
    reloc_hyp_t h[SEEK_HYPS];
    double total[SEEK_HYPS];
    int n = reloc_search(f, s->cloud, h, SEEK_HYPS);
    s->searches++;
    out->event = SEEK_SEARCHED;
    out->nhyp = n > 0 ? n : 0;
    if (n > 0) {
        add_evidence(s, h, total, n);
        out->best = h[0];
        out->second = n > 1 ? h[1] : h[0];
        out->best_total = total[0];
        out->second_total = n > 1 ? total[1] : -INFINITY;
        reloc_cloud_pose_now(s->cloud, (const double[3]){ h[0].x, h[0].y, h[0].theta }, odom, out->best_now);
    }
    bool clear = n > 0 && h[0].hit >= s->p.min_hit && h[0].contradiction <= s->p.max_contradiction &&
                 (n == 1 || total[0] - total[1] >= s->p.margin);
    if (clear) {
        mcl_init_pose(f, out->best_now, (const double[3]){ 0.1, 0.1, 0.05 });
        enter(s, SEEK_VERIFY, now_s);
        return;
    }
    say_why(out, &s->p, out->why, sizeof out->why);
    if (++s->attempts > s->p.attempts) {
        enter(s, SEEK_ASK, now_s);
        out->event = SEEK_GAVE_UP;
        return;
    }
    double other[3];
    reloc_cloud_pose_now(s->cloud, (const double[3]){ out->second.x, out->second.y, out->second.theta }, odom, other);
    s->face = wrap(odom[2] + (n > 1 ? telling_heading(s, f, scan, out->best_now, other) : most_open(s, scan)));
    enter(s, SEEK_FACE, now_s);
}

/* A turn starts a frame of its own: turning on the spot, odometry hardly drifts within it. */
static void start_turn(seek_t *s, const double odom[3], double now_s)
{
    reloc_cloud_reset(s->cloud, odom);
    memcpy(s->origin_odom, odom, sizeof s->origin_odom);
    enter(s, SEEK_TURN, now_s);
}

static void turn(seek_t *s, mcl_t *f, const double odom[3], const mcl_scan_t *scan, double now_s, seek_out_t *out)
{
    bool round = s->turned >= 2 * M_PI - 0.1;
    bool stuck = now_s - s->phase_s > 3 * 2 * M_PI / fmax(s->p.turn_speed, 0.05) + 5;   /* not turning */
    bool cramped = nearest(s, scan, M_PI) < s->p.robot_radius + 0.02;
    if (round || stuck || cramped) {
        search(s, f, odom, scan, now_s, out);
        return;
    }
    out->move = true;
    out->omega = s->turn_dir * s->p.turn_speed;
}

static void face(seek_t *s, const double odom[3], double now_s, seek_out_t *out)
{
    double err = wrap(s->face - odom[2]);
    if (fabs(err) < 0.15 || now_s - s->phase_s > 20) {
        s->drive_from[0] = odom[0];
        s->drive_from[1] = odom[1];
        enter(s, SEEK_DRIVE, now_s);
        return;
    }
    out->move = true;
    out->omega = err > 0 ? s->p.turn_speed : -s->p.turn_speed;
}

static void drive(seek_t *s, const double odom[3], const mcl_scan_t *scan, double now_s, seek_out_t *out)
{
    double gone = hypot(odom[0] - s->drive_from[0], odom[1] - s->drive_from[1]);
    bool blocked = nearest(s, scan, 0.5) < s->p.robot_radius + 0.35;
    bool late = now_s - s->phase_s > 2 * s->p.drive_distance / fmax(s->p.drive_speed, 0.05) + 5;
    if (gone >= s->p.drive_distance || blocked || late) {
        start_turn(s, odom, now_s);
        return;
    }
    out->move = true;
    out->v = s->p.drive_speed;
    out->omega = fmax(-0.3, fmin(0.3, 0.8 * wrap(s->face - odom[2])));
}

static void verify(seek_t *s, mcl_t *f, const double odom[3], double now_s, seek_out_t *out)
{
    out->update_filter = true;
    if (now_s == s->phase_s)
        return;                 /* the filter has not seen a scan from the place found yet */
    mcl_fit_t fit;
    double pose[3], cov[9];
    mcl_last_fit(f, &fit, NULL, NULL);
    if (fit.contradiction <= s->p.max_contradiction)
        s->verified++;
    else
        s->doubts++;
    if (s->verified >= s->p.verify_updates) {
        mcl_pose_at(f, odom, pose, cov);
        memcpy(out->best_now, pose, sizeof pose);
        out->event = SEEK_FOUND;
        s->phase = SEEK_OFF;
    } else if (s->doubts >= 3) {
        /* The place found does not hold: start over from here. */
        s->nprev = 0;
        start_turn(s, odom, now_s);
        out->update_filter = false;
    }
}

void seek_step(seek_t *s, mcl_t *f, const double odom[3], const mcl_scan_t *scan, double now_s, seek_out_t *out)
{
    memset(out, 0, sizeof *out);
    if (s->phase == SEEK_OFF || s->phase == SEEK_ASK)
        return;
    if (s->phase != SEEK_VERIFY)
        reloc_cloud_add(s->cloud, odom, s->mount, scan);
    s->turned += fabs(wrap(odom[2] - s->last_odom[2]));
    memcpy(s->last_odom, odom, sizeof s->last_odom);
    switch (s->phase) {
    case SEEK_TURN: turn(s, f, odom, scan, now_s, out); break;
    case SEEK_FACE: face(s, odom, now_s, out); break;
    case SEEK_DRIVE: drive(s, odom, scan, now_s, out); break;
    case SEEK_VERIFY: verify(s, f, odom, now_s, out); break;
    default: break;
    }
}
