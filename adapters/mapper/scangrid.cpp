// scangrid: the mapper's log-odds grid, its smoothed likelihood for matching, and the matcher.
#include "adapters/mapper/scangrid.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace mapper {

double wrap(double a)
{
    return std::atan2(std::sin(a), std::cos(a));
}

Pose compose(const Pose &a, const Pose &b)
{
    double c = std::cos(a.th), s = std::sin(a.th);
    return { a.x + c * b.x - s * b.y, a.y + s * b.x + c * b.y, wrap(a.th + b.th) };
}

Pose between(const Pose &a, const Pose &b)
{
    double c = std::cos(a.th), s = std::sin(a.th), dx = b.x - a.x, dy = b.y - a.y;
    return { c * dx + s * dy, -s * dx + c * dy, wrap(b.th - a.th) };
}

Grid::Grid(int width, int height, double ox, double oy, const GridParams &p)
    : w_(width), h_(height), ox_(ox), oy_(oy), p_(p)
{
    size_t n = (size_t)w_ * h_;
    lo_ = ZeroArray<float>(n);
    like_ = ZeroArray<float>(n);
    seen_ = ZeroArray<uint8_t>(n);
    wall_ = ZeroArray<uint8_t>(n);
    bool ok = lo_.ok() && like_.ok() && seen_.ok() && wall_.ok();
    for (int l = 0; l < LEVELS; l++) {
        pw_[l] = (w_ >> (l + 1)) + 1;
        ph_[l] = (h_ >> (l + 1)) + 1;
        pyr_[l] = ZeroArray<float>((size_t)pw_[l] * ph_[l]);
        quad_[l] = ZeroArray<float>((size_t)pw_[l] * ph_[l]);
        ok = ok && pyr_[l].ok() && quad_[l].ok();
    }
    if (!ok)
        throw std::bad_alloc();
    kr_ = std::max(1, (int)std::ceil(3 * p_.sigma / p_.resolution));
    for (int dy = -kr_; dy <= kr_; dy++)
        for (int dx = -kr_; dx <= kr_; dx++) {
            double d2 = (dx * dx + dy * dy) * p_.resolution * p_.resolution;
            kernel_.push_back((float)std::exp(-d2 / (2 * p_.sigma * p_.sigma)));
        }
    bx0_ = by0_ = INT32_MAX;
    bx1_ = by1_ = INT32_MIN;
}

// Only what was touched is cleared: the pages of a large grid the robot never reached stay
// untouched (and unpaid for).
void Grid::clear()
{
    if (bx1_ >= bx0_) {
        int x0 = std::max(0, bx0_ - kr_), x1 = std::min(w_ - 1, bx1_ + kr_);
        int y0 = std::max(0, by0_ - kr_), y1 = std::min(h_ - 1, by1_ + kr_);
        size_t len = (size_t)(x1 - x0 + 1);
        for (int y = y0; y <= y1; y++) {
            size_t i = (size_t)y * w_ + x0;
            if (used_logodds_) {
                std::fill_n(&lo_[i], len, 0.0f);
                std::fill_n(&seen_[i], len, 0);
            }
            std::fill_n(&like_[i], len, 0.0f);
            std::fill_n(&wall_[i], len, 0);
        }
        for (int l = 0; l < LEVELS; l++) {
            int a = std::max(0, (x0 >> (l + 1)) - 1), b = x1 >> (l + 1);
            for (int by = std::max(0, (y0 >> (l + 1)) - 1); by <= y1 >> (l + 1); by++) {
                std::fill_n(&pyr_[l][(size_t)by * pw_[l] + a], b - a + 1, 0.0f);
                std::fill_n(&quad_[l][(size_t)by * pw_[l] + a], b - a + 1, 0.0f);
            }
        }
    }
    bx0_ = by0_ = INT32_MAX;
    bx1_ = by1_ = INT32_MIN;
    used_logodds_ = false;
}

void Grid::end_batch()
{
    batch_ = false;
    if (bx1_ >= bx0_)
        build_pyramid(std::max(0, bx0_ - kr_), std::max(0, by0_ - kr_), std::min(w_ - 1, bx1_ + kr_),
                      std::min(h_ - 1, by1_ + kr_));
}

