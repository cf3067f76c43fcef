/* mapeval: a built map against the world it was built in. */
#include "map/mapeval.h"

#include <math.h>
#include <stdlib.h>

/* map_server's trinary reading of a built map's cell. */
static int mapeval_class(int8_t v)
{
    return v < 0 || v > 100 ? -1 : v >= 65 ? 1 : v < 20 ? 0 : -1;
}

static int mapeval_at(const occmap_t *m, double x, double y)
{
    int cx, cy;
    if (!occmap_cell(m, x, y, &cx, &cy))
        return -1;
    return mapeval_class(occmap_get(m, cx, cy));
}

/* Whether grid g has a cell of class k within one cell of the point (x, y). */
static int mapeval_near(const occmap_t *g, double x, double y, int k)
{
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++)
            if (mapeval_at(g, x + dx * g->resolution, y + dy * g->resolution) == k)
                return 1;
    return 0;
}

/* A rigid transform of the built map's frame into the world's (rotation th about the origin,
 * then dx, dy): the comparison moves points, never the grid, which a rotation would resample. */
typedef struct {
    double c, s, dx, dy;
} frame_t;

static void to_world(const frame_t *f, double x, double y, double *wx, double *wy)
{
    *wx = f->c * x - f->s * y + f->dx;
    *wy = f->s * x + f->c * y + f->dy;
}

/* The class of the built map's cell under world point (x, y). */
static int built_at(const occmap_t *map, const frame_t *f, double x, double y)
{
    x -= f->dx;
    y -= f->dy;
    return mapeval_at(map, f->c * x + f->s * y, -f->s * x + f->c * y);
}

/* Whether the built map has a cell of class k within one cell of world point (x, y). */
static int built_near(const occmap_t *map, const frame_t *f, double x, double y, int k)
{
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++)
            if (built_at(map, f, x + dx * map->resolution, y + dy * map->resolution) == k)
                return 1;
    return 0;
}

static void compare_in(const occmap_t *truth, const occmap_t *map, const frame_t *f, double sx, double sy, mapeval_t *e)
{
    long tp = 0, nocc = 0, walls = 0, found = 0, nfree = 0, covered = 0;
    for (int y = 0; y < map->height; y++)
        for (int x = 0; x < map->width; x++) {
            if (mapeval_class(map->cells[(size_t)y * map->width + x]) != 1)
                continue;
            double px, py;
            occmap_cell_center(map, x, y, &px, &py);
            to_world(f, px, py, &px, &py);
            nocc++;
            tp += mapeval_near(truth, px, py, 1);
        }
    int W = truth->width, H = truth->height;
    unsigned char *reach = calloc((size_t)W * H, 1);
    int *stack = malloc(sizeof(int) * (size_t)W * H);
    int sp = 0, cx, cy;
    if (reach && stack && occmap_cell(truth, sx, sy, &cx, &cy) && occmap_get(truth, cx, cy) == OCCMAP_FREE) {
        reach[cy * W + cx] = 1;
        stack[sp++] = cy * W + cx;
        while (sp) {
            int i = stack[--sp], x = i % W, y = i / W;
            const int nb[4][2] = { { 1, 0 }, { -1, 0 }, { 0, 1 }, { 0, -1 } };
            for (int k = 0; k < 4; k++) {
                int u = x + nb[k][0], v = y + nb[k][1];
                if (occmap_get(truth, u, v) == OCCMAP_FREE && !reach[v * W + u]) {
                    reach[v * W + u] = 1;
                    stack[sp++] = v * W + u;
                }
            }
        }
    }
    for (int y = 0; y < H && reach; y++)
        for (int x = 0; x < W; x++) {
            double px, py;
            occmap_cell_center(truth, x, y, &px, &py);
            int8_t t = truth->cells[(size_t)y * W + x];
            if (reach[y * W + x]) {
                nfree++;
                covered += built_at(map, f, px, py) == 0;
            }
            if (t != OCCMAP_OCCUPIED)
                continue;
            const int nb[4][2] = { { 1, 0 }, { -1, 0 }, { 0, 1 }, { 0, -1 } };
            int visible = 0;
            for (int k = 0; k < 4 && !visible; k++) {
                int u = x + nb[k][0], v = y + nb[k][1];
                double qx, qy;
                occmap_cell_center(truth, u, v, &qx, &qy);
                visible = occmap_get(truth, u, v) == OCCMAP_FREE && built_at(map, f, qx, qy) == 0;
            }
            if (!visible)
                continue;
            walls++;
            found += built_near(map, f, px, py, 1);
        }
    free(reach);
    free(stack);
    e->map_occupied = nocc;
    e->truth_walls = walls;
    e->truth_free = nfree;
    e->precision = nocc ? (double)tp / nocc : 0;
    e->recall = walls ? (double)found / walls : 0;
    e->coverage = nfree ? (double)covered / nfree : 0;
}

