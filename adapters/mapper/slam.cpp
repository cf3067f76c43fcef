// slam: keyframes matched against the grid, a pose graph closed by matching against older
// keyframes, and the grid re-rendered from the keyframes after each optimization.
#include "adapters/mapper/slam.h"

#include <cerrno>
#include <chrono>
#include <cmath>
#include <memory>
#include <new>
#include <vector>

#include "adapters/mapper/posegraph.hpp"
#include "adapters/mapper/scangrid.hpp"
#include "core/err.h"

using namespace mapper;

namespace {

struct Keyframe {
    Pose pose;
    Scan scan;
};

double ms_since(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

struct slam {
    slam_params_t p;
    Pose pose0;
    std::unique_ptr<Grid> grid;
    std::vector<Keyframe> kfs;
    std::vector<Edge> edges;
    bool have_odom = false;
    Pose last_odom, last_pose;
    double odom_since_kf = 0;                  // m the odometry went since the last keyframe
    int last_loop_try = 0;
    bool pending = false;                      // a large correction waiting for a second closure
    Edge pending_edge;
    Pose pending_fix;                          // map-frame transform it would apply to the robot
    slam_stats_t st{};
};

extern "C" void slam_params_default(slam_params_t *p)
{
    const slam_params_t d = SLAM_PARAMS_DEFAULTS;
    *p = d;
}

static GridParams grid_params(const slam_params_t *p)
{
    GridParams g;
    g.resolution = p->resolution;
    g.l_hit = p->l_hit;
    g.l_miss = p->l_miss;
    g.l_min = p->l_min;
    g.l_max = p->l_max;
    g.sigma = p->sigma;
    return g;
}

extern "C" slam_t *slam_create(const slam_params_t *p, const double pose0[3])
{
    if (!p || !(p->resolution >= 0.01) || !(p->size_m >= 1) || p->size_m / p->resolution > 8000 ||
        !(p->l_hit > 0) || !(p->l_miss < 0) || !(p->sigma > 0) || !(p->kf_dist > 0) || !(p->kf_angle > 0) ||
        !(p->search_xy >= 0) || !(p->prior_xy > 0) || !(p->prior_th > 0) || !(p->search_th >= 0) || !(p->step_th > 0) || p->loop_every < 1 ||
        !(p->loop_drift >= 0) || !(p->loop_drift_per_kf >= 0) || !(p->loop_optimize_xy >= 0) || !(p->loop_optimize_th >= 0) ||
        !std::isfinite(pose0[0]) || !std::isfinite(pose0[1]) || !std::isfinite(pose0[2])) {
        errno = EINVAL;
        return nullptr;
    }
    try {
        auto *s = new slam;
        s->p = *p;
        s->pose0 = { pose0[0], pose0[1], wrap(pose0[2]) };
        int n = (int)std::ceil(p->size_m / p->resolution);
        s->grid = std::make_unique<Grid>(n, n, pose0[0] - n * p->resolution / 2, pose0[1] - n * p->resolution / 2,
                                         grid_params(p));
        return s;
    } catch (const std::bad_alloc &) {
        errno = ENOMEM;
        return nullptr;
    }
}

extern "C" void slam_destroy(slam_t *s)
{
    delete s;
}

static bool make_scan(const slam_t *s, const slam_scan_t *in, Scan *out)
{
    if (!in || !in->ranges || in->n <= 0 || in->n > 100000 || !std::isfinite(in->angle_min) ||
        !std::isfinite(in->angle_increment) || !(in->range_max > 0) || !std::isfinite(in->range_max) ||
        !std::isfinite(in->range_min))
        return false;
    const slam_params_t &p = s->p;
    out->ox = p.laser_x;
    out->oy = p.laser_y;
    double c0 = std::cos(p.laser_theta), s0 = std::sin(p.laser_theta);
    double free_r = std::fmin(p.free_range, in->range_max);
    /* Each beam's return in the sensor frame (NaN: no reading, +inf: nothing within range). */
    std::vector<double> px((size_t)in->n), py((size_t)in->n);
    for (int i = 0; i < in->n; i++) {
        double r = in->ranges[i], a = in->angle_min + i * in->angle_increment;
        bool ok = std::isfinite(r) && r >= in->range_min && r > 0;
        bool hit = ok && r < in->range_max - 1e-3;
        px[(size_t)i] = hit ? r * std::cos(a) : ok ? INFINITY : NAN;
        py[(size_t)i] = hit ? r * std::sin(a) : ok ? INFINITY : NAN;
    }
    for (int i = 0; i < in->n; i++) {
        double r = in->ranges[i];
        if (std::isnan(px[(size_t)i]))
            continue;               /* a beam with no reading tells nothing */
        double a = in->angle_min + i * in->angle_increment;
        bool hit = std::isfinite(px[(size_t)i]);
        /* A return comes from a wall's surface, the boundary between the free cell before it and
         * the wall's own: half a cell further along the beam is inside the wall, for the map and
         * for the matcher alike (at the surface itself, walls seen from one side would be drawn a
         * cell out of place). The beam clears the cells up to `clear_margin` in front of the
         * surface: along the beam that is clear_margin / sin(incidence), the surface's direction
         * taken from the neighbouring returns, so a beam that meets a wall at a grazing angle
         * does not run through the wall's row of cells before its return (it wore the walls
         * along corridors away: with the true poses 3 % of the walls seen were drawn free). */
        auto along = [&](double d, std::vector<float> &vx, std::vector<float> &vy) {
            double lx = d * std::cos(a), ly = d * std::sin(a);
            vx.push_back((float)(p.laser_x + c0 * lx - s0 * ly));
            vy.push_back((float)(p.laser_y + s0 * lx + c0 * ly));
        };
        if (hit) {
            double sin_inc = 1;
            for (int j : { i - 1, i + 1 }) {
                if (j < 0 || j >= in->n || !std::isfinite(px[(size_t)j]))
                    continue;
                double tx = px[(size_t)j] - px[(size_t)i], ty = py[(size_t)j] - py[(size_t)i], tl = std::hypot(tx, ty);
                if (tl > 1e-6 && tl < p.clear_surface)
                    sin_inc = std::fmin(sin_inc, std::fabs(std::cos(a) * ty - std::sin(a) * tx) / tl);
            }
            along(r + p.resolution / 2, out->hx, out->hy);
            along(std::fmax(0, r - std::fmin(p.clear_margin / std::fmax(sin_inc, 0.05), p.clear_back_max)), out->fx,
                  out->fy);
        } else {
            along(free_r, out->mx, out->my);
        }
    }
    return true;
}

static void rerender(slam_t *s)
{
    s->grid->clear();
    for (const Keyframe &k : s->kfs)
        s->grid->integrate(k.pose, k.scan);
}

static int optimize_graph(slam_t *s, int fixed_upto = 0)
{
    auto t0 = std::chrono::steady_clock::now();
    std::vector<Pose> nodes;
    nodes.reserve(s->kfs.size());
    for (const Keyframe &k : s->kfs)
        nodes.push_back(k.pose);
    OptResult r = optimize(nodes, s->edges, 50, fixed_upto);
    if (!r.ok)
        return -1;
    Pose newest_before = s->kfs.back().pose;
    for (size_t i = 0; i < nodes.size(); i++)
        s->kfs[i].pose = nodes[i];
    // The robot is where it was relative to the newest keyframe, which moved.
    s->last_pose = compose(s->kfs.back().pose, between(newest_before, s->last_pose));
    rerender(s);
    s->st.optimizations++;
    s->st.last_opt_ms = ms_since(t0);
    return 0;
}

// Match the newest keyframe against a grid of older keyframes near it; on success add the edge
// and optimize.
static void try_loop(slam_t *s)
{
    const slam_params_t &p = s->p;
    int k = (int)s->kfs.size() - 1;
    if (!p.loop_closure || k - s->last_loop_try < p.loop_every || k < p.loop_min_gap)
        return;
    s->last_loop_try = k;
    const Keyframe &cur = s->kfs[k];
    int best = -1;
    double best_d = p.loop_radius;
    for (int j = 0; j <= k - p.loop_min_gap; j++) {
        double d = std::hypot(s->kfs[j].pose.x - cur.pose.x, s->kfs[j].pose.y - cur.pose.y);
        if (d < best_d) {
            best_d = d;
            best = j;
        }
    }
    if (best < 0)
        return;
    s->st.loop_candidates++;
    const Pose &c = s->kfs[best].pose;
    double half = 12.0;
    int n = (int)std::ceil(2 * half / p.resolution);
    Grid local(n, n, c.x - half, c.y - half, grid_params(&p));
    int used = 0;
    for (int j = 0; j <= k - p.loop_min_gap && used < 60; j++)
        if (std::hypot(s->kfs[j].pose.x - c.x, s->kfs[j].pose.y - c.y) < 5.0) {
            local.integrate(s->kfs[j].pose, s->kfs[j].scan);
            used++;
        }
    MatchWindow coarse{ p.loop_search_xy, p.loop_search_th, 0.01, 2, false, 0, 0, 0.3 };
    Pose m1, m2;
    /* Along a corridor the scan fits nearly as well a metre further on: such a match is no
     * closure (on the office route 1 closure in 3 was 0.8-1.6 m wrong before this check). */
    double rival = 0, csc = local.match(cur.scan, cur.pose, coarse, &m1, &rival);
    if (rival > p.loop_max_rival * csc) {
        s->st.loop_ambiguous++;
        return;
    }
    /* A best pose at the window's edge is a maximum cut off by the window, not a place found
     * (along the office's corridors such closures were 1.4-1.9 m wrong); and the scan matcher does
     * not drift by more than a few cm per metre between the two keyframes. */
    Pose moved = between(cur.pose, m1);
    if (std::fabs(m1.x - cur.pose.x) > p.loop_search_xy - coarse.step_cells * p.resolution ||
        std::fabs(m1.y - cur.pose.y) > p.loop_search_xy - coarse.step_cells * p.resolution ||
        std::fabs(moved.th) > p.loop_search_th - 2 * coarse.step_th ||
        std::hypot(moved.x, moved.y) > p.loop_drift + p.loop_drift_per_kf * (k - best)) {
        s->st.loop_implausible++;
        return;
    }
    MatchWindow fine{ 0.1, 0.02, 0.004, 1, true, 0, 0 };
    double sc = local.match(cur.scan, m1, fine, &m2);
    if (sc < p.loop_min_score || cur.scan.hx.size() < 40)
        return;
    Edge e;
    e.a = best;
    e.b = k;
    e.z = between(c, m2);
    e.sigma_xy = 0.05;
    e.sigma_th = 0.02;
    e.loop = true;
    /* A closure that agrees with the graph is kept for later. One that moves the robot less than
     * the scan matcher's own reach optimizes nothing: matching every scan against the whole map
     * already holds it together at that scale, and the closures' own errors (median 2-3 cm, one in
     * ten 0.1-0.3 m or 0.02-0.05 rad) bent the map more than they mended (docs/mapping.md). */
    Pose fixed = compose(c, e.z), d = between(cur.pose, fixed);
    if (std::hypot(d.x, d.y) <= p.loop_optimize_xy && std::fabs(d.th) <= p.loop_optimize_th) {
        s->edges.push_back(e);
        s->st.loop_closures++;
        return;
    }
    /* A large correction is believed when the next closure, against another place, asks for the
     * same one: a real drift moves the robot and what it saw since alike, a look-alike place does
     * not repeat itself. */
    Pose fix = compose(fixed, between(cur.pose, Pose{}));
    bool recent = s->pending && k - s->pending_edge.b <= 3 * p.loop_every;
    Pose agree = recent ? between(compose(s->pending_fix, cur.pose), fixed) : Pose{};
    if (!recent || std::hypot(agree.x, agree.y) > 0.1 || std::fabs(agree.th) > 0.03) {
        if (s->pending)
            s->st.loop_unconfirmed++;
        s->pending = true;
        s->pending_edge = e;
        s->pending_fix = fix;
        return;
    }
    s->pending = false;
    s->edges.push_back(s->pending_edge);
    s->edges.push_back(e);
    s->st.loop_closures += 2;
    /* What came before the older of the two places stays: the drift is in what came after. */
    optimize_graph(s, std::min(best, s->pending_edge.a));
}

// A new scan drawn into the grid at the robot's pose; the walls it clears are counted (a
// re-render draws them again, uncounted).
static void add_to_grid(slam_t *s, const Scan &sc)
{
    int64_t cleared = s->grid->cleared();
    s->grid->integrate(s->last_pose, sc);
    s->st.cells_cleared += s->grid->cleared() - cleared;
}

extern "C" int slam_add_scan(slam_t *s, const double odom[3], const slam_scan_t *scan, double pose[3])
{
    Scan sc;
    if (!std::isfinite(odom[0]) || !std::isfinite(odom[1]) || !std::isfinite(odom[2]) || !make_scan(s, scan, &sc))
        return marie_fail(EINVAL);
    auto t0 = std::chrono::steady_clock::now();
    Pose o{ odom[0], odom[1], odom[2] };
    s->st.scans++;
    int added = 0;
    if (s->kfs.empty()) {
        s->last_pose = s->pose0;
    } else {
        Pose guess = s->have_odom ? compose(s->last_pose, between(s->last_odom, o)) : s->last_pose;
        MatchWindow win{ s->p.search_xy, s->p.search_th, s->p.step_th, 1, true, s->p.prior_xy, s->p.prior_th };
        if (!s->have_odom) {        /* after an odometry restart the robot may have moved unseen */
            win.xy *= 3;
            win.th *= 3;
            win.prior_xy *= 3;
            win.prior_th *= 3;
        }
        Pose m;
        double score = s->grid->match(sc, guess, win, &m);
        s->st.last_score = score;
        if (score >= s->p.min_score) {
            s->st.matches++;
            s->last_pose = m;
        } else {
            s->st.match_failures++;
            s->last_pose = guess;
        }
    }
    if (s->have_odom) {
        Pose d = between(s->last_odom, o);
        s->odom_since_kf += std::hypot(d.x, d.y);
    }
    s->last_odom = o;
    s->have_odom = true;
    bool new_kf = s->kfs.empty();
    if (!new_kf) {
        Pose d = between(s->kfs.back().pose, s->last_pose);
        /* The odometry's own travel counts too: a match that cannot see the robot advance
         * (a long room, its far wall out of range) must not keep the map from growing. */
        new_kf = std::hypot(d.x, d.y) >= s->p.kf_dist || std::fabs(d.th) >= s->p.kf_angle ||
                 s->odom_since_kf >= 2 * s->p.kf_dist;
    }
    if (new_kf) {
        if ((int)s->kfs.size() < s->p.max_keyframes) {
            if (!s->kfs.empty()) {
                Edge e;
                e.a = (int)s->kfs.size() - 1;
                e.b = e.a + 1;
                e.z = between(s->kfs.back().pose, s->last_pose);
                e.sigma_xy = 0.02;
                e.sigma_th = 0.01;
                s->edges.push_back(e);
            }
            s->kfs.push_back({ s->last_pose, sc });
            s->odom_since_kf = 0;
            s->st.keyframes = (int64_t)s->kfs.size();
            add_to_grid(s, sc);
            try_loop(s);
        } else {
            add_to_grid(s, sc);     /* past the bound the map still grows */
        }
        added = 1;
    }
    s->st.last_match_ms = ms_since(t0);
    if (pose) {
        pose[0] = s->last_pose.x;
        pose[1] = s->last_pose.y;
        pose[2] = s->last_pose.th;
    }
    return added;
}

extern "C" void slam_pose(const slam_t *s, const double odom[3], double pose[3])
{
    Pose r = s->last_pose;
    if (s->have_odom)
        r = compose(s->last_pose, between(s->last_odom, { odom[0], odom[1], odom[2] }));
    else if (s->kfs.empty())
        r = s->pose0;
    pose[0] = r.x;
    pose[1] = r.y;
    pose[2] = r.th;
}

extern "C" void slam_odometry_reset(slam_t *s)
{
    s->have_odom = false;
}

extern "C" occmap_t *slam_render(const slam_t *s)
{
    return slam_render_blocks(s, 1);
}

extern "C" occmap_t *slam_render_blocks(const slam_t *s, int block)
{
    int x0, y0, x1, y1;
    s->grid->bounds(&x0, &y0, &x1, &y1);
    if (x1 <= x0 || y1 <= y0 || block < 1) {
        errno = block < 1 ? EINVAL : ENOENT;
        return nullptr;
    }
    const Grid &g = *s->grid;
    x0 = std::max(0, (x0 - 1) / block * block), y0 = std::max(0, (y0 - 1) / block * block);
    x1 = std::min(g.width(), (x1 + block) / block * block), y1 = std::min(g.height(), (y1 + block) / block * block);
    double r = s->p.resolution;
    occmap_t *m = occmap_create(x1 - x0, y1 - y0, r, g.origin_x() + x0 * r, g.origin_y() + y0 * r);
    if (!m)
        return nullptr;
    for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++) {
            int8_t v = OCCMAP_UNKNOWN;
            if (g.seen(x, y)) {
                double pr = 1 / (1 + std::exp(-(double)g.log_odds(x, y)));
                v = (int8_t)std::lround(std::fmin(100, std::fmax(0, 100 * pr)));
            }
            m->cells[(size_t)(y - y0) * m->width + (x - x0)] = v;
        }
    return m;
}

extern "C" int slam_keyframes(const slam_t *s, double *poses, int max)
{
    int n = 0;
    for (const Keyframe &k : s->kfs) {
        if (n >= max)
            break;
        poses[3 * n] = k.pose.x;
        poses[3 * n + 1] = k.pose.y;
        poses[3 * n + 2] = k.pose.th;
        n++;
    }
    return (int)s->kfs.size() < max ? (int)s->kfs.size() : max;
}

extern "C" void slam_get_stats(const slam_t *s, slam_stats_t *st)
{
    *st = s->st;
}

extern "C" int slam_optimize(slam_t *s)
{
    if (s->kfs.size() < 2)
        return -1;
    return optimize_graph(s);
}
