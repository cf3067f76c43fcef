// scangrid: the mapper's log-odds grid, its smoothed likelihood for matching, and the matcher.
#include "adapters/mapper/scangrid.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

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
    lo_.assign(n, 0.0f);
    like_.assign(n, 0.0f);
    seen_.assign(n, 0);
    wall_.assign(n, 0);
    kr_ = std::max(1, (int)std::ceil(3 * p_.sigma / p_.resolution));
    for (int dy = -kr_; dy <= kr_; dy++)
        for (int dx = -kr_; dx <= kr_; dx++) {
            double d2 = (dx * dx + dy * dy) * p_.resolution * p_.resolution;
            kernel_.push_back((float)std::exp(-d2 / (2 * p_.sigma * p_.sigma)));
        }
    bx0_ = by0_ = INT32_MAX;
    bx1_ = by1_ = INT32_MIN;
}

void Grid::clear()
{
    std::fill(lo_.begin(), lo_.end(), 0.0f);
    std::fill(like_.begin(), like_.end(), 0.0f);
    std::fill(seen_.begin(), seen_.end(), 0);
    std::fill(wall_.begin(), wall_.end(), 0);
    bx0_ = by0_ = INT32_MAX;
    bx1_ = by1_ = INT32_MIN;
}

size_t Grid::memory_bytes() const
{
    return lo_.size() * (sizeof(float) * 2 + 2);
}

void Grid::bounds(int *x0, int *y0, int *x1, int *y1) const
{
    *x0 = bx0_;
    *y0 = by0_;
    *x1 = bx1_ + 1;
    *y1 = by1_ + 1;
}

// Walls are stamped once, when a cell first turns occupied: the likelihood is the max of the
// kernels, so a later stamp never lowers what an earlier one set.
void Grid::stamp(int cx, int cy)
{
    size_t k = 0;
    for (int dy = -kr_; dy <= kr_; dy++)
        for (int dx = -kr_; dx <= kr_; dx++, k++) {
            int x = cx + dx, y = cy + dy;
            if (x < 0 || y < 0 || x >= w_ || y >= h_)
                continue;
            float &v = like_[(size_t)y * w_ + x];
            v = std::max(v, kernel_[k]);
        }
}

void Grid::hit(int cx, int cy)
{
    size_t i = (size_t)cy * w_ + cx;
    lo_[i] = (float)std::min(p_.l_max, lo_[i] + p_.l_hit);
    seen_[i] = 1;
    if (lo_[i] > p_.l_occupied) {
        if (!(wall_[i] & STAMPED))
            stamp(cx, cy);
        wall_[i] = STAMPED | WALL;
    }
    bx0_ = std::min(bx0_, cx), bx1_ = std::max(bx1_, cx);
    by0_ = std::min(by0_, cy), by1_ = std::max(by1_, cy);
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
    bx0_ = std::min(bx0_, cx), bx1_ = std::max(bx1_, cx);
    by0_ = std::min(by0_, cy), by1_ = std::max(by1_, cy);
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

void Grid::integrate(const Pose &at, const Scan &s)
{
    double c = std::cos(at.th), sn = std::sin(at.th), r = p_.resolution;
    double sx = at.x + c * s.ox - sn * s.oy, sy = at.y + sn * s.ox + c * s.oy;
    int scx = (int)std::floor((sx - ox_) / r), scy = (int)std::floor((sy - oy_) / r);
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
    }
    for (size_t i = 0; i < s.hx.size(); i++) {
        int ex, ey;
        cell(s.hx[i], s.hy[i], &ex, &ey);
        if (ex >= 0 && ey >= 0 && ex < w_ && ey < h_)
            hit(ex, ey);
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

double Grid::correlative(const Scan &s, const Pose &guess, const MatchWindow &win, Pose *out, double *rival) const
{
    const double r = p_.resolution;
    const int n = (int)s.hx.size(), step = std::max(1, win.step_cells);
    const int nt = win.step_th > 0 ? (int)std::lround(win.th / win.step_th) : 0;
    const int nc = (int)std::lround(win.xy / r / step);
    std::vector<int> idx(n);
    std::vector<uint8_t> in(n);
    double best = -1, best_raw = 0;
    int best_dx = 0, best_dy = 0;
    std::vector<float> raws;            // every translation's best raw score over the angles, for the rival
    const int side = 2 * nc + 1;
    if (rival)
        raws.assign((size_t)side * side, 0.0f);
    *out = guess;
    for (int t = -nt; t <= nt; t++) {
        double th = guess.th + t * win.step_th, c = std::cos(th), sn = std::sin(th);
        for (int i = 0; i < n; i++) {
            int cx = (int)std::floor((guess.x + c * s.hx[i] - sn * s.hy[i] - ox_) / r);
            int cy = (int)std::floor((guess.y + sn * s.hx[i] + c * s.hy[i] - oy_) / r);
            int m = nc * step;
            in[i] = cx - m >= 0 && cy - m >= 0 && cx + m < w_ && cy + m < h_;
            idx[i] = cy * w_ + cx;
        }
        for (int dy = -nc; dy <= nc; dy++)
            for (int dx = -nc; dx <= nc; dx++) {
                int off = dy * step * w_ + dx * step;
                double sum = 0;
                for (int i = 0; i < n; i++)
                    if (in[i])
                        sum += like_[idx[i] + off];
                double raw = sum / n;
                if (rival) {
                    float &v = raws[(size_t)(dy + nc) * side + (dx + nc)];
                    v = std::max(v, (float)raw);
                }
                // A mild pull towards the prediction breaks ties along featureless corridors.
                double sc = raw;
                if (win.prior_xy > 0 && win.prior_th > 0) {
                    double d2 = (double)(dx * dx + dy * dy) * step * step * r * r / (win.prior_xy * win.prior_xy);
                    double a = t * win.step_th / win.prior_th;
                    sc *= std::exp(-0.5 * (d2 + a * a));
                } else {
                    /* a mild pull towards the prediction still breaks exact ties */
                    sc *= 1 - 0.01 * (double)(dx * dx + dy * dy + t * t) / (nc * nc + nt * nt + 1);
                }
                if (sc > best) {
                    best = sc;
                    best_raw = raw;
                    best_dx = dx;
                    best_dy = dy;
                    *out = { guess.x + dx * step * r, guess.y + dy * step * r, wrap(th) };
                }
            }
    }
    if (rival) {
        double far2 = win.rival_radius / (step * r);
        far2 *= far2;
        *rival = 0;
        for (int dy = -nc; dy <= nc; dy++)
            for (int dx = -nc; dx <= nc; dx++)
                if ((dx - best_dx) * (dx - best_dx) + (dy - best_dy) * (dy - best_dy) >= far2)
                    *rival = std::max(*rival, (double)raws[(size_t)(dy + nc) * side + (dx + nc)]);
    }
    return best_raw;
}

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

double Grid::match(const Scan &all, const Pose &guess, const MatchWindow &win, Pose *out, double *rival) const
{
    *out = guess;
    Scan seen = seen_hits(all, guess);
    const Scan &s = seen.hx.size() >= 20 ? seen : all;
    if (s.hx.size() < 10)
        return 0;
    Pose c;
    correlative(s, guess, win, &c, win.rival_radius > 0 ? rival : nullptr);
    double sc = score(s, c);
    if (win.refine)
        sc = refine(s, guess, win, &c);
    *out = c;
    return sc;
}

}  // namespace mapper
