/* recovery: progress watch and the escalation ladder, as a pure function of each cycle. */
#include "adapters/behaviours/recovery.h"

#include <math.h>
#include <string.h>

void rec_params_default(rec_params_t *p)
{
    *p = (rec_params_t)REC_PARAMS_DEFAULTS;
}

void rec_state_reset(rec_state_t *s)
{
    memset(s, 0, sizeof *s);
    s->goal = -1;
}

const char *rec_stage_name(int stage)
{
    static const char *const n[] = { "none", "replan", "back_off", "rotate", "detour" };
    return stage >= 0 && stage <= REC_DETOUR ? n[stage] : "?";
}

/* Which side is more open, from the scan: +1 left, -1 right. */
static double open_side(const arb_inputs_t *in)
{
    double l = 0, r = 0;
    for (int k = 0; in->ranges && k < in->nranges; k++) {
        double x = in->ranges[k];
        if (!isfinite(x) || x <= in->range_min)
            continue;
        x = fmin(fmin(x, in->range_max), 3.0);
        if (in->angle_min + k * in->angle_increment > 0)
            l += x;
        else
            r += x;
    }
    return l >= r ? 1 : -1;
}

/* What is left to drive: from the nearest point of the path to its end, along it. A winding path
 * (a maze) takes the robot away from its goal for a while, which is still progress. */
static double remaining(const arb_inputs_t *in)
{
    const double *P = in->path;
    int n = in->npath, best = 0;
    double bd = INFINITY, bt = 0;
    for (int i = 0; i + 1 < n; i++) {
        double ax = P[3 * i], ay = P[3 * i + 1], dx = P[3 * i + 3] - ax, dy = P[3 * i + 4] - ay;
        double l2 = dx * dx + dy * dy, t = l2 > 0 ? ((in->pose[0] - ax) * dx + (in->pose[1] - ay) * dy) / l2 : 0;
        t = t < 0 ? 0 : t > 1 ? 1 : t;
        double d = hypot(ax + t * dx - in->pose[0], ay + t * dy - in->pose[1]);
        if (d < bd) {
            bd = d;
            best = i;
            bt = t;
        }
    }
    if (n < 2)
        return hypot(P[0] - in->pose[0], P[1] - in->pose[1]);
    double left = bd;
    for (int i = best; i + 1 < n; i++) {
        double seg = hypot(P[3 * i + 3] - P[3 * i], P[3 * i + 4] - P[3 * i + 1]);
        left += i == best ? (1 - bt) * seg : seg;
    }
    return left;
}

/* Keeps the returns of each new scan that lie within a metre of the robot, in the map frame: one
 * per 5 cm (a return near one kept renews it), the oldest given up for a new one. */
static void remember(rec_state_t *s, double now_s, const arb_params_t *ap, const arb_inputs_t *in)
{
    if (!in->ranges || in->scan_age < 0 || in->scan_age > ap->stale_scan_s || in->pose_age < 0 ||
        in->pose_age > ap->stale_pose_s || !isfinite(in->pose[0]) || !isfinite(in->pose[1]) || !isfinite(in->pose[2]))
        return;
    double t = now_s - in->scan_age;
    if (fabs(t - s->last_scan_t) < 1e-6)
        return;                 /* this scan is already in */
    s->last_scan_t = t;
    double c = cos(in->pose[2]), sn = sin(in->pose[2]);
    for (int k = 0; k < in->nranges; k++) {
        double r = in->ranges[k];
        if (!isfinite(r) || r <= in->range_min || r >= fmin(in->range_max, 1.0))
            continue;
        double a = in->angle_min + k * in->angle_increment, lx = r * cos(a), ly = r * sin(a);
        float x = (float)(in->pose[0] + c * lx - sn * ly), y = (float)(in->pose[1] + sn * lx + c * ly);
        int slot = 0;
        bool kept = false;
        for (int i = 0; i < REC_SEEN_MAX && !kept; i++) {
            float dx = s->seen[i][0] - x, dy = s->seen[i][1] - y;
            if (s->seen_t[i] > 0 && dx * dx + dy * dy < 0.05f * 0.05f) {
                s->seen_t[i] = t;
                kept = true;
            } else if (s->seen_t[i] < s->seen_t[slot]) {
                slot = i;
            }
        }
        if (kept)
            continue;
        s->seen[slot][0] = x;
        s->seen[slot][1] = y;
        s->seen_t[slot] = t;
    }
}

/* Whether a remembered return lies behind the robot, within its width (half_width each side)
 * and less than backoff_clearance behind its footprint. */
static bool blocked_behind(const rec_state_t *s, double now_s, const rec_params_t *p, const arb_params_t *ap,
                           const arb_inputs_t *in)
{
    double c = cos(in->pose[2]), sn = sin(in->pose[2]), hw = ap->half_width;
    for (int i = 0; i < REC_SEEN_MAX; i++) {
        if (s->seen_t[i] <= 0 || now_s - s->seen_t[i] > p->memory_s)
            continue;
        double dx = s->seen[i][0] - in->pose[0], dy = s->seen[i][1] - in->pose[1];
        double x = c * dx + sn * dy, y = -sn * dx + c * dy;
        if (x < 0 && x > -(hw + p->backoff_clearance) && fabs(y) < hw)
            return true;
    }
    return false;
}

