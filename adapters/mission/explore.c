/* explore: frontier detection and ranking for the explore mission (docs/mapping.md). */
#include "adapters/mission/explore.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/buf.h"
#include "core/err.h"

enum { C_UNKNOWN = 0, C_FREE = 1, C_OCC = 2 };

void explore_params_default(explore_params_t *p)
{
    *p = (explore_params_t)EXPLORE_PARAMS_DEFAULTS;
}

static int cell_class(int8_t v)
{
    return v >= 0 && v < 20 ? C_FREE : v >= 65 && v <= 100 ? C_OCC : C_UNKNOWN;
}

/* The passable cells: known free with no occupied cell within the robot's radius. */
static unsigned char *passable(const occmap_t *m, double radius)
{
    size_t n = (size_t)m->width * m->height;
    unsigned char *ok = malloc(n);
    if (!ok)
        return NULL;
    for (size_t i = 0; i < n; i++)
        ok[i] = cell_class(m->cells[i]) == C_FREE;
    int r = (int)ceil(radius / m->resolution);
    for (int y = 0; y < m->height; y++)
        for (int x = 0; x < m->width; x++) {
            if (cell_class(m->cells[(size_t)y * m->width + x]) != C_OCC)
                continue;
            for (int dy = -r; dy <= r; dy++)
                for (int dx = -r; dx <= r; dx++) {
                    int u = x + dx, v = y + dy;
                    if (dx * dx + dy * dy <= r * r && u >= 0 && v >= 0 && u < m->width && v < m->height)
                        ok[(size_t)v * m->width + u] = 0;
                }
        }
    return ok;
}

/* Breadth-first distances (cells, 4-connected) from the passable cell nearest (rx, ry) within
 * one robot radius; parents for the way back. -1 with errno ENOENT when there is none. */
static int reach(const occmap_t *m, const unsigned char *ok, double rx, double ry, double radius, int *dist, int *parent)
{
    int W = m->width, H = m->height, cx, cy, start = -1;
    for (size_t i = 0; i < (size_t)W * H; i++)
        dist[i] = -1;
    if (!occmap_cell(m, rx, ry, &cx, &cy))
        return marie_fail(ENOENT);
    int r = (int)ceil(radius / m->resolution) + 1, best = INT32_MAX;
    for (int dy = -r; dy <= r; dy++)
        for (int dx = -r; dx <= r; dx++) {
            int u = cx + dx, v = cy + dy;
            if (u >= 0 && v >= 0 && u < W && v < H && ok[(size_t)v * W + u] && dx * dx + dy * dy < best) {
                best = dx * dx + dy * dy;
                start = v * W + u;
            }
        }
    if (start < 0)
        return marie_fail(ENOENT);
    int *queue = malloc(sizeof(int) * (size_t)W * H);
    if (!queue)
        return -1;
    int head = 0, tail = 0;
    dist[start] = 0;
    parent[start] = -1;
    queue[tail++] = start;
    while (head < tail) {
        int i = queue[head++], x = i % W, y = i / W;
        const int nb[4][2] = { { 1, 0 }, { -1, 0 }, { 0, 1 }, { 0, -1 } };
        for (int k = 0; k < 4; k++) {
            int u = x + nb[k][0], v = y + nb[k][1];
            if (u < 0 || v < 0 || u >= W || v >= H)
                continue;
            int j = v * W + u;
            if (ok[j] && dist[j] < 0) {
                dist[j] = dist[i] + 1;
                parent[j] = i;
                queue[tail++] = j;
            }
        }
    }
    free(queue);
    return start;
}

static int by_cost(const void *a, const void *b)
{
    double x = ((const explore_frontier_t *)a)->cost, y = ((const explore_frontier_t *)b)->cost;
    return x < y ? -1 : x > y;
}

static bool unknown_next(const occmap_t *m, int x, int y)
{
    const int nb[4][2] = { { 1, 0 }, { -1, 0 }, { 0, 1 }, { 0, -1 } };
    for (int k = 0; k < 4; k++) {
        int u = x + nb[k][0], v = y + nb[k][1];
        if (u >= 0 && v >= 0 && u < m->width && v < m->height && cell_class(m->cells[(size_t)v * m->width + u]) == C_UNKNOWN)
            return true;
    }
    return false;
}