// The pyramid over the cells [x0, x1] x [y0, y1] from the likelihood, level by level (each
// block the maximum of the four below it), and the 2 x 2 maxima of each level beside it.
void Grid::build_pyramid(int x0, int y0, int x1, int y1)
{
    for (int l = 0; l < LEVELS; l++) {
        const int sh = l + 1, bx0 = x0 >> sh, by0 = y0 >> sh;
        const int bx1 = std::min(x1 >> sh, pw_[l] - 1), by1 = std::min(y1 >> sh, ph_[l] - 1);
        /* The level below: the likelihood itself, or the previous level; its row length and extent. */
        const float *below = l ? pyr_[l - 1].data() : like_.data();
        const int bw = l ? pw_[l - 1] : w_, bh = l ? ph_[l - 1] : h_;
        float *out = pyr_[l].data();
        for (int by = by0; by <= by1; by++) {
            const int y = 2 * by;
            const float *r0 = below + (size_t)y * bw, *r1 = y + 1 < bh ? r0 + bw : r0;
            for (int bx = bx0; bx <= bx1; bx++) {
                const int x = 2 * bx, x2 = x + 1 < bw ? x + 1 : x;
                out[(size_t)by * pw_[l] + bx] = std::max(std::max(r0[x], r0[x2]), std::max(r1[x], r1[x2]));
            }
        }
        float *q = quad_[l].data();
        for (int by = std::max(0, by0 - 1); by <= by1; by++) {
            const float *r0 = out + (size_t)by * pw_[l], *r1 = by + 1 < ph_[l] ? r0 + pw_[l] : r0;
            for (int bx = std::max(0, bx0 - 1); bx <= bx1; bx++) {
                const int x2 = bx + 1 < pw_[l] ? bx + 1 : bx;
                q[(size_t)by * pw_[l] + bx] = std::max(std::max(r0[bx], r0[x2]), std::max(r1[bx], r1[x2]));
            }
        }
    }
}

// What the grid holds in memory: the part of its arrays the map has reached.
size_t Grid::memory_bytes() const
{
    if (bx1_ < bx0_)
        return 0;
    size_t cells = (size_t)(bx1_ - bx0_ + 1 + 2 * kr_) * (size_t)(by1_ - by0_ + 1 + 2 * kr_);
    return cells * (sizeof(float) * 2 + 2) + cells * sizeof(float) / 3;
}

void Grid::bounds(int *x0, int *y0, int *x1, int *y1) const
{
    *x0 = bx0_;
    *y0 = by0_;
    *x1 = bx1_ + 1;
    *y1 = by1_ + 1;
}

void Grid::touch(int cx, int cy)
{
    bx0_ = std::min(bx0_, cx), bx1_ = std::max(bx1_, cx);
    by0_ = std::min(by0_, cy), by1_ = std::max(by1_, cy);
}

// The likelihood only rises between clears, so each level of the pyramid rises with it; a
// level already as high stops the climb (every level above it is at least as high).
void Grid::raise(int cx, int cy, float v)
{
    float &c = like_[(size_t)cy * w_ + cx];
    if (v <= c)
        return;
    c = v;
    for (int l = 0; l < LEVELS && !batch_; l++) {
        int bx = cx >> (l + 1), by = cy >> (l + 1);
        float &b = pyr_[l][(size_t)by * pw_[l] + bx];
        if (b >= v)
            break;
        b = v;
        for (int y = std::max(0, by - 1); y <= by; y++)
            for (int x = std::max(0, bx - 1); x <= bx; x++) {
                float &q = quad_[l][(size_t)y * pw_[l] + x];
                q = std::max(q, v);
            }
    }
}

// Walls are stamped once, when a cell first turns occupied: the likelihood is the max of the
// kernels, so a later stamp never lowers what an earlier one set.
void Grid::stamp(int cx, int cy)
{
    size_t k = 0;
    for (int dy = -kr_; dy <= kr_; dy++)
        for (int dx = -kr_; dx <= kr_; dx++, k++) {
            int x = cx + dx, y = cy + dy;
            if (x >= 0 && y >= 0 && x < w_ && y < h_)
                raise(x, y, kernel_[k]);
        }
}

