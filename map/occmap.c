/* occmap: occupancy grid storage, ray casting and generated test worlds. */
#include "map/occmap.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

occmap_t *occmap_create(int width, int height, double resolution, double origin_x, double origin_y)
{
    if (width <= 0 || height <= 0 || !(resolution > 0) || (size_t)width * height > (1u << 28)) {
        errno = EINVAL;
        return NULL;
    }
    occmap_t *m = calloc(1, sizeof(*m));
    if (!m)
        return NULL;
    m->cells = calloc((size_t)width * height, 1);
    if (!m->cells) {
        free(m);
        return NULL;
    }
    m->width = width;
    m->height = height;
    m->resolution = resolution;
    m->origin_x = origin_x;
    m->origin_y = origin_y;
    return m;
}

void occmap_destroy(occmap_t *m)
{
    if (!m)
        return;
    free(m->cells);
    free(m);
}

occmap_t *occmap_clone(const occmap_t *m)
{
    occmap_t *c = occmap_create(m->width, m->height, m->resolution, m->origin_x, m->origin_y);
    if (c)
        memcpy(c->cells, m->cells, (size_t)m->width * m->height);
    return c;
}

bool occmap_occupied_at(const occmap_t *m, double x, double y)
{
    int cx, cy;
    if (!occmap_cell(m, x, y, &cx, &cy))
        return true;
    return m->cells[(size_t)cy * m->width + cx] == OCCMAP_OCCUPIED;
}

bool occmap_footprint_clear(const occmap_t *m, double x, double y, double th, double lx, double ly)
{
    int cx, cy;
    if (!occmap_cell(m, x, y, &cx, &cy) || occmap_get(m, cx, cy) != OCCMAP_FREE)
        return false;
    /* Sample the rectangle at half a cell: every cell it overlaps is visited. */
    double c = cos(th), s = sin(th), step = m->resolution / 2;
    for (double u = -lx / 2; u <= lx / 2 + 1e-9; u += step)
        for (double v = -ly / 2; v <= ly / 2 + 1e-9; v += step)
            if (occmap_occupied_at(m, x + c * u - s * v, y + s * u + c * v))
                return false;
    return true;
}

/* Every cell within r cells of (cx, cy) is known free. */
static bool disk_free(const occmap_t *m, int cx, int cy, int r)
{
    for (int dy = -r; dy <= r; dy++)
        for (int dx = -r; dx <= r; dx++)
            if (dx * dx + dy * dy <= r * r && occmap_get(m, cx + dx, cy + dy) != OCCMAP_FREE)
                return false;
    return true;
}

int occmap_nearest_clear(const occmap_t *m, double x, double y, double radius, double *ox, double *oy)
{
    int x0 = (int)floor((x - m->origin_x) / m->resolution), y0 = (int)floor((y - m->origin_y) / m->resolution);
    int r = (int)ceil(radius / m->resolution), far = m->width + m->height;
    /* Square rings around the start: a cell of ring k is at least k cells away, so the search
     * ends at the first ring farther than the best cell found. */
    double best = INFINITY;
    for (int ring = 0; ring <= far && ring <= best; ring++)
        for (int dy = -ring; dy <= ring; dy++)
            for (int dx = -ring; dx <= ring; dx++) {
                if (abs(dx) != ring && abs(dy) != ring)
                    continue;
                double d = hypot(dx, dy);
                if (d < best && disk_free(m, x0 + dx, y0 + dy, r)) {
                    best = d;
                    occmap_cell_center(m, x0 + dx, y0 + dy, ox, oy);
                }
            }
    if (best < INFINITY)
        return 0;
    errno = ENOENT;
    return -1;
}

occmap_t *occmap_coarsen(const occmap_t *m, double res)
{
    if (!(res >= m->resolution)) {
        errno = EINVAL;
        return NULL;
    }
    int w = (int)ceil(m->width * m->resolution / res - 1e-9), h = (int)ceil(m->height * m->resolution / res - 1e-9);
    occmap_t *c = occmap_create(w, h, res, m->origin_x, m->origin_y);
    if (!c)
        return NULL;
    for (int y = 0; y < m->height; y++)
        for (int x = 0; x < m->width; x++) {
            int cx = (int)((x + 0.5) * m->resolution / res), cy = (int)((y + 0.5) * m->resolution / res);
            int8_t v = m->cells[(size_t)y * m->width + x], *to = &c->cells[(size_t)cy * w + cx];
            if (v == OCCMAP_OCCUPIED)
                *to = OCCMAP_OCCUPIED;
            else if (v != OCCMAP_FREE && *to == OCCMAP_FREE)
                *to = OCCMAP_UNKNOWN;
        }
    return c;
}

void occmap_fill_rect(occmap_t *m, double x0, double y0, double x1, double y1, int8_t value)
{
    if (x1 < x0) { double t = x0; x0 = x1; x1 = t; }
    if (y1 < y0) { double t = y0; y0 = y1; y1 = t; }
    int c0 = (int)floor((x0 - m->origin_x) / m->resolution), c1 = (int)floor((x1 - m->origin_x) / m->resolution);
    int r0 = (int)floor((y0 - m->origin_y) / m->resolution), r1 = (int)floor((y1 - m->origin_y) / m->resolution);
    if (c0 < 0) c0 = 0;
    if (r0 < 0) r0 = 0;
    if (c1 >= m->width) c1 = m->width - 1;
    if (r1 >= m->height) r1 = m->height - 1;
    for (int r = r0; r <= r1; r++)
        for (int c = c0; c <= c1; c++)
            m->cells[(size_t)r * m->width + c] = value;
}