int rec_step(const rec_params_t *p, rec_state_t *s, double now_s, const arb_params_t *ap, const arb_inputs_t *in,
             int win, const arb_vote_t votes[ARB_COUNT], double *v, double *omega, bool *replan)
{
    *replan = false;
    remember(s, now_s, ap, in);
    bool following = in->path && in->npath > 0 && in->path_status == 0 && votes[ARB_FOLLOW].active;
    if (p->stuck_s <= 0 || win == ARB_ESTOP || win == ARB_TELEOP || !in->path || in->npath <= 0 || in->pose_age < 0) {
        s->stage = REC_NONE;
        s->best_t = now_s;
        return REC_NONE;
    }
    double ex = in->path[3 * (in->npath - 1)], ey = in->path[3 * (in->npath - 1) + 1];
    double d = remaining(in), d_end = hypot(ex - in->pose[0], ey - in->pose[1]);
    if (in->path_goal != s->goal || fabs(ex - s->end[0]) > 0.5 || fabs(ey - s->end[1]) > 0.5) {
        /* A new goal starts with a clean slate; a replanned path for the same goal keeps the level. */
        if (in->path_goal != s->goal)
            s->level = 0;
        s->goal = in->path_goal;
        s->end[0] = ex;
        s->end[1] = ey;
        s->best = d;
        s->best_t = now_s;
    }
    if (s->stage == REC_NONE) {
        if (!following && win != ARB_AVOID) {
            s->best_t = now_s;          /* idle or done: nothing to watch */
            return REC_NONE;
        }
        if (d < s->best - p->min_progress) {
            s->best = d;
            s->best_t = now_s;
        }
        if (now_s - s->best_t < p->stuck_s)
            return REC_NONE;
        s->recoveries++;
        if (s->level < p->max_level)
            s->level++;
        s->stage = REC_REPLAN;
        s->stage_end = now_s + 1.0;
        *replan = true;
    }
    /* Advance through the ladder; a back-off ends (or is skipped) where it would reach what is
     * behind. */
    for (;;) {
        if (s->stage == REC_BACKOFF && now_s < s->stage_end && blocked_behind(s, now_s, p, ap, in)) {
            s->stage_end = now_s;
            s->backoffs_cut++;
        }
        if (s->stage == REC_NONE || now_s < s->stage_end)
            break;
        switch (s->stage) {
        case REC_REPLAN:
            s->stage = REC_BACKOFF;
            s->stage_end = now_s + p->backoff_s;
            break;
        case REC_BACKOFF: {
            /* Head for a point past the trouble: towards the goal, and off to whichever side of
             * that line the scan finds more open, the further the more recoveries it took. */
            double ux = (ex - in->pose[0]) / fmax(d_end, 1e-6), uy = (ey - in->pose[1]) / fmax(d_end, 1e-6);
            double side = open_side(in), h = in->pose[2];
            double lx = -sin(h) * side, ly = cos(h) * side;          /* the open side, in the map */
            double sgn = (-uy * lx + ux * ly) >= 0 ? 1 : -1;          /* ... left or right of the line */
            double ahead = fmin(p->detour_ahead, d_end), off = p->detour_side * s->level;
            s->target[0] = in->pose[0] + ux * ahead - uy * sgn * off;
            s->target[1] = in->pose[1] + uy * ahead + ux * sgn * off;
            s->stage = REC_ROTATE;
            s->stage_end = now_s + p->rotate_s;
            break;
        }
        case REC_ROTATE:
            s->stage = REC_DETOUR;
            s->stage_end = now_s + p->detour_s * s->level;
            break;
        default:
            s->stage = REC_NONE;
            s->best = d;                /* judge progress afresh from here */
            s->best_t = now_s;
            return REC_NONE;
        }
    }
    double herr = 0, tdist = 0;
    if (s->stage == REC_ROTATE || s->stage == REC_DETOUR) {
        double tx = s->target[0] - in->pose[0], ty = s->target[1] - in->pose[1];
        herr = remainder(atan2(ty, tx) - in->pose[2], 2 * M_PI);
        tdist = hypot(tx, ty);
        if (s->stage == REC_ROTATE && fabs(herr) < 0.2) {
            s->stage = REC_DETOUR;      /* facing it: go */
            s->stage_end = now_s + p->detour_s * s->level;
        }
        if (s->stage == REC_DETOUR && tdist < 0.3) {
            s->stage = REC_NONE;
            s->best = d;
            s->best_t = now_s;
            return REC_NONE;
        }
    }
    switch (s->stage) {
    case REC_REPLAN:
        *v = 0;
        *omega = 0;
        break;
    case REC_BACKOFF:
        *v = -p->backoff_v;
        *omega = 0;
        break;
    case REC_ROTATE:
        *v = 0;
        *omega = (herr > 0 ? 1 : -1) * fmin(ap->omega_max * 0.7, fmax(0.3, fabs(herr)));
        break;
    default:
        /* Drive to the target; avoid steers round what is ahead and stops short of it. */
        if (votes[ARB_AVOID].active) {
            *v = votes[ARB_AVOID].v;
            *omega = votes[ARB_AVOID].omega;
        } else if (fabs(herr) > 1.0) {
            *v = 0;
            *omega = (herr > 0 ? 0.7 : -0.7) * ap->omega_max;
        } else {
            *v = 0.6 * ap->v_max * (1 - fabs(herr) / 1.5);
            *omega = fmax(-ap->omega_max, fmin(ap->omega_max, 1.5 * herr));
        }
        break;
    }
    return s->stage;
}
