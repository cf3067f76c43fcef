// reloc: global relocalization by search. A coarse pass scores every free position of the map
// at every heading (5 degrees) with the cloud's points on a blurred table, one look-up a point;
// the best are refined by hill climbing on the localizer's field and judged ray by ray.
#include "adapters/localizer/reloc.h"
#include "adapters/localizer/field.h"
#include "adapters/common/posebuf.h"

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <new>
#include <unordered_map>
#include <vector>

namespace {

double wrap(double a)
{
    return std::atan2(std::sin(a), std::cos(a));
}

const int kHeadings = 72;       // coarse headings: 5 degrees
const int kCoarsePoints = 60;
const int kFinePoints = 300;
const int kRefined = 150;       // coarse candidates refined
const double kFreeOfWalls = 0.15;

}  // namespace

// Points are kept one per 10 cm square, and used once a second scan saw that square too: a
// stray reading (or someone walking by) is seen once, a wall by every scan that faces it.
struct reloc_cloud {
    double ref[3] = {0, 0, 0};
    std::vector<float> pts;     // sx, sy, x, y per square, from the first scan that saw it
    std::vector<int> seen;      // scans that saw each square
    std::vector<int> last;      // the last of them
    std::unordered_map<uint64_t, int> cells;
    std::vector<float> kept;    // the squares seen twice, as pts
    uint64_t sectors = 0;
    int scans = 0;

    void keep()
    {
        kept.clear();
        sectors = 0;
        for (size_t i = 0; i < seen.size(); i++) {
            if (seen[i] < 2)
                continue;
            kept.insert(kept.end(), pts.begin() + 4 * i, pts.begin() + 4 * i + 4);
            int sector = (int)std::floor((std::atan2(pts[4 * i + 3], pts[4 * i + 2]) + M_PI) / (M_PI / 18));
            sectors |= 1ull << std::clamp(sector, 0, 35);
        }
    }
};

extern "C" reloc_cloud_t *reloc_cloud_create(void)
{
    reloc_cloud_t *c = new (std::nothrow) reloc_cloud;
    if (!c)
        errno = ENOMEM;
    return c;
}

extern "C" void reloc_cloud_destroy(reloc_cloud_t *c)
{
    delete c;
}

extern "C" void reloc_cloud_reset(reloc_cloud_t *c, const double odom[3])
{
    std::copy(odom, odom + 3, c->ref);
    c->pts.clear();
    c->seen.clear();
    c->last.clear();
    c->cells.clear();
    c->kept.clear();
    c->sectors = 0;
    c->scans = 0;
}

extern "C" void reloc_cloud_add(reloc_cloud_t *c, const double odom[3], const double mount[3], const mcl_scan_t *scan)
{
    double rel[3], laser[3];
    pose2d_between(c->ref, odom, rel);
    pose2d_compose(rel, mount, laser);
    try {
        c->scans++;
        for (int k = 0; k < scan->n; k++) {
            double r = scan->ranges[k];
            if (!std::isfinite(r) || r <= scan->range_min || r >= scan->range_max)
                continue;
            double a = laser[2] + scan->angle_min + k * scan->angle_increment;
            double x = laser[0] + r * std::cos(a), y = laser[1] + r * std::sin(a);
            uint64_t key = ((uint64_t)(uint32_t)(int32_t)std::floor(x / 0.1) << 32) |
                           (uint32_t)(int32_t)std::floor(y / 0.1);
            auto it = c->cells.find(key);
            if (it != c->cells.end()) {
                int i = it->second;
                if (c->last[(size_t)i] != c->scans) {
                    c->seen[(size_t)i]++;
                    c->last[(size_t)i] = c->scans;
                }
                continue;
            }
            if (c->seen.size() >= 20000)
                continue;
            c->cells.emplace(key, (int)c->seen.size());
            c->pts.insert(c->pts.end(), { (float)laser[0], (float)laser[1], (float)x, (float)y });
            c->seen.push_back(1);
            c->last.push_back(c->scans);
        }
        c->keep();
    } catch (...) {
        // Out of memory: the cloud keeps what it has.
    }
}