double occmap_raycast(const occmap_t *m, double x, double y, double angle, double max_range)
{
    /* Grid traversal (Amanatides & Woo) in cell units: exact first hit, no step size. */
    double res = m->resolution;
    double fx = (x - m->origin_x) / res, fy = (y - m->origin_y) / res;
    double dx = cos(angle), dy = sin(angle);
    int cx = (int)floor(fx), cy = (int)floor(fy);
    int sx = dx > 0 ? 1 : -1, sy = dy > 0 ? 1 : -1;
    double tdx = dx != 0 ? fabs(1.0 / dx) : INFINITY, tdy = dy != 0 ? fabs(1.0 / dy) : INFINITY;
    double tx = dx > 0 ? (cx + 1 - fx) * tdx : dx < 0 ? (fx - cx) * tdx : INFINITY;
    double ty = dy > 0 ? (cy + 1 - fy) * tdy : dy < 0 ? (fy - cy) * tdy : INFINITY;
    double tmax = max_range / res, t = 0;
    while (t <= tmax) {
        if (cx < 0 || cy < 0 || cx >= m->width || cy >= m->height ||
            m->cells[(size_t)cy * m->width + cx] == OCCMAP_OCCUPIED)
            return t * res < max_range ? t * res : max_range;
        if (tx < ty) { t = tx; tx += tdx; cx += sx; }
        else { t = ty; ty += tdy; cy += sy; }
    }
    return max_range;
}

static uint32_t lcg(uint32_t *s)
{
    *s = *s * 1664525u + 1013904223u;
    return *s >> 8;
}

static double urand(uint32_t *s, double a, double b)
{
    return a + (b - a) * (lcg(s) / 16777216.0);
}

occmap_t *occmap_make_office(double width_m, double height_m, double res, uint32_t seed)
{
    int w = (int)ceil(width_m / res), h = (int)ceil(height_m / res);
    occmap_t *m = occmap_create(w, h, res, 0, 0);
    if (!m)
        return NULL;
    const double t = 0.1;  /* wall thickness */
    double W = w * res, H = h * res;
    occmap_fill_rect(m, 0, 0, W, t, OCCMAP_OCCUPIED);
    occmap_fill_rect(m, 0, H - t, W, H, OCCMAP_OCCUPIED);
    occmap_fill_rect(m, 0, 0, t, H, OCCMAP_OCCUPIED);
    occmap_fill_rect(m, W - t, 0, W, H, OCCMAP_OCCUPIED);
    /* A corridor 2 m wide along x through the middle, rooms on both sides. */
    double cy0 = H / 2 - 1.0, cy1 = H / 2 + 1.0;
    occmap_fill_rect(m, 0, cy0 - t, W, cy0, OCCMAP_OCCUPIED);
    occmap_fill_rect(m, 0, cy1, W, cy1 + t, OCCMAP_OCCUPIED);
    uint32_t s = seed ? seed : 1;
    for (int side = 0; side < 2; side++) {
        double x = 0;
        while (x < W - 2.5) {
            double rw = urand(&s, 3.5, 6.0);
            double x1 = x + rw > W - 2.5 ? W : x + rw;
            /* Door 1 m wide into the corridor, at a random place along the room. */
            double door = urand(&s, x + 0.5, x1 - 1.6);
            if (side == 0)
                occmap_fill_rect(m, door, cy0 - t, door + 1.0, cy0, OCCMAP_FREE);
            else
                occmap_fill_rect(m, door, cy1, door + 1.0, cy1 + t, OCCMAP_FREE);
            if (x1 < W)
                occmap_fill_rect(m, x1 - t / 2, side == 0 ? 0 : cy1, x1 + t / 2, side == 0 ? cy0 : H, OCCMAP_OCCUPIED);
            /* Furniture: one or two boxes against the back wall, clear of the door side. */
            int nbox = 1 + (int)(lcg(&s) % 2);
            for (int b = 0; b < nbox; b++) {
                double bw = urand(&s, 0.6, 1.4), bd = urand(&s, 0.5, 0.9);
                double bx = urand(&s, x + 0.3, x1 - 0.3 - bw);
                if (side == 0)
                    occmap_fill_rect(m, bx, t + 0.2, bx + bw, t + 0.2 + bd, OCCMAP_OCCUPIED);
                else
                    occmap_fill_rect(m, bx, H - t - 0.2 - bd, bx + bw, H - t - 0.2, OCCMAP_OCCUPIED);
            }
            x = x1;
        }
    }
    /* A few pillars in the corridor break its symmetry along x. */
    for (double px = 4.0 + urand(&s, 0, 2); px < W - 3; px += urand(&s, 6, 10))
        occmap_fill_rect(m, px, cy0, px + 0.3, cy0 + 0.3, OCCMAP_OCCUPIED);
    return m;
}
