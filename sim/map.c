/* map: a decoded PGM to an occupancy grid (map_server's trinary rule), walls to rectangles. */
#include "sim/map.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

sim_map_t *sim_map_from_pgm(const sim_pgm_t *pgm, const sim_map_info_t *info)
{
    sim_map_t *m = calloc(1, sizeof(*m));
    if (!m)
        return NULL;
    m->width = pgm->width;
    m->height = pgm->height;
    m->resolution = info->resolution;
    m->origin_x = info->origin[0];
    m->origin_y = info->origin[1];
    m->origin_yaw = info->origin[2];
    m->cells = malloc((size_t)m->width * m->height);
    if (!m->cells) {
        free(m);
        return NULL;
    }
    for (int row = 0; row < pgm->height; row++) {
        int j = pgm->height - 1 - row;  /* image top row is the map's last row */
        for (int i = 0; i < pgm->width; i++) {
            double v = (double)pgm->pixels[(size_t)row * pgm->width + i] / pgm->maxval;
            double p = info->negate ? v : 1.0 - v;     /* probability of being occupied */
            int8_t c = SIM_MAP_UNKNOWN;
            if (p > info->occupied_thresh)
                c = SIM_MAP_OCCUPIED;
            else if (p < info->free_thresh)
                c = SIM_MAP_FREE;
            m->cells[(size_t)j * m->width + i] = c;
        }
    }
    return m;
}

void sim_map_destroy(sim_map_t *m)
{
    if (!m)
        return;
    free(m->cells);
    free(m);
}

void sim_map_cell_center(const sim_map_t *m, int i, int j, double *x, double *y)
{
    double lx = (i + 0.5) * m->resolution, ly = (j + 0.5) * m->resolution;
    double c = cos(m->origin_yaw), s = sin(m->origin_yaw);
    *x = m->origin_x + c * lx - s * ly;
    *y = m->origin_y + s * lx + c * ly;
}

long sim_map_rects(const sim_map_t *m, sim_rect_t **out)
{
    size_t cap = 256, n = 0;
    sim_rect_t *r = malloc(cap * sizeof(*r));
    /* open[k]: index in r of the rectangle still growing upward whose run starts at column k */
    long *open = malloc((size_t)m->width * sizeof(*open));
    long *next = malloc((size_t)m->width * sizeof(*next));
    if (!r || !open || !next)
        goto nomem;
    for (int i = 0; i < m->width; i++)
        open[i] = -1;
    for (int j = 0; j < m->height; j++) {
        for (int i = 0; i < m->width; i++)
            next[i] = -1;
        int i = 0;
        while (i < m->width) {
            if (sim_map_cell(m, i, j) != SIM_MAP_OCCUPIED) {
                i++;
                continue;
            }
            int i0 = i;
            while (i < m->width && sim_map_cell(m, i, j) == SIM_MAP_OCCUPIED)
                i++;
            long k = open[i0];
            if (k >= 0 && r[k].w == i - i0 && r[k].j + r[k].h == j) {
                r[k].h++;               /* the same run as the row below: stack it */
            } else {
                if (n == cap) {
                    sim_rect_t *g = realloc(r, 2 * cap * sizeof(*r));
                    if (!g)
                        goto nomem;
                    r = g;
                    cap *= 2;
                }
                r[n] = (sim_rect_t){ i0, j, i - i0, 1 };
                k = (long)n++;
            }
            next[i0] = k;
        }
        long *t = open;
        open = next;
        next = t;
    }
    free(open);
    free(next);
    *out = r;
    return (long)n;
nomem:
    free(r);
    free(open);
    free(next);
    return -ENOMEM;
}