static int reloc_cloud_size(const reloc_cloud_t *c)
{
    return (int)(c->kept.size() / 4);
}

extern "C" void reloc_cloud_pose_now(const reloc_cloud_t *c, const double origin[3], const double odom[3], double out[3])
{
    double rel[3];
    pose2d_between(c->ref, odom, rel);
    pose2d_compose(origin, rel, out);
}

extern "C" void reloc_cloud_origin(const reloc_cloud_t *c, const double now[3], const double odom[3], double out[3])
{
    double rel[3], back[3];
    pose2d_between(c->ref, odom, rel);
    pose2d_between(rel, (const double[3]){ 0, 0, 0 }, back);
    pose2d_compose(now, back, out);
}

namespace {

struct cand {
    float score;
    int cell, heading;
};

// Evenly spread indices of at most `want` of the n points.
std::vector<int> spread(int n, int want)
{
    std::vector<int> idx;
    int m = std::min(n, want);
    for (int j = 0; j < m; j++)
        idx.push_back((int)((double)j * n / m));
    return idx;
}

struct searcher {
    const lfield &fd;
    double sigma;
    const std::vector<float> &pts;
    std::vector<int> fine_idx;

    // Mean log likelihood per point of the frame's origin at pose q.
    double score(const double q[3]) const
    {
        double c = std::cos(q[2]), s = std::sin(q[2]), k = 1.0 / (2 * sigma * sigma), sum = 0;
        for (int i : fine_idx) {
            double px = pts[4 * i + 2], py = pts[4 * i + 3];
            int cell = fd.cell(q[0] + c * px - s * py, q[1] + s * px + c * py);
            if (cell < 0) {
                sum += std::log(0.005);
                continue;
            }
            double d = std::min<double>(fd.dist[(size_t)cell], 1.0);
            sum += std::log(std::exp(-d * d * k) + (fd.kind[(size_t)cell] == lfield::FREE ? 0.05 : 0.005));
        }
        return sum / std::max<size_t>(fine_idx.size(), 1);
    }

    // Hill climbing from q, steps halved when nothing is better; never farther from where it
    // started than reach_xy, reach_th.
    void refine(double q[3], double step_xy, double step_th, double *best, double reach_xy = INFINITY,
                double reach_th = INFINITY) const
    {
        static const int dirs[6][3] = { { 1, 0, 0 }, { -1, 0, 0 }, { 0, 1, 0 }, { 0, -1, 0 }, { 0, 0, 1 }, { 0, 0, -1 } };
        const double q0[3] = { q[0], q[1], q[2] };
        *best = score(q);
        for (int it = 0; it < 80 && (step_xy > 0.01 || step_th > 0.004); it++) {
            double bq[3] = { q[0], q[1], q[2] }, bs = *best;
            for (auto &d : dirs) {
                double t[3] = { q[0] + d[0] * step_xy, q[1] + d[1] * step_xy, wrap(q[2] + d[2] * step_th) };
                if (std::hypot(t[0] - q0[0], t[1] - q0[1]) > reach_xy || std::fabs(wrap(t[2] - q0[2])) > reach_th)
                    continue;
                double v = score(t);
                if (v > bs) {
                    bs = v;
                    std::copy(t, t + 3, bq);
                }
            }
            if (bs > *best) {
                *best = bs;
                std::copy(bq, bq + 3, q);
            } else {
                step_xy /= 2;
                step_th /= 2;
            }
        }
    }