void Grid::hit(int cx, int cy)
{
    size_t i = (size_t)cy * w_ + cx;
    lo_[i] = (float)std::min(p_.l_max, lo_[i] + p_.l_hit);
    seen_[i] = 1;
    if (lo_[i] > L_OCCUPIED) {
        /* Walls are stamped once, when a cell first turns occupied: a stray return (a beam's
         * noise, a passer-by) does not thicken the walls of a map matched against for hours. */
        if (stamp_walls_ && !(wall_[i] & STAMPED))
            stamp(cx, cy);
        wall_[i] |= STAMPED | WALL;
    }
    touch(cx, cy);
}

void Grid::miss(int cx, int cy)
{
    size_t i = (size_t)cy * w_ + cx;
    lo_[i] = (float)std::max(p_.l_min, lo_[i] + p_.l_miss);
    seen_[i] = 1;
    if ((wall_[i] & WALL) && lo_[i] < 0) {
        wall_[i] &= (uint8_t)~WALL;
        cleared_++;
    }
    touch(cx, cy);
}

// Bresenham from (x0, y0) to (x1, y1): every cell but the last is passed through; the ray stops
// at the grid's edge.
template <typename F>
static bool trace(int x0, int y0, int x1, int y1, int w, int h, F pass)
{
    int dx = std::abs(x1 - x0), sx = x0 < x1 ? 1 : -1;
    int dy = -std::abs(y1 - y0), sy = y0 < y1 ? 1 : -1;
    int err = dx + dy;
    for (;;) {
        if (x0 < 0 || y0 < 0 || x0 >= w || y0 >= h)
            return false;
        if (x0 == x1 && y0 == y1)
            return true;
        pass(x0, y0);
        int e2 = 2 * err;
        if (e2 >= dy) {
            err += dy;
            x0 += sx;
        }
        if (e2 <= dx) {
            err += dx;
            y0 += sy;
        }
    }
}

bool Grid::integrate(const Pose &at, const Scan &s)
{
    used_logodds_ = true;
    double c = std::cos(at.th), sn = std::sin(at.th), r = p_.resolution;
    double sx = at.x + c * s.ox - sn * s.oy, sy = at.y + sn * s.ox + c * s.oy;
    int scx = (int)std::floor((sx - ox_) / r), scy = (int)std::floor((sy - oy_) / r);
    bool whole = true;
    auto cell = [&](double px, double py, int *cx, int *cy) {
        *cx = (int)std::floor((at.x + c * px - sn * py - ox_) / r);
        *cy = (int)std::floor((at.y + sn * px + c * py - oy_) / r);
    };
    auto pass = [this](int x, int y) { miss(x, y); };
    for (size_t i = 0; i < s.mx.size(); i++) {
        int ex, ey;
        cell(s.mx[i], s.my[i], &ex, &ey);
        if (trace(scx, scy, ex, ey, w_, h_, pass))
            miss(ex, ey);
        else
            whole = false;
    }
    // A beam that hit clears the cells in front of the surface it hit, the last one included;
    // traced to the hit itself, its line would enter the wall's row of cells before the hit's
    // cell (up to several cells before it at a grazing angle) and wear the wall away. The hits
    // come after all the free rays, so no beam of the same scan clears a wall it drew.
    for (size_t i = 0; i < s.fx.size(); i++) {
        int ex, ey;
        cell(s.fx[i], s.fy[i], &ex, &ey);
        if (trace(scx, scy, ex, ey, w_, h_, pass))
            miss(ex, ey);
        else
            whole = false;
    }
    for (size_t i = 0; i < s.hx.size(); i++) {
        int ex, ey;
        cell(s.hx[i], s.hy[i], &ex, &ey);
        if (ex >= 0 && ey >= 0 && ex < w_ && ey < h_)
            hit(ex, ey);
        else
            whole = false;
    }
    return whole;
}

void Grid::add_hits(const Pose &at, const Scan &s)
{
    double c = std::cos(at.th), sn = std::sin(at.th), r = p_.resolution;
    for (size_t i = 0; i < s.hx.size(); i++) {
        int cx = (int)std::floor((at.x + c * s.hx[i] - sn * s.hy[i] - ox_) / r);
        int cy = (int)std::floor((at.y + sn * s.hx[i] + c * s.hy[i] - oy_) / r);
        if (cx < 0 || cy < 0 || cx >= w_ || cy >= h_)
            continue;
        size_t k = (size_t)cy * w_ + cx;
        if (!(wall_[k] & STAMPED))
            stamp(cx, cy);
        wall_[k] |= STAMPED;
        touch(cx, cy);
    }
}

