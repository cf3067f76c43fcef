/* trajeval: ATE after a rigid SE(2) alignment, and relation errors over lengths of path. */
#include "map/trajeval.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"

static double wrap(double a) { return atan2(sin(a), cos(a)); }

/* b seen from a. */
static traj_pose_t between(const traj_pose_t *a, const traj_pose_t *b)
{
    double c = cos(a->th), s = sin(a->th), dx = b->x - a->x, dy = b->y - a->y;
    return (traj_pose_t){ b->utime, c * dx + s * dy, -s * dx + c * dy, wrap(b->th - a->th) };
}

size_t trajeval_pair(const traj_pose_t *est, size_t n_est, const traj_pose_t *ref, size_t n_ref, int64_t max_gap_us,
                     traj_pose_t *est_out, traj_pose_t *ref_out)
{
    size_t n = 0, k = 0;
    for (size_t i = 0; i < n_est && n_ref; i++) {
        int64_t t = est[i].utime;
        while (k + 1 < n_ref && ref[k + 1].utime <= t)
            k++;
        traj_pose_t r;
        if (ref[k].utime == t) {
            r = ref[k];
        } else if (ref[k].utime < t && k + 1 < n_ref && ref[k + 1].utime - ref[k].utime <= max_gap_us) {
            double w = (double)(t - ref[k].utime) / (double)(ref[k + 1].utime - ref[k].utime);
            r = (traj_pose_t){ t, ref[k].x + w * (ref[k + 1].x - ref[k].x), ref[k].y + w * (ref[k + 1].y - ref[k].y),
                               wrap(ref[k].th + w * wrap(ref[k + 1].th - ref[k].th)) };
        } else {
            continue;
        }
        est_out[n] = est[i];
        ref_out[n++] = r;
    }
    return n;
}

/* The rotation and translation that best put est onto ref in the least-squares sense (Umeyama's
 * closed form, without scale, in the plane). */
static void align(const traj_pose_t *est, const traj_pose_t *ref, size_t n, double out[3])
{
    double ex = 0, ey = 0, rx = 0, ry = 0;
    for (size_t i = 0; i < n; i++) {
        ex += est[i].x, ey += est[i].y, rx += ref[i].x, ry += ref[i].y;
    }
    ex /= (double)n, ey /= (double)n, rx /= (double)n, ry /= (double)n;
    double sxx = 0, sxy = 0, syx = 0, syy = 0;
    for (size_t i = 0; i < n; i++) {
        double ax = est[i].x - ex, ay = est[i].y - ey, bx = ref[i].x - rx, by = ref[i].y - ry;
        sxx += ax * bx, sxy += ax * by, syx += ay * bx, syy += ay * by;
    }
    double th = atan2(sxy - syx, sxx + syy), c = cos(th), s = sin(th);
    out[0] = rx - (c * ex - s * ey);
    out[1] = ry - (s * ex + c * ey);
    out[2] = th;
}

/* Each pose i with the first j whose reference path from i reaches dist: the motion from i to j
 * as estimated against the reference's. */
static void relations(const traj_pose_t *est, const traj_pose_t *ref, const double *cum, size_t n, double dist,
                      trajeval_rel_t *r)
{
    memset(r, 0, sizeof *r);
    r->dist = dist;
    size_t j = 0;
    double ts = 0, rs = 0;
    for (size_t i = 0; i < n; i++) {
        if (j <= i)
            j = i + 1;
        while (j < n && cum[j] - cum[i] < dist - 1e-9)
            j++;
        if (j >= n)
            break;
        traj_pose_t de = between(&est[i], &est[j]), dr = between(&ref[i], &ref[j]);
        traj_pose_t e = between(&dr, &de);
        double t = hypot(e.x, e.y), a = fabs(e.th);
        ts += t, rs += a;
        r->trans_max = fmax(r->trans_max, t);
        r->rot_max = fmax(r->rot_max, a);
        r->n++;
    }
    if (r->n) {
        r->trans_mean = ts / (double)r->n;
        r->rot_mean = rs / (double)r->n;
    }
}

int trajeval_run(const traj_pose_t *est, const traj_pose_t *ref, size_t n, const double *dists, int ndist,
                 trajeval_t *out)
{
    memset(out, 0, sizeof *out);
    if (n < 2 || ndist < 0 || ndist > TRAJEVAL_MAX_REL)
        return marie_fail(EINVAL);
    for (int k = 0; k < ndist; k++)
        if (!(dists[k] > 0))
            return marie_fail(EINVAL);
    out->pairs = n;
    align(est, ref, n, out->align);
    double c = cos(out->align[2]), s = sin(out->align[2]), se = 0;
    for (size_t i = 0; i < n; i++) {
        double x = out->align[0] + c * est[i].x - s * est[i].y, y = out->align[1] + s * est[i].x + c * est[i].y;
        double e = hypot(x - ref[i].x, y - ref[i].y);
        se += e * e;
        out->ate_max = fmax(out->ate_max, e);
    }
    out->ate_rms = sqrt(se / (double)n);
    double *cum = malloc(n * sizeof *cum);
    if (!cum)
        return marie_fail(ENOMEM);
    cum[0] = 0;
    for (size_t i = 1; i < n; i++)
        cum[i] = cum[i - 1] + hypot(ref[i].x - ref[i - 1].x, ref[i].y - ref[i - 1].y);
    out->path = cum[n - 1];
    out->nrel = ndist;
    for (int k = 0; k < ndist; k++)
        relations(est, ref, cum, n, dists[k], &out->rel[k]);
    free(cum);
    return 0;
}
