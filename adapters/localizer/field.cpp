// field: the map sampled for the localizer (distance to walls, cell kinds, ray tracing).
#include "adapters/localizer/field.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <memory>

#include "map/clearance.h"

bool lfield::build(const occmap_t *m, double max_res)
{
    k = std::max(1, (int)std::ceil(m->resolution / max_res - 1e-9));
    map_res = m->resolution;
    res = m->resolution / k;
    ox = m->origin_x;
    oy = m->origin_y;
    if ((double)m->width * k * (double)m->height * k > 16e6) {
        errno = EFBIG;
        return false;
    }
    w = m->width * k;
    h = m->height * k;
    // The fine grid's cells copy their map cell; its clearance to the occupied ones is then
    // measured from each fine centre to the occupied cells' faces.
    std::unique_ptr<occmap_t, decltype(&occmap_destroy)> fine(occmap_create(w, h, res, ox, oy), &occmap_destroy);
    if (!fine)
        return false;
    kind.resize((size_t)w * h);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            int8_t v = m->cells[(size_t)(y / k) * m->width + x / k];
            fine->cells[(size_t)y * w + x] = v;
            kind[(size_t)y * w + x] = v == OCCMAP_OCCUPIED ? OCC : v == OCCMAP_FREE ? FREE : UNK;
        }
    std::unique_ptr<float, decltype(&std::free)> cl(occmap_clearance(fine.get(), true), &std::free);
    if (!cl)
        return false;
    dist.assign(cl.get(), cl.get() + (size_t)w * h);
    for (float &d : dist)
        d = std::max(d, 0.0f);
    free_cells.clear();
    for (int i = 0; i < m->width * m->height; i++)
        if (m->cells[i] == OCCMAP_FREE)
            free_cells.push_back(i);
    return true;
}

double lfield::trace(double x, double y, double c, double s, double max_r) const
{
    // A point anywhere in a cell is at least the centre's distance less half a diagonal from a
    // wall; never step less than half a cell, so no wall a cell thick is stepped over.
    const double slack = 0.71 * res, least = 0.5 * res;
    double t = 0;
    while (t < max_r) {
        int i = cell(x + t * c, y + t * s);
        if (i < 0 || kind[(size_t)i] == OCC)
            return t;
        t += std::max((double)dist[(size_t)i] - slack, least);
    }
    return max_r;
}

lfield::verdict_t lfield::verdict(double x, double y, double c, double s, double r, double near) const
{
    double reach = r < 0 ? -r - std::max(0.3, near) : std::max(r - near, 0.0);
    double t = trace(x, y, c, s, reach);
    if (t < reach)      // stopped on the way: by a wall, or by the map's edge
        return cell(x + t * c, y + t * s) >= 0 ? THROUGH : NOTHING;
    if (r < 0)
        return NOTHING;
    int end = cell(x + r * c, y + r * s);
    if (end < 0)
        return NOTHING;
    if (dist[(size_t)end] <= near)
        return HIT;
    return kind[(size_t)end] == FREE ? SHORTER : NOTHING;
}