void mapeval_compare(const occmap_t *truth, const occmap_t *map, double sx, double sy, mapeval_t *e)
{
    compare_in(truth, map, &(frame_t){ 1, 0, 0, 0 }, sx, sy, e);
}

/* Alignment: every rotation in 0.0025 rad steps, every shift in cells, counted against the world's
 * walls dilated by one cell. Ties (a shift within one cell keeps a cell "near" its wall) go to
 * the transform that puts more cells on the walls themselves, then to the smallest one: a map
 * that is right is not moved. The best one goes to *odx, *ody, *oth: 0, or -1 when out of memory. */
static int best_alignment(const occmap_t *truth, const occmap_t *map, double max_xy, double max_th, double *odx,
                          double *ody, double *oth)
{
    int W = truth->width, H = truth->height;
    unsigned char *near = calloc((size_t)W * H, 1);
    double *px = malloc(sizeof(double) * 2 * (size_t)map->width * map->height);
    if (!near || !px) {
        free(near);
        free(px);
        return -1;
    }
    /* 2: a wall cell, 1: within one cell of one */
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            if (truth->cells[(size_t)y * W + x] == OCCMAP_OCCUPIED)
                for (int dy = -1; dy <= 1; dy++)
                    for (int dx = -1; dx <= 1; dx++)
                        if (x + dx >= 0 && y + dy >= 0 && x + dx < W && y + dy < H)
                            near[(size_t)(y + dy) * W + x + dx] = 1;
    for (int i = 0; i < W * H; i++)
        if (truth->cells[i] == OCCMAP_OCCUPIED)
            near[i] = 2;
    long n = 0;
    for (int y = 0; y < map->height; y++)
        for (int x = 0; x < map->width; x++)
            if (mapeval_class(map->cells[(size_t)y * map->width + x]) == 1) {
                occmap_cell_center(map, x, y, &px[2 * n], &px[2 * n + 1]);
                n++;
            }
    long best = -1, best_on = -1;
    double best_size = INFINITY, r = truth->resolution;
    *odx = *ody = *oth = 0;
    for (double th = -max_th; th <= max_th + 1e-9; th += 0.0025) {
        double c = cos(th), sn = sin(th);
        for (double dy = -max_xy; dy <= max_xy + 1e-9; dy += r)
            for (double dx = -max_xy; dx <= max_xy + 1e-9; dx += r) {
                long hits = 0, on = 0;
                for (long i = 0; i < n; i++) {
                    double x = c * px[2 * i] - sn * px[2 * i + 1] + dx, y = sn * px[2 * i] + c * px[2 * i + 1] + dy;
                    int cx = (int)floor((x - truth->origin_x) / r), cy = (int)floor((y - truth->origin_y) / r);
                    int k = cx >= 0 && cy >= 0 && cx < W && cy < H ? near[(size_t)cy * W + cx] : 0;
                    hits += k > 0;
                    on += k == 2;
                }
                double size = fabs(dx) + fabs(dy) + fabs(th) * 10;   /* 0.1 rad weighs as 1 m */
                if (hits > best || (hits == best && (on > best_on || (on == best_on && size < best_size - 1e-9)))) {
                    best = hits;
                    best_on = on;
                    best_size = size;
                    *odx = dx, *ody = dy, *oth = th;
                }
            }
    }
    free(near);
    free(px);
    return 0;
}

occmap_t *mapeval_align(const occmap_t *truth, const occmap_t *map, double max_xy, double max_th,
                        double *odx, double *ody, double *oth)
{
    if (best_alignment(truth, map, max_xy, max_th, odx, ody, oth) < 0)
        return NULL;
    double c = cos(*oth), sn = sin(*oth);
    return occmap_from_cells(map->width, map->height, map->resolution, c * map->origin_x - sn * map->origin_y + *odx,
                             sn * map->origin_x + c * map->origin_y + *ody, *oth, map->cells);
}

int mapeval_judge(const occmap_t *truth, const occmap_t *map, double sx, double sy, mapeval_judgement_t *j)
{
    *j = (mapeval_judgement_t){ 0 };
    mapeval_compare(truth, map, sx, sy, &j->raw);
    if (best_alignment(truth, map, 0.5, 0.03, &j->dx, &j->dy, &j->th) < 0)
        return -1;
    compare_in(truth, map, &(frame_t){ cos(j->th), sin(j->th), j->dx, j->dy }, sx, sy, &j->aligned);
    return 0;
}
