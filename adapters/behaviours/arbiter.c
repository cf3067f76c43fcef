/* arbiter: behaviours as pure functions of one cycle's inputs, and their priority arbitration. */
#include "adapters/behaviours/arbiter.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include "core/log.h"

static const char *const names[ARB_COUNT] = { "estop", "avoid", "teleop", "relocalize", "face_speaker", "follow_path",
                                               "idle" };

void arb_params_default(arb_params_t *p)
{
    *p = (arb_params_t)ARB_PARAMS_DEFAULTS;
}

static int priority(const arb_params_t *p, int behaviour)
{
    switch (behaviour) {
    case ARB_ESTOP: return (int)p->priority_estop;
    case ARB_AVOID: return (int)p->priority_avoid;
    case ARB_TELEOP: return (int)p->priority_teleop;
    case ARB_RELOC: return (int)p->priority_relocalize;
    case ARB_FACE: return (int)p->priority_face;
    case ARB_FOLLOW: return (int)p->priority_follow;
    default: return 0;
    }
}

void arb_state_reset(arb_state_t *s)
{
    memset(s, 0, sizeof(*s));
    s->path_goal = -1;
    s->face_done = -1;
}

static double clamp(double x, double lo, double hi)
{
    return x < lo ? lo : x > hi ? hi : x;
}