    void judge(reloc_hyp_t *h) const
    {
        double q[3] = { h->x, h->y, h->theta };
        double c = std::cos(q[2]), s = std::sin(q[2]);
        int hit = 0, through = 0;
        for (int i : fine_idx) {
            double sx = q[0] + c * pts[4 * i] - s * pts[4 * i + 1], sy = q[1] + s * pts[4 * i] + c * pts[4 * i + 1];
            double ex = q[0] + c * pts[4 * i + 2] - s * pts[4 * i + 3], ey = q[1] + s * pts[4 * i + 2] + c * pts[4 * i + 3];
            double r = std::hypot(ex - sx, ey - sy);
            if (r <= 0)
                continue;
            lfield::verdict_t v = fd.verdict(sx, sy, (ex - sx) / r, (ey - sy) / r, r, 3 * sigma);
            hit += v == lfield::HIT;
            through += v == lfield::THROUGH;
        }
        h->hit = (double)hit / std::max<size_t>(fine_idx.size(), 1);
        h->contradiction = hit + through >= 10 ? (double)through / (hit + through) : 0.0;
    }
};

// The coarse pass's table: a grid of g m over the map, padded by the cloud's reach so no look-up
// leaves it, each cell the log likelihood of a point there (blurred to the grid: distance less
// half a cell); and the candidate origins, free cells at least kFreeOfWalls from a wall.
struct table {
    double g = 0;
    int pad = 0, pw = 0, ph = 0;
    std::vector<float> t;
    std::vector<int> cands;

    table(const lfield &fd, double sigma, const std::vector<float> &pts)
    {
        double area = (double)fd.free_cells.size() * fd.map_res * fd.map_res, reach = 0;
        g = std::max({ 0.1, fd.map_res, std::sqrt(area / 12000) });
        for (size_t i = 0; i < pts.size(); i += 4)
            reach = std::max(reach, (double)std::hypot(pts[i + 2], pts[i + 3]));
        pad = (int)std::ceil(reach / g) + 2;
        pw = (int)std::ceil(fd.w * fd.res / g) + 2 * pad;
        ph = (int)std::ceil(fd.h * fd.res / g) + 2 * pad;
        double sc = std::max(sigma, 0.6 * g), k = 1.0 / (2 * sc * sc);
        t.resize((size_t)pw * ph);
        for (int j = 0; j < ph; j++)
            for (int i = 0; i < pw; i++) {
                int cell = fd.cell(fd.ox + (i - pad + 0.5) * g, fd.oy + (j - pad + 0.5) * g);
                bool free = cell >= 0 && fd.kind[(size_t)cell] == lfield::FREE;
                double d = cell < 0 ? INFINITY : std::max(0.0, (double)fd.dist[(size_t)cell] - 0.5 * g);
                t[(size_t)j * pw + i] = (float)std::log(std::exp(-d * d * k) + (free ? 0.1 : 0.01));
                if (free && fd.dist[(size_t)cell] >= kFreeOfWalls)
                    cands.push_back(j * pw + i);
            }
    }
    std::array<double, 4> pose(const lfield &fd, const cand &c) const
    {
        int ci = c.cell % pw - pad, cj = c.cell / pw - pad;
        return { fd.ox + (ci + 0.5) * g, fd.oy + (cj + 0.5) * g, wrap(2 * M_PI * c.heading / kHeadings), g };
    }
};

// Keeps a candidate's best two headings, 20 degrees apart at least.
void keep_best(float sum, int h, float &b1, int &h1, float &b2, int &h2)
{
    bool apart = std::abs(h - h1) >= 4 && std::abs(h - h1) <= kHeadings - 4;
    if (sum > b1) {
        if (apart) {
            b2 = b1;
            h2 = h1;
        }
        b1 = sum;
        h1 = h;
    } else if (sum > b2 && apart) {
        b2 = sum;
        h2 = h;
    }
}

// The coarse pass: every candidate at every heading scored with kCoarsePoints points, one table
// look-up each; the kRefined best (two headings per candidate at most), as map poses with the
// grid's step.
std::vector<std::array<double, 4>> coarse(const lfield &fd, double sigma, const std::vector<float> &pts)
{
    table tb(fd, sigma, pts);
    std::vector<int> idx = spread((int)pts.size() / 4, kCoarsePoints), off(idx.size());
    size_t nc = tb.cands.size();
    std::vector<float> b1(nc, -INFINITY), b2(nc, -INFINITY);
    std::vector<int> h1(nc, 0), h2(nc, 0);
    for (int h = 0; h < kHeadings; h++) {
        double th = 2 * M_PI * h / kHeadings, c = std::cos(th), s = std::sin(th);
        for (size_t j = 0; j < idx.size(); j++) {
            double px = pts[4 * idx[j] + 2], py = pts[4 * idx[j] + 3];
            off[j] = (int)std::lround((s * px + c * py) / tb.g) * tb.pw + (int)std::lround((c * px - s * py) / tb.g);
        }
        for (size_t ci = 0; ci < nc; ci++) {
            const float *t = tb.t.data() + tb.cands[ci];
            float sum = 0;
            for (int o : off)
                sum += t[o];
            keep_best(sum, h, b1[ci], h1[ci], b2[ci], h2[ci]);
        }
    }
    std::vector<cand> all;
    all.reserve(2 * nc);
    for (size_t ci = 0; ci < nc; ci++) {
        all.push_back({ b1[ci], tb.cands[ci], h1[ci] });
        if (std::isfinite(b2[ci]))
            all.push_back({ b2[ci], tb.cands[ci], h2[ci] });
    }
    size_t keep = std::min<size_t>(all.size(), kRefined);
    std::partial_sort(all.begin(), all.begin() + keep, all.end(),
                      [](const cand &a, const cand &b) { return a.score > b.score; });
    std::vector<std::array<double, 4>> out;
    for (size_t i = 0; i < keep; i++)
        out.push_back(tb.pose(fd, all[i]));
    return out;
}

}  // namespace

