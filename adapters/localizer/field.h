// field: the localizer's view of the map, shared by the particle filter (mcl.cpp) and the global
// search (reloc.cpp): the distance from every point to the nearest wall, sampled at 5 cm or finer
// (a coarse map is sampled finer, so a beam ending on a wall's face is measured from that face,
// not from the centre of the 20 cm cell behind it), what the map says each cell is, and rays
// traced through it.
#ifndef ADAPTERS_LOCALIZER_FIELD_H
#define ADAPTERS_LOCALIZER_FIELD_H

#include <cstdint>
#include <vector>

#include "map/occmap.h"

struct mcl;

struct lfield {
    enum : uint8_t { FREE = 0, OCC = 1, UNK = 2 };
    int w = 0, h = 0, k = 1;            // field cells; k of them across one map cell
    double res = 0, ox = 0, oy = 0;     // field cell size and the map's origin
    double map_res = 0;
    std::vector<float> dist;            // m from a cell's centre to the nearest occupied cell's edge
    std::vector<uint8_t> kind;          // FREE, OCC or UNK (unknown and 1..99) as the map says
    std::vector<int32_t> free_cells;    // map cells known free (indices into the map), for sampling

    // Fills the field from m, at most max_res per cell. false with errno ENOMEM or EFBIG (more
    // than 16 M field cells).
    bool build(const occmap_t *m, double max_res);

    int cell(double x, double y) const
    {
        double fx = (x - ox) / res, fy = (y - oy) / res;
        if (!(fx >= 0 && fy >= 0 && fx < w && fy < h))
            return -1;
        return (int)fy * w + (int)fx;
    }
    // How far a ray from (x, y) along (c, s) goes before it enters an occupied cell, up to
    // max_r (or leaves the map, which ends it too). Steps by the distance field, so free space
    // is crossed in a few steps.
    double trace(double x, double y, double c, double s, double max_r) const;

    // A beam from the laser at (x, y) along (c, s) that read r (-range_max: nothing seen)
    // against the map: it should end on a wall (within `near`), with no wall on its way there.
    // SHORTER: it ends in free space short of the walls; THROUGH: it passed through a wall, or
    // saw nothing where a wall stands well within range; NOTHING: it went where the map does
    // not know (unknown cells, off the map), or saw nothing where the map has nothing.
    enum verdict_t { HIT, SHORTER, THROUGH, NOTHING };
    verdict_t verdict(double x, double y, double c, double s, double r, double near) const;
};

// The filter's field and its sigma_hit widened by the map's cells, for the global search.
const lfield &mcl_field(const mcl *f);
double mcl_sigma(const mcl *f);

#endif