double Grid::sample(double x, double y, double *gx, double *gy) const
{
    double fx = (x - ox_) / p_.resolution - 0.5, fy = (y - oy_) / p_.resolution - 0.5;
    int ix = (int)std::floor(fx), iy = (int)std::floor(fy);
    if (ix < 0 || iy < 0 || ix + 1 >= w_ || iy + 1 >= h_) {
        *gx = *gy = 0;
        return 0;
    }
    double ax = fx - ix, ay = fy - iy;
    const float *r0 = &like_[(size_t)iy * w_ + ix], *r1 = r0 + w_;
    double v00 = r0[0], v10 = r0[1], v01 = r1[0], v11 = r1[1];
    *gx = ((v10 - v00) * (1 - ay) + (v11 - v01) * ay) / p_.resolution;
    *gy = ((v01 - v00) * (1 - ax) + (v11 - v10) * ax) / p_.resolution;
    return (v00 * (1 - ax) + v10 * ax) * (1 - ay) + (v01 * (1 - ax) + v11 * ax) * ay;
}

double Grid::score(const Scan &s, const Pose &at) const
{
    if (s.hx.size() < 10)
        return 0;
    double c = std::cos(at.th), sn = std::sin(at.th), sum = 0, gx, gy;
    for (size_t i = 0; i < s.hx.size(); i++)
        sum += sample(at.x + c * s.hx[i] - sn * s.hy[i], at.y + sn * s.hx[i] + c * s.hy[i], &gx, &gy);
    return sum / (double)s.hx.size();
}

void Grid::copy_likelihood(const Grid &src)
{
    const double r = p_.resolution;
    const int dx = (int)std::lround((ox_ - src.ox_) / r), dy = (int)std::lround((oy_ - src.oy_) / r);
    const int B = 1 << LEVELS;
    if (src.bx1_ < src.bx0_ || dx % B || dy % B)
        return;
    /* Where the source has anything (its touched cells and their kernels' reach), in whole
     * blocks of the coarsest level, so that the pyramid is copied as it is. */
    /* Both grids' cells: x in [0, w_) here and x + dx in [0, src.w_) there (dx, -dx multiples of B). */
    int x0 = std::max({ 0, -dx, (src.bx0_ - src.kr_ - dx) / B * B }), x1 = std::min(w_, (src.bx1_ + src.kr_ + 1 - dx + B) / B * B);
    int y0 = std::max({ 0, -dy, (src.by0_ - src.kr_ - dy) / B * B }), y1 = std::min(h_, (src.by1_ + src.kr_ + 1 - dy + B) / B * B);
    x1 = std::min(x1, src.w_ - dx), y1 = std::min(y1, src.h_ - dy);
    if (x1 <= x0 || y1 <= y0)
        return;
    for (int y = y0; y < y1; y++)
        std::copy_n(&src.like_[(size_t)(y + dy) * src.w_ + (x0 + dx)], x1 - x0, &like_[(size_t)y * w_ + x0]);
    for (int l = 0; l < LEVELS; l++) {
        int sh = l + 1, a = x0 >> sh, b = std::min(pw_[l], (x1 + (1 << sh) - 1) >> sh), ox = dx >> sh, oy = dy >> sh;
        b = std::min(b, src.pw_[l] - ox);
        for (int by = y0 >> sh; by < std::min(ph_[l], std::min(src.ph_[l] - oy, (y1 + (1 << sh) - 1) >> sh)); by++) {
            std::copy_n(&src.pyr_[l][(size_t)(by + oy) * src.pw_[l] + a + ox], b - a, &pyr_[l][(size_t)by * pw_[l] + a]);
            std::copy_n(&src.quad_[l][(size_t)(by + oy) * src.pw_[l] + a + ox], b - a, &quad_[l][(size_t)by * pw_[l] + a]);
        }
    }
    touch(x0, y0);
    touch(x1 - 1, y1 - 1);
}

double Grid::contradiction(const Scan &s, const Pose &at, double l_free) const
{
    if (s.hx.empty())
        return 0;
    double c = std::cos(at.th), sn = std::sin(at.th), r = p_.resolution;
    size_t bad = 0;
    for (size_t i = 0; i < s.hx.size(); i++) {
        int cx = (int)std::floor((at.x + c * s.hx[i] - sn * s.hy[i] - ox_) / r);
        int cy = (int)std::floor((at.y + sn * s.hx[i] + c * s.hy[i] - oy_) / r);
        if (cx < 0 || cy < 0 || cx >= w_ || cy >= h_)
            continue;
        size_t k = (size_t)cy * w_ + cx;
        bad += lo_[k] < l_free;
    }
    return (double)bad / (double)s.hx.size();
}