/* Group the reachable frontier cells (8-connected) and rank the groups. */
static int cluster(const occmap_t *m, const explore_params_t *p, const int *dist, const double *black, int nblack,
                   explore_frontier_t *out, int max)
{
    int W = m->width, H = m->height, found = 0;
    size_t n = (size_t)W * H;
    unsigned char *fr = calloc(n, 1);
    int *stack = malloc(sizeof(int) * n), *members = malloc(sizeof(int) * n);
    explore_frontier_t *all = NULL;
    int nall = 0;
    size_t cap = 0;
    if (!fr || !stack || !members)
        goto out;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            fr[(size_t)y * W + x] = dist[(size_t)y * W + x] >= 0 && unknown_next(m, x, y);
    for (size_t s = 0; s < n; s++) {
        if (fr[s] != 1)
            continue;
        int sp = 0, nm = 0;
        double sx = 0, sy = 0;
        fr[s] = 2;
        stack[sp++] = (int)s;
        while (sp) {
            int i = stack[--sp], x = i % W, y = i / W;
            members[nm++] = i;
            sx += x;
            sy += y;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int u = x + dx, v = y + dy;
                    if (u >= 0 && v >= 0 && u < W && v < H && fr[(size_t)v * W + u] == 1) {
                        fr[(size_t)v * W + u] = 2;
                        stack[sp++] = v * W + u;
                    }
                }
        }
        if (nm < p->min_cells)
            continue;
        sx /= nm;
        sy /= nm;
        int goal = members[0];
        double bd = INFINITY;
        for (int k = 0; k < nm; k++) {
            double d = hypot(members[k] % W - sx, members[k] / W - sy);
            if (d < bd) {
                bd = d;
                goal = members[k];
            }
        }
        explore_frontier_t f;
        occmap_cell_center(m, goal % W, goal / W, &f.x, &f.y);
        bool banned = false;
        for (int b = 0; b < nblack && !banned; b++)
            banned = hypot(black[2 * b] - f.x, black[2 * b + 1] - f.y) < p->blacklist_radius;
        if (banned)
            continue;
        f.cells = nm;
        f.path_m = dist[goal] * m->resolution;
        f.cost = f.path_m - p->info_weight * nm * m->resolution;
        if (MARIE_GROW(all, cap, (size_t)nall + 1) < 0)
            goto out;
        all[nall++] = f;
    }
    found = nall;
    if (nall > 0) {             /* no frontier: `all` was never allocated */
        qsort(all, (size_t)nall, sizeof(*all), by_cost);
        memcpy(out, all, sizeof(*all) * (size_t)(nall < max ? nall : max));
    }
out:
    free(fr);
    free(stack);
    free(members);
    free(all);
    return found;
}

/* The clearances to try, in order (the count): robot_radius, then escape_radius. A robot that
 * drove through a gap narrower than twice robot_radius (the planner keeps less) into a spot
 * walled in at that clearance, behind a box, saw nothing reachable and called the exploration
 * done with a third of the office unseen. */
static int clearances(const explore_params_t *p, double r[2])
{
    r[0] = p->robot_radius;
    r[1] = p->escape_radius;
    return p->escape_radius > 0 && p->escape_radius < p->robot_radius ? 2 : 1;
}

/* reach() at a clearance, the passable cells made for it: 0, 1 when the robot stands on
 * nothing passable, or -1 with errno ENOMEM. */
static int reach_at(const occmap_t *m, double radius, double rx, double ry, int *dist, int *parent)
{
    unsigned char *ok = passable(m, radius);
    if (!ok)
        return marie_fail(ENOMEM);
    int rc = reach(m, ok, rx, ry, radius, dist, parent) < 0 ? 1 : 0;
    free(ok);
    return rc;
}

int explore_frontiers(const occmap_t *m, const explore_params_t *p, double rx, double ry, const double *blacklist,
                      int nblack, explore_frontier_t *out, int max)
{
    if (!m || !p || !out || max < 0 || m->width <= 0 || m->height <= 0 || !(m->resolution > 0) || !isfinite(rx) ||
        !isfinite(ry))
        return marie_fail(EINVAL);
    size_t n = (size_t)m->width * m->height;
    int *dist = malloc(sizeof(int) * n), *parent = malloc(sizeof(int) * n);
    int found = -1;
    if (!dist || !parent) {
        errno = ENOMEM;
        goto out;
    }
    double radii[2];
    int tries = clearances(p, radii);
    found = 0;
    for (int t = 0; t < tries && found == 0; t++) {
        int rc = reach_at(m, radii[t], rx, ry, dist, parent);
        if (rc < 0) {
            found = -1;
            break;
        }
        /* the robot on nothing passable: nothing it can reach */
        found = rc ? 0 : cluster(m, p, dist, blacklist, nblack, out, max);
    }
out:
    free(dist);
    free(parent);
    return found;
}

int explore_path(const occmap_t *m, const explore_params_t *p, double rx, double ry, double gx, double gy, double *xy,
                 int max)
{
    if (!m || !p || !xy || max < 2)
        return marie_fail(EINVAL);
    size_t n = (size_t)m->width * m->height;
    int *dist = malloc(sizeof(int) * n), *parent = malloc(sizeof(int) * n);
    int count = -1, gcx, gcy;
    if (!dist || !parent) {
        errno = ENOMEM;
        goto out;
    }
    if (!occmap_cell(m, gx, gy, &gcx, &gcy)) {
        errno = ENOENT;
        goto out;
    }
    /* At the clearances explore_frontiers() tries, in the same order. */
    double radii[2];
    int tries = clearances(p, radii), reached = 0;
    for (int t = 0; t < tries && !reached; t++) {
        int rc = reach_at(m, radii[t], rx, ry, dist, parent);
        if (rc < 0)
            goto out;
        reached = rc == 0 && dist[(size_t)gcy * m->width + gcx] >= 0;
    }
    if (!reached) {
        errno = ENOENT;
        goto out;
    }
    int len = dist[(size_t)gcy * m->width + gcx] + 1;
    /* Every cell of the way, or evenly spaced ones when max is short; the goal is always last. */
    int step = (len + max - 1) / max;
    count = (len - 1) / step + 1;
    for (int idx = len - 1, i = gcy * m->width + gcx; i >= 0 && idx >= 0; idx--, i = parent[i])
        if (idx % step == 0)
            occmap_cell_center(m, i % m->width, i / m->width, &xy[2 * (idx / step)], &xy[2 * (idx / step) + 1]);
    occmap_cell_center(m, gcx, gcy, &xy[2 * (count - 1)], &xy[2 * (count - 1) + 1]);
out:
    free(dist);
    free(parent);
    return count;
}