extern "C" int reloc_search(const mcl_t *f, const reloc_cloud_t *c, reloc_hyp_t *out, int max)
{
    int n = reloc_cloud_size(c);
    if (n == 0 || max <= 0)
        return 0;
    try {
        const lfield &fd = mcl_field(f);
        searcher se{ fd, mcl_sigma(f), c->kept, spread(n, kFinePoints) };
        std::vector<reloc_hyp_t> found;
        for (auto &q0 : coarse(fd, se.sigma, c->kept)) {
            double q[3] = { q0[0], q0[1], q0[2] }, sc;
            se.refine(q, q0[3] / 2, M_PI / kHeadings, &sc);
            found.push_back({ q[0], q[1], q[2], sc, 0, 0 });
        }
        std::sort(found.begin(), found.end(), [](const reloc_hyp_t &a, const reloc_hyp_t &b) { return a.score > b.score; });
        int m = 0;
        for (const reloc_hyp_t &h : found) {
            bool distinct = true;
            for (int i = 0; i < m && distinct; i++)
                distinct = std::hypot(h.x - out[i].x, h.y - out[i].y) > 1.0 || std::fabs(wrap(h.theta - out[i].theta)) > 0.35;
            if (!distinct)
                continue;
            out[m] = h;
            se.judge(&out[m]);
            if (++m == max)
                break;
        }
        return m;
    } catch (...) {
        errno = ENOMEM;
        return -1;
    }
}

extern "C" void reloc_judge_at(const mcl_t *f, const reloc_cloud_t *c, const double origin[3], reloc_hyp_t *out)
{
    *out = reloc_hyp_t{ origin[0], origin[1], origin[2], -INFINITY, 0, 0 };
    int n = reloc_cloud_size(c);
    if (n == 0)
        return;
    try {
        searcher se{ mcl_field(f), mcl_sigma(f), c->kept, spread(n, kFinePoints) };
        double q[3] = { origin[0], origin[1], origin[2] };
        se.refine(q, 0.05, M_PI / kHeadings / 2, &out->score, 0.1, 0.05);
        out->x = q[0], out->y = q[1], out->theta = q[2];
        se.judge(out);
    } catch (...) {
        // Out of memory: no score, the place counts as not fitting.
    }
}