// Branch and bound over the search window (Olson 2009; Cartographer's fast correlative matcher):
// for each angle the scan's cells at the guess, then square regions of translations, each scored
// by an upper bound from the pyramid (a point may land anywhere in its region), the best-bounded
// regions split first and a region dropped when its bound cannot beat the best pose found. The
// result is the exhaustive search's, at a fraction of its cost for windows of metres.
struct Grid::Search {
    const Grid &g;
    const MatchWindow &win;
    int n, nc, nt, top;
    double r;
    std::vector<int> px, py;                   // per angle, per point: the cell at the guess
    // The weight of a pose: the prior around the prediction, or a mild pull that breaks ties.
    double weight(int dx, int dy, int t) const
    {
        if (win.prior_xy > 0 && win.prior_th > 0) {
            double d2 = (double)(dx * dx + dy * dy) * r * r / (win.prior_xy * win.prior_xy);
            double a = t * win.step_th / win.prior_th;
            return std::exp(-0.5 * (d2 + a * a));
        }
        return 1 - 0.01 * (double)(dx * dx + dy * dy + t * t) / (double)(nc * nc + nt * nt + 1);
    }
    // The search has scored as many regions and poses as it may: what it found is what it has.
    bool cut() const { return win.max_evals > 0 && evals >= win.max_evals; }
    // Mean likelihood of the points at offset (x, y) for angle t (level 0), or its bound over the
    // region of 2^level offsets from (x, y).
    mutable long evals = 0;                    // regions and poses scored so far
    double raw(int t, int x, int y, int level) const
    {
        evals++;
        const int *cx = &px[(size_t)(t + nt) * n], *cy = &py[(size_t)(t + nt) * n];
        double sum = 0;
        if (level == 0) {
            for (int i = 0; i < n; i++) {
                int a = cx[i] + x, b = cy[i] + y;
                if (a >= 0 && b >= 0 && a < g.w_ && b < g.h_)
                    sum += g.like_[(size_t)b * g.w_ + a];
            }
        } else {
            /* The bound of a region of 2^level offsets: the maximum over the two blocks a side
             * its cells can fall in (quad_). */
            const float *q = g.quad_[level - 1].data();
            const unsigned pw = (unsigned)g.pw_[level - 1], ph = (unsigned)g.ph_[level - 1];
            for (int i = 0; i < n; i++) {
                unsigned a = (unsigned)((cx[i] + x) >> level), b = (unsigned)((cy[i] + y) >> level);
                if (a < pw && b < ph)
                    sum += q[(size_t)b * pw + a];
                else if ((cx[i] + x + (1 << level) - 1) >= 0 && (cy[i] + y + (1 << level) - 1) >= 0)
                    sum += 1;   /* straddles the grid's low edge: no bound tighter than the most */
            }
        }
        return sum / n;
    }
    struct Cand {
        int t, x, y, level;
        double bound;
    };
    // The weight's maximum over a region: at its offset nearest the prediction.
    double best_weight(const Cand &c) const
    {
        int s = (1 << c.level) - 1;
        int dx = std::clamp(0, c.x, c.x + s), dy = std::clamp(0, c.y, c.y + s);
        return weight(dx, dy, c.t);
    }
    // Farthest distance^2 (cells) from (bx, by) to the region, and nearest.
    static void dist2(const Cand &c, int bx, int by, double *near, double *far)
    {
        int s = (1 << c.level) - 1;
        int nx = std::clamp(bx, c.x, c.x + s) - bx, ny = std::clamp(by, c.y, c.y + s) - by;
        int fx = std::max(std::abs(c.x - bx), std::abs(c.x + s - bx)), fy = std::max(std::abs(c.y - by), std::abs(c.y + s - by));
        *near = (double)nx * nx + (double)ny * ny;
        *far = (double)fx * fx + (double)fy * fy;
    }
    // Best weighted pose (weighted = true) or best raw pose farther than sqrt(excl2) cells from
    // (ex, ey): depth first, best bound first.
    void descend(std::vector<Cand> &cands, bool weighted, int ex, int ey, double excl2, Cand *best, double *best_score) const
    {
        std::sort(cands.begin(), cands.end(), [](const Cand &a, const Cand &b) { return a.bound > b.bound; });
        for (const Cand &c : cands) {
            if (c.bound <= *best_score || cut())
                break;
            if (c.level == 0) {
                *best_score = c.bound;
                *best = c;
                continue;
            }
            std::vector<Cand> kids;
            int h = 1 << (c.level - 1);
            for (int k = 0; k < 4; k++) {
                Cand d{ c.t, c.x + (k & 1) * h, c.y + (k >> 1) * h, c.level - 1, 0 };
                if (d.x > nc || d.y > nc)
                    continue;
                double nd, fd;
                dist2(d, ex, ey, &nd, &fd);
                if (!weighted && fd < excl2)
                    continue;
                if (d.level == 0 && !weighted && nd < excl2)
                    continue;
                d.bound = raw(d.t, d.x, d.y, d.level) * (weighted ? (d.level ? best_weight(d) : weight(d.x, d.y, d.t)) : 1);
                kids.push_back(d);
            }
            descend(kids, weighted, ex, ey, excl2, best, best_score);
        }
    }
    std::vector<Cand> roots(bool weighted, int ex, int ey, double excl2) const
    {
        std::vector<Cand> out;
        int s = 1 << top;
        for (int t = -nt; t <= nt; t++)
            for (int y = -nc; y <= nc; y += s)
                for (int x = -nc; x <= nc; x += s) {
                    Cand c{ t, x, y, top, 0 };
                    double nd, fd;
                    dist2(c, ex, ey, &nd, &fd);
                    if (!weighted && (fd < excl2 || (top == 0 && nd < excl2)))
                        continue;
                    c.bound = raw(t, x, y, top) * (weighted ? best_weight(c) : 1);
                    out.push_back(c);
                }
        return out;
    }
};

