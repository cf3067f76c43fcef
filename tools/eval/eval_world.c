/* eval_world: marie-eval's ground: the user's map, what the world has that the map lacks (boxes,
 * wall segments, drawn at random by the seed, nowhere near the start), a coarser map, and the
 * starts, goals and kidnappings picked on it. */
#include "tools/eval/eval.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "map/clearance.h"
#include "map/gridpath.h"

/* ---- random numbers (splitmix64) ---- */
static uint64_t rng_state;

void eval_rng_seed(uint64_t seed)
{
    rng_state = seed;
}

static uint64_t rng_next(void)
{
    uint64_t z = (rng_state += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

static double eval_rng_unit(void)
{
    return (double)(rng_next() >> 11) / 9007199254740992.0;
}

/* ---- cells ---- */
static int cell_of(const occmap_t *m, double x, double y)
{
    int cx, cy;
    return occmap_cell(m, x, y, &cx, &cy) ? cy * m->width + cx : -1;
}

static void center_of(const occmap_t *m, int c, double out[2])
{
    occmap_cell_center(m, c % m->width, c / m->width, &out[0], &out[1]);
}

static int random_cell(const occmap_t *m, const uint8_t *ok)
{
    for (int k = 0; k < 200000; k++) {
        int c = (int)(eval_rng_unit() * m->width * m->height);
        if (ok[c])
            return c;
    }
    return -1;
}

/* The passable cell of m nearest (x, y) within 0.5 m, or -1. */
static int nearest_ok(const occmap_t *m, const uint8_t *ok, double x, double y)
{
    int cx, cy, best = -1, r = (int)ceil(0.5 / m->resolution);
    if (!occmap_cell(m, x, y, &cx, &cy))
        return -1;
    double bd = INFINITY;
    for (int dy = -r; dy <= r; dy++)
        for (int dx = -r; dx <= r; dx++) {
            int xx = cx + dx, yy = cy + dy;
            if (xx < 0 || yy < 0 || xx >= m->width || yy >= m->height || !ok[yy * m->width + xx] || dx * dx + dy * dy >= bd)
                continue;
            bd = dx * dx + dy * dy;
            best = yy * m->width + xx;
        }
    return best;
}

/* ---- what the world has that the map lacks ---- */
static bool near_start(const eval_site_t *s, double x, double y)
{
    return hypot(x - s->start[0], y - s->start[1]) < 1.5;
}

/* Boxes of 0.3 to 0.8 m, each where the robot could drive (so on its ways, not in corners). */
static void draw_boxes(eval_site_t *s, int n)
{
    for (int k = 0, tries = 0; k < n && tries < 1000; tries++) {
        int c = random_cell(s->map, s->map_pass);
        double p[2], w = 0.3 + 0.5 * eval_rng_unit(), h = 0.3 + 0.5 * eval_rng_unit();
        if (c < 0)
            return;
        center_of(s->map, c, p);
        if (near_start(s, p[0], p[1]))
            continue;
        occmap_fill_rect(s->world, p[0] - w / 2, p[1] - h / 2, p[0] + w / 2, p[1] + h / 2, OCCMAP_OCCUPIED);
        k++;
    }
}

/* Wall segments 0.15 m thick, 1.5 to 4 m long, along x or y from a free spot, stopping at a wall
 * or the start's surroundings: partitions the map never had. */
static void draw_walls(eval_site_t *s, int n)
{
    const double t = 0.15, step = s->world->resolution / 2;
    for (int k = 0, tries = 0; k < n && tries < 1000; tries++) {
        int c = random_cell(s->map, s->map_pass);
        double p[2];
        if (c < 0)
            return;
        center_of(s->map, c, p);
        int dir = (int)(eval_rng_unit() * 4);
        double dx = dir == 0 ? 1 : dir == 1 ? -1 : 0, dy = dir == 2 ? 1 : dir == 3 ? -1 : 0;
        double len = 1.5 + 2.5 * eval_rng_unit(), l = 0;
        for (; l < len; l += step) {
            double x = p[0] + dx * l, y = p[1] + dy * l;
            if (near_start(s, x, y) || occmap_occupied_at(s->world, x, y))
                break;
        }
        if (l < 1.0)
            continue;
        double x1 = p[0] + dx * l, y1 = p[1] + dy * l;
        occmap_fill_rect(s->world, fmin(p[0], x1) - (dy ? t / 2 : 0), fmin(p[1], y1) - (dx ? t / 2 : 0),
                         fmax(p[0], x1) + (dy ? t / 2 : 0), fmax(p[1], y1) + (dx ? t / 2 : 0), OCCMAP_OCCUPIED);
        k++;
    }
}

/* ---- the site ---- */
static int grids(eval_site_t *s, double r_plan)
{
    free(s->map_pass), free(s->map_goal), free(s->world_pass), free(s->world_goal);
    s->map_pass = occmap_passable(s->map, r_plan, false);
    s->map_goal = occmap_passable(s->map, r_plan + 0.05, false);
    s->world_pass = occmap_passable(s->world, r_plan, false);
    s->world_goal = occmap_passable(s->world, r_plan + 0.05, false);
    return s->map_pass && s->map_goal && s->world_pass && s->world_goal ? 0 : -1;
}

static bool pick_start(eval_site_t *s)
{
    for (int k = 0; k < 1000; k++) {
        int c = random_cell(s->map, s->map_goal);
        if (c < 0)
            return false;
        double p[2];
        center_of(s->map, c, p);
        int wc = cell_of(s->world, p[0], p[1]);
        if (wc >= 0 && s->world_goal[wc]) {
            s->start[0] = p[0], s->start[1] = p[1], s->start[2] = (eval_rng_unit() * 2 - 1) * M_PI;
            return true;
        }
    }
    return false;
}

static int save(const occmap_t *m, const char *dir, const char *name, char *yaml, size_t len)
{
    snprintf(yaml, len, "%s/%s.yaml", dir, name);
    if (occmap_save(m, yaml) == 0)
        return 0;
    fprintf(stderr, "eval: cannot write %s\n", yaml);
    return -1;
}

int eval_site_make(eval_site_t *s, const eval_world_t *w, const eval_opts_t *o, const char *dir)
{
    memset(s, 0, sizeof *s);
    marie_errors_t errs = { 0 };
    s->world = occmap_load(w->yaml, &errs);
    if (!s->world) {
        fprintf(stderr, "eval: %s: %s\n", w->yaml, errs.n ? errs.msgs[0] : "cannot load");
        marie_errors_clear(&errs);
        return -1;
    }
    s->map = o->coarse > 0 ? occmap_coarsen(s->world, o->coarse) : occmap_clone(s->world);
    double r_plan = w->radius + w->clearance;
    if (!s->map || grids(s, r_plan) < 0 || !pick_start(s)) {
        fprintf(stderr, "eval: %s: no free start for a robot of %.2f m + %.2f m\n", w->name, w->radius, w->clearance);
        return -1;
    }
    draw_boxes(s, (int)o->boxes);
    draw_walls(s, (int)o->walls);
    if (grids(s, r_plan) < 0)
        return -1;
    snprintf(s->world_yaml, sizeof s->world_yaml, "%s", w->yaml);
    snprintf(s->map_yaml, sizeof s->map_yaml, "%s", w->yaml);
    if ((o->boxes || o->walls) && save(s->world, dir, "world", s->world_yaml, sizeof s->world_yaml) < 0)
        return -1;
    if (o->coarse > 0 && save(s->map, dir, "map", s->map_yaml, sizeof s->map_yaml) < 0)
        return -1;
    return 0;
}

void eval_site_free(eval_site_t *s)
{
    occmap_destroy(s->world);
    occmap_destroy(s->map);
    free(s->map_pass), free(s->map_goal), free(s->world_pass), free(s->world_goal);
    memset(s, 0, sizeof *s);
}

/* Length of the shortest path on m's passable grid between two cells, straightened; -1: none. */
static double shortest(const occmap_t *m, const uint8_t *pass, int from, int to)
{
    int *cells = NULL, nc = 0;
    if (gridpath_find(m->width, m->height, pass, from, to, &cells, &nc) < 0)
        return -1;
    nc = gridpath_shortcut(m->width, m->height, pass, cells, nc);
    double len = 0;
    for (int q = 0; q + 1 < nc; q++)
        len += hypot(cells[q + 1] % m->width - cells[q] % m->width, cells[q + 1] / m->width - cells[q] / m->width);
    free(cells);
    return len * m->resolution;
}

double eval_pick_goal(const eval_site_t *s, const double from[2], double goal[2])
{
    int mf = nearest_ok(s->map, s->map_pass, from[0], from[1]);
    int wf = nearest_ok(s->world, s->world_pass, from[0], from[1]);
    for (int t = 0; mf >= 0 && wf >= 0 && t < 500; t++) {
        int c = random_cell(s->map, s->map_goal);
        if (c < 0)
            return -1;
        double g[2];
        center_of(s->map, c, g);
        int wc = cell_of(s->world, g[0], g[1]);
        if (hypot(g[0] - from[0], g[1] - from[1]) < 2.0 || wc < 0 || !s->world_goal[wc])
            continue;
        double len = shortest(s->world, s->world_pass, wf, wc);
        if (len < 0 || shortest(s->map, s->map_pass, mf, c) < 0)
            continue;
        goal[0] = g[0], goal[1] = g[1];
        return len;
    }
    return -1;
}

double eval_pick_kidnap(const eval_site_t *s, const double from[2], const double goal[2], double pose[3])
{
    int wg = nearest_ok(s->world, s->world_pass, goal[0], goal[1]);
    for (int t = 0; wg >= 0 && t < 500; t++) {
        int c = random_cell(s->map, s->map_goal);
        if (c < 0)
            return -1;
        double p[2];
        center_of(s->map, c, p);
        int wc = cell_of(s->world, p[0], p[1]);
        if (hypot(p[0] - from[0], p[1] - from[1]) < 3.0 || wc < 0 || !s->world_goal[wc])
            continue;
        double len = shortest(s->world, s->world_pass, wc, wg);
        if (len < 0)
            continue;
        pose[0] = p[0], pose[1] = p[1], pose[2] = (eval_rng_unit() * 2 - 1) * M_PI;
        return len;
    }
    return -1;
}