static void vote(arb_vote_t *o, bool active, double v, double w, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
static void vote(arb_vote_t *o, bool active, double v, double w, const char *fmt, ...)
{
    o->active = active;
    o->v = v;
    o->omega = w;
    MARIE_VFORMAT(o->reason, fmt);
}

static bool fresh(double age, double limit)
{
    return age >= 0 && (limit <= 0 || age <= limit);
}

static void arb_estop(const arb_params_t *p, const arb_inputs_t *in, arb_vote_t *o)
{
    if (in->estop_age >= 0 && in->estop_pressed)
        vote(o, true, 0, 0, "pressed");
    else if (p->estop_required && !fresh(in->estop_age, p->stale_estop_s))
        vote(o, true, 0, 0, in->estop_age < 0 ? "no e-stop state" : "e-stop state stale");
    else
        vote(o, false, 0, 0, "released");
}

static void arb_teleop(const arb_params_t *p, const arb_inputs_t *in, arb_vote_t *o)
{
    if (fresh(in->teleop_age, p->teleop_timeout_s) && isfinite(in->teleop_v) && isfinite(in->teleop_omega))
        vote(o, true, clamp(in->teleop_v, -p->v_max, p->v_max), clamp(in->teleop_omega, -p->omega_max, p->omega_max),
             "operator");
    else
        vote(o, false, 0, 0, in->teleop_age < 0 ? "no operator" : "operator idle");
}

/* The lost localizer turns the robot on the spot to see all around, and drives it to another
 * place when where it stands is ambiguous (adapters/localizer/seek.h). */
static void arb_reloc(const arb_params_t *p, const arb_inputs_t *in, arb_vote_t *o)
{
    if (fresh(in->reloc_age, p->relocalize_timeout_s) && isfinite(in->reloc_v) && isfinite(in->reloc_omega))
        vote(o, true, clamp(in->reloc_v, -p->v_max, p->v_max), clamp(in->reloc_omega, -p->omega_max, p->omega_max),
             "lost: the localizer searches");
    else
        vote(o, false, 0, 0, "localized");
}

static void arb_avoid(const arb_params_t *p, const arb_inputs_t *in, arb_vote_t *o)
{
    if (!in->ranges || in->nranges <= 0 || !fresh(in->scan_age, p->stale_scan_s)) {
        vote(o, false, 0, 0, "no fresh scan");
        return;
    }
    /* Nearest return inside the corridor the robot sweeps when driving straight on, and
     * which side is more open (sum of clear distance left vs right). */
    double ahead = INFINITY, ahead_y = 0, open_l = 0, open_r = 0;
    for (int k = 0; k < in->nranges; k++) {
        double r = in->ranges[k];
        if (!isfinite(r) || r <= in->range_min)
            continue;
        double a = in->angle_min + k * in->angle_increment;
        double rr = r > in->range_max ? in->range_max : r;
        if (a > 0)
            open_l += fmin(rr, 2.0);
        else
            open_r += fmin(rr, 2.0);
        if (r >= in->range_max)
            continue;
        double x = r * cos(a), y = r * sin(a);
        if (x > 0 && fabs(y) < p->half_width && x < ahead) {
            ahead = x;
            ahead_y = y;
        }
    }
    o->aside = false;
    if (ahead >= p->slow_distance) {
        vote(o, false, 0, 0, "clear %.2f m", isfinite(ahead) ? ahead : -1.0);
        return;
    }
    /* Straight ahead, turn to the more open side; off to one side (a corner's wall beside the
     * robot), turn away from it: the robot then passes it. */
    double turn = open_l >= open_r ? p->avoid_omega : -p->avoid_omega;
    if (fabs(ahead_y) > p->half_width / 2) {
        turn = ahead_y > 0 ? -p->avoid_omega : p->avoid_omega;
        o->aside = true;
    }
    if (ahead <= p->stop_distance) {
        vote(o, true, 0, turn, "blocked at %.2f m", ahead);
        return;
    }
    double f = (ahead - p->stop_distance) / (p->slow_distance - p->stop_distance);
    vote(o, true, 0.5 * p->v_max * f, turn * (1 - f), "obstacle at %.2f m", ahead);
}

/* Turns on the spot toward the last speaker once: when faced (or too late) the request is
 * over, so the path that the speaker's command brings can turn the robot away again. */
static void arb_face(const arb_params_t *p, arb_state_t *s, const arb_inputs_t *in, arb_vote_t *o)
{
    if (in->face_id <= 0 || !isfinite(in->face_heading)) {
        vote(o, false, 0, 0, "no speaker");
        return;
    }
    if (in->face_id == s->face_done || !fresh(in->face_age, p->face_timeout_s)) {
        vote(o, false, 0, 0, in->face_id == s->face_done ? "speaker faced" : "speaker heard too long ago");
        return;
    }
    if (!fresh(in->pose_age, p->stale_pose_s) || !isfinite(in->pose[2])) {
        vote(o, false, 0, 0, "no pose");
        return;
    }
    double err = remainder(in->face_heading - in->pose[2], 2 * M_PI);
    if (fabs(err) < p->face_tolerance) {
        s->face_done = in->face_id;
        vote(o, false, 0, 0, "speaker faced");
        return;
    }
    /* Brisk while far off, no slower than 0.3 rad/s near the end so it does not creep. */
    double w = clamp(1.5 * err, -p->omega_max, p->omega_max);
    if (fabs(w) < 0.3)
        w = err > 0 ? 0.3 : -0.3;
    vote(o, true, 0, w, "turning to speaker (%.0f deg)", err * 180 / M_PI);
}

/* m along the path: this close, a corner counts as reached and the walk goes round it. */
#define CORNER_REACHED 0.05
/* rad: at a corner, the heading error left when the robot stops turning on the spot. */
#define CORNER_FACED 0.3

void arb_follow(const arb_params_t *p, arb_state_t *s, const arb_inputs_t *in, arb_vote_t *o)
{
    if (!in->path || in->npath <= 0 || !fresh(in->path_age, p->stale_path_s)) {
        vote(o, false, 0, 0, "no path");
        return;
    }
    if (in->path_status != 0) {
        vote(o, false, 0, 0, "path status %d", in->path_status);
        return;
    }
    if (!fresh(in->pose_age, p->stale_pose_s)) {
        vote(o, false, 0, 0, in->pose_age < 0 ? "no pose" : "pose stale %.1f s", in->pose_age);
        return;
    }
    for (int i = 0; i < 3 * in->npath; i++)
        if (!isfinite(in->path[i])) {
            vote(o, false, 0, 0, "path has non-finite poses");
            return;
        }
    if (!isfinite(in->pose[0]) || !isfinite(in->pose[1]) || !isfinite(in->pose[2])) {
        vote(o, false, 0, 0, "pose not finite");
        return;
    }
    const double *P = in->path;
    int n = in->npath;
    double ex = P[3 * (n - 1)], ey = P[3 * (n - 1) + 1];
    if (s->path_goal != in->path_goal || s->npath != n || s->path_end[0] != ex || s->path_end[1] != ey) {
        s->path_goal = in->path_goal;
        s->npath = n;
        s->path_end[0] = ex;
        s->path_end[1] = ey;
        s->progress = 0;
        s->done = false;
    }
    double x = in->pose[0], y = in->pose[1], th = in->pose[2];
    double to_end = hypot(ex - x, ey - y);
    if (s->done || to_end < p->goal_tolerance) {
        s->done = true;
        vote(o, false, 0, 0, "path done");
        return;
    }
    /* Closest point on the segments from the progress index on (never back along the path). */
    int best = s->progress;
    double bd = INFINITY, bt = 0;
    for (int i = s->progress; i < n - 1; i++) {
        double ax = P[3 * i], ay = P[3 * i + 1], bx = P[3 * i + 3], by = P[3 * i + 4];
        double dx = bx - ax, dy = by - ay, l2 = dx * dx + dy * dy;
        double t = l2 > 0 ? clamp(((x - ax) * dx + (y - ay) * dy) / l2, 0, 1) : 0;
        double d = hypot(ax + t * dx - x, ay + t * dy - y);
        if (d < bd) { bd = d; best = i; bt = t; }
    }
    s->progress = best;
    /* Walk the lookahead distance along the path from the closest point. A sharp corner ends
     * the walk: pure pursuit would cut it, and the path (planned on the inflated map) keeps
     * the footprint off the wall only at the corner itself. The robot drives to it, slowing,
     * and when there turns towards the next leg. */
    double gx = ex, gy = ey, to_corner = INFINITY;
    bool at_corner = false;
    if (n > 1) {
        double need = p->lookahead, walked = 0;
        double cx = P[3 * best] + bt * (P[3 * best + 3] - P[3 * best]);
        double cy = P[3 * best + 1] + bt * (P[3 * best + 4] - P[3 * best + 1]);
        need = sqrt(fmax(0, need * need - bd * bd));  /* the look-ahead circle meets the path here */
        double heading = atan2(P[3 * best + 4] - P[3 * best + 1], P[3 * best + 3] - P[3 * best]);
        for (int i = best; i < n - 1; i++) {
            double nx = P[3 * i + 3], ny = P[3 * i + 4];
            double seg = hypot(nx - cx, ny - cy);
            if (seg >= need) {
                gx = cx + (nx - cx) * (seg > 0 ? need / seg : 0);
                gy = cy + (ny - cy) * (seg > 0 ? need / seg : 0);
                break;
            }
            walked += seg;
            if (p->corner_angle > 0 && i + 2 < n) {
                /* A corner may be one vertex (a grid path) or a few close ones (a sampled,
                 * shortcut path): the turn counts from the heading of the leg being driven. */
                double a1 = atan2(P[3 * i + 7] - ny, P[3 * i + 6] - nx);
                bool turns = fabs(remainder(a1 - heading, 2 * M_PI)) > p->corner_angle;
                if (walked <= CORNER_REACHED) {
                    /* At this corner already: the next leg is driven, once faced. */
                    at_corner = at_corner || turns;
                    heading = a1;
                } else if (turns) {
                    gx = nx;
                    gy = ny;
                    to_corner = walked;
                    break;
                }
            }
            need -= seg;
            cx = nx;
            cy = ny;
        }
    }
    double dx = gx - x, dy = gy - y;
    double lx = cos(th) * dx + sin(th) * dy, ly = -sin(th) * dx + cos(th) * dy;
    double herr = atan2(ly, lx);
    /* At a corner the robot turns on the spot until it faces the next leg: steering round
     * from there would swing it towards the corner's inner wall. */
    if (fabs(herr) > (at_corner ? CORNER_FACED : p->turn_in_place)) {
        vote(o, true, 0, herr > 0 ? p->omega_max * 0.7 : -p->omega_max * 0.7, "turning to path (%.0f deg)",
             herr * 180 / M_PI);
        return;
    }
    double L2 = lx * lx + ly * ly;
    double k = L2 > 1e-9 ? 2 * ly / L2 : 0;      /* pure pursuit curvature */
    /* Slow down while the look-ahead point is off to the side, but keep turning briskly:
     * the turn rate is the curvature at no less than a walking pace. */
    double v = p->v_max * clamp(1 - fabs(herr) / p->turn_in_place, 0.15, 1.0);
    v = fmin(v, fmax(0.1, 0.8 * to_end));       /* ease into the goal */
    v = fmin(v, fmax(0.08, 0.8 * to_corner));   /* ... and into a corner */
    double w = k * fmax(v, 0.3);
    if (fabs(w) > p->omega_max) {
        v *= p->omega_max / fabs(w);
        w = w > 0 ? p->omega_max : -p->omega_max;
    }
    vote(o, true, v, w, "pursuit %d/%d, %.1f m to go", best + 1, n, to_end);
}

int arb_decide(const arb_params_t *p, arb_state_t *s, const arb_inputs_t *in, arb_vote_t votes[ARB_COUNT])
{
    for (int b = 0; b < ARB_COUNT; b++) {
        votes[b].name = names[b];
        votes[b].priority = priority(p, b);
    }
    arb_estop(p, in, &votes[ARB_ESTOP]);
    arb_avoid(p, in, &votes[ARB_AVOID]);
    arb_teleop(p, in, &votes[ARB_TELEOP]);
    arb_reloc(p, in, &votes[ARB_RELOC]);
    arb_face(p, s, in, &votes[ARB_FACE]);
    arb_follow(p, s, in, &votes[ARB_FOLLOW]);
    vote(&votes[ARB_IDLE], true, 0, 0, "nothing to do");
    int win = ARB_IDLE, below = ARB_IDLE;     /* below: the winner if avoid abstained */
    for (int b = 0; b < ARB_COUNT; b++) {
        if (votes[b].active && (!votes[win].active || votes[b].priority > votes[win].priority))
            win = b;
        if (b != ARB_AVOID && votes[b].active && (!votes[below].active || votes[b].priority > votes[below].priority))
            below = b;
    }
    /* Avoid keeps the robot from driving into things; turning in place cannot (the base is
     * round), so avoid does not veto a behaviour that only turns. Otherwise the two fight
     * for ever beside a wall when a new path starts behind the robot: follow turns towards
     * it, which brings the wall ahead, avoid turns back to the open side, and so on. */
    if (win == ARB_AVOID && below != ARB_IDLE && votes[below].v == 0 && votes[below].omega != 0)
        win = below;
    /* Avoid knows what is near, the path (planned on the inflated map) which way is open: at a
     * corridor's corner the more open side of the scan is often the wrong one. Avoid keeps its
     * speed; it turns the way the path goes when the path clearly turns, unless what is in
     * the way is off to one side (turning towards the path would turn into it). */
    if (win == ARB_AVOID && !votes[ARB_AVOID].aside && votes[ARB_FOLLOW].active &&
        fabs(votes[ARB_FOLLOW].omega) > 0.2 && votes[ARB_AVOID].omega * votes[ARB_FOLLOW].omega < 0)
        votes[ARB_AVOID].omega = -votes[ARB_AVOID].omega;
    return win;
}