// Gauss-Newton on the mean squared misfit (1 - likelihood) per hit, plus the prediction's prior.
double Grid::refine(const Scan &s, const Pose &guess, const MatchWindow &win, Pose *pose) const
{
    Pose p = *pose;
    const double n = (double)s.hx.size();
    const double wxy = win.prior_xy > 0 ? 1 / (win.prior_xy * win.prior_xy) : 0;
    const double wth = win.prior_th > 0 ? 1 / (win.prior_th * win.prior_th) : 0;
    // The objective: mean misfit plus the prior, in the same units as the search's weighting.
    auto objective = [&](const Pose &q) {
        double dx = q.x - guess.x, dy = q.y - guess.y, dt = wrap(q.th - guess.th);
        return (1 - score(s, q)) + 0.5 * 0.2 * (wxy * (dx * dx + dy * dy) + wth * dt * dt);
    };
    double best = objective(p);
    for (int it = 0; it < 10; it++) {
        Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
        Eigen::Vector3d b = Eigen::Vector3d::Zero();
        double c = std::cos(p.th), sn = std::sin(p.th);
        for (size_t i = 0; i < s.hx.size(); i++) {
            double gx, gy, hx = s.hx[i], hy = s.hy[i];
            double m = sample(p.x + c * hx - sn * hy, p.y + sn * hx + c * hy, &gx, &gy);
            Eigen::Vector3d J(gx, gy, gx * (-sn * hx - c * hy) + gy * (c * hx - sn * hy));
            H += J * J.transpose() / n;
            b += J * (1 - m) / n;
        }
        Eigen::Vector3d w(0.2 * wxy, 0.2 * wxy, 0.2 * wth);
        H.diagonal() += w;
        b += Eigen::Vector3d(w[0] * (guess.x - p.x), w[1] * (guess.y - p.y), w[2] * wrap(guess.th - p.th));
        H.diagonal() += Eigen::Vector3d(1e-6, 1e-6, 1e-6) + 0.1 * H.diagonal();
        Eigen::Vector3d d = H.ldlt().solve(b);
        if (!d.allFinite())
            break;
        double lim = 2 * p_.resolution;
        Pose q = { p.x + std::clamp(d[0], -lim, lim), p.y + std::clamp(d[1], -lim, lim),
                   wrap(p.th + std::clamp(d[2], -0.05, 0.05)) };
        double oq = objective(q);
        if (oq >= best)
            break;
        best = oq;
        p = q;
        if (std::fabs(d[0]) + std::fabs(d[1]) < 1e-4 && std::fabs(d[2]) < 1e-4)
            break;
    }
    *pose = p;
    return score(s, p);
}

// Only the hits that land on cells the map has seen (at the prediction) are matched: a hit on a
// wall's part never seen scores nothing wherever it lands, except by sliding the robot back until
// it falls on the part already mapped, and that pulled every match towards the known map by a
// little, always against the motion.
Scan Grid::seen_hits(const Scan &s, const Pose &guess) const
{
    Scan k;
    k.ox = s.ox;
    k.oy = s.oy;
    double c = std::cos(guess.th), sn = std::sin(guess.th), r = p_.resolution;
    for (size_t i = 0; i < s.hx.size(); i++) {
        int cx = (int)std::floor((guess.x + c * s.hx[i] - sn * s.hy[i] - ox_) / r);
        int cy = (int)std::floor((guess.y + sn * s.hx[i] + c * s.hy[i] - oy_) / r);
        if (cx >= 0 && cy >= 0 && cx < w_ && cy < h_ && seen_[(size_t)cy * w_ + cx]) {
            k.hx.push_back(s.hx[i]);
            k.hy.push_back(s.hy[i]);
        }
    }
    return k;
}

double Grid::match(const Scan &all, const Pose &guess, const MatchWindow &win, Pose *out, double *rival,
                   bool *edge, bool *cut) const
{
    *out = guess;
    if (edge)
        *edge = false;
    Scan seen = win.seen_only ? seen_hits(all, guess) : Scan{};
    const Scan &s = win.seen_only && seen.hx.size() >= 20 ? seen : all;
    if (s.hx.size() < 10)
        return 0;
    const double r = p_.resolution;
    Search q{ *this, win, (int)s.hx.size(), (int)std::lround(win.xy / r),
              win.step_th > 0 ? (int)std::lround(win.th / win.step_th) : 0, 0, r, {}, {} };
    // Three or so regions a side at the top: larger ones bound too loosely to prune anything.
    while (q.top < LEVELS && (2 << (q.top + 1)) <= 2 * q.nc + 1)
        q.top++;
    q.px.resize((size_t)(2 * q.nt + 1) * q.n);
    q.py.resize(q.px.size());
    for (int t = -q.nt; t <= q.nt; t++) {
        double th = guess.th + t * win.step_th, c = std::cos(th), sn = std::sin(th);
        for (int i = 0; i < q.n; i++) {
            size_t k = (size_t)(t + q.nt) * q.n + i;
            q.px[k] = (int)std::floor((guess.x + c * s.hx[i] - sn * s.hy[i] - ox_) / r);
            q.py[k] = (int)std::floor((guess.y + sn * s.hx[i] + c * s.hy[i] - oy_) / r);
        }
    }
    std::vector<Search::Cand> cands = q.roots(true, 0, 0, 0);
    Search::Cand best{ 0, 0, 0, 0, 0 };
    double best_score = win.floor > 0 ? win.floor : -1;
    q.descend(cands, true, 0, 0, 0, &best, &best_score);
    if (win.floor > 0 && best_score <= win.floor)
        return 0;
    if (cut)
        *cut = q.cut();
    if (best_score < 0)
        return 0;
    Pose c{ guess.x + best.x * r, guess.y + best.y * r, wrap(guess.th + best.t * win.step_th) };
    if (edge)
        *edge = std::abs(best.x) >= q.nc || std::abs(best.y) >= q.nc || (q.nt > 0 && std::abs(best.t) >= q.nt);
    if (rival && win.rival_radius > 0) {
        double excl = win.rival_radius / r;
        std::vector<Search::Cand> rc = q.roots(false, best.x, best.y, excl * excl);
        Search::Cand rb{ 0, 0, 0, 0, 0 };
        /* A rival matters only near the best: below win.rival_floor of it, none is sought. */
        double rs = win.rival_floor * best_score;
        q.descend(rc, false, best.x, best.y, excl * excl, &rb, &rs);
        *rival = rs > win.rival_floor * best_score ? rs : 0;
    }
    double sc = score(s, c);
    if (win.refine)
        sc = refine(s, guess, win, &c);
    *out = c;
    return sc;
}

}  // namespace mapper
