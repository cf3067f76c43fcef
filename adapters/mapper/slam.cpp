// slam: keyframes matched against the grid, a pose graph closed by matching against older
// keyframes, and the grid re-rendered from the keyframes after each optimization.
#include "adapters/mapper/slam.h"

#include <cerrno>
#include <algorithm>
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
    Scan few;                                  // its hits thinned (match_points): what a loop matches against
    double path;                               // m along the keyframes from the first
    double drift;                              // m the tracking may have drifted since the first (see drift_step)
};

double ms_since(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

// A grid of the hits of the keyframes since `first` (up to track_keyframes of them) that scans
// are matched against: the robot tracks itself on what it saw lately, never on the map of long
// ago, so that a drift shows when it comes back (to the loop closures) instead of being snapped
// away by the tracking and left in the map.
struct Tracker {
    std::unique_ptr<Grid> grid;
    int first = -1;                            // its first keyframe (-1: empty)
    int count = 0;                             // keyframes in it
    Pose centre;
};

struct slam {
    slam_params_t p;
    Pose pose0;
    std::unique_ptr<Grid> grid;                // the map shown (log-odds), never matched against
    Tracker trk[2];                            // two, half a life apart: the older is matched against
    std::unique_ptr<Grid> chain;               // the loop matcher's grid of an older stretch of path
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

extern "C" slam_t *slam_create(const slam_params_t *p, const double pose0[3])
{
    if (!p || !(p->resolution >= 0.01) || !(p->size_m >= 1) || p->size_m / p->resolution > 8000 ||
        !(p->l_hit > 0) || !(p->l_miss < 0) || !(p->sigma > 0) || !(p->kf_dist > 0) || !(p->kf_angle > 0) ||
        !(p->search_xy >= 0) || !(p->prior_xy > 0) || !(p->prior_th > 0) || !(p->search_th >= 0) || !(p->step_th > 0) || p->loop_every < 1 ||
        !(p->loop_drift >= 0) || !(p->loop_drift_per_m >= 0) || p->loop_chain < 1 || !(p->loop_optimize_xy >= 0) || !(p->loop_optimize_th >= 0) ||
        !(p->min_range >= 0) || !(p->odom_noise_xy >= 0) || !(p->odom_noise_th >= 0) || !(p->odom_noise_thd >= 0) ||
        !(p->search_max_xy >= p->search_xy) || !(p->search_max_th >= p->search_th) || !(p->search_max_xy <= 50) ||
        !(p->search_max_th <= M_PI) || !std::isfinite(p->grow_score) || !(p->disagree_sigma > 0) ||
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
                                         *p);
        int t = (int)std::ceil(p->track_size_m / p->resolution);
        for (Tracker &k : s->trk)
            k.grid = std::make_unique<Grid>(t, t, 0, 0, *p);
        s->grid->set_stamp_walls(true);
        int cn = (int)std::ceil(30.0 / p->resolution);
        s->chain = std::make_unique<Grid>(cn, cn, 0, 0, *p);
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
    /* Each beam's return in the sensor frame; NAN: the beam tells nothing, INFINITY: it saw nothing
     * up to range_max. REP 117: +inf is no return, -inf nearer than the sensor measures, NaN no
     * reading; a reading nearer than range_min (or min_range: a sensor's 0 or 0.1 mm error codes,
     * the robot's own body) is no wall either. */
    const double nearest = std::fmax(in->range_min, p.min_range);
    std::vector<double> px((size_t)in->n), py((size_t)in->n);
    for (int i = 0; i < in->n; i++) {
        double r = in->ranges[i], a = in->angle_min + i * in->angle_increment;
        bool none = r == INFINITY || (std::isfinite(r) && r >= in->range_max - 1e-3);
        bool hit = !none && std::isfinite(r) && r >= nearest;
        px[(size_t)i] = hit ? r * std::cos(a) : none ? INFINITY : NAN;
        py[(size_t)i] = hit ? r * std::sin(a) : none ? INFINITY : NAN;
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

// At most `max` of the scan's hits for the searches, one per square of a side grown until they
// fit (an adaptive voxel filter, as Cartographer's): a wall near the robot gives as many returns
// as a wall far away needs, and the search's cost goes with the points.
static Scan thin(const Scan &in, size_t max)
{
    if (in.hx.size() <= max)
        return in;
    Scan out;
    out.ox = in.ox, out.oy = in.oy;
    for (double side = 0.1; side < 100; side *= 1.5) {
        std::vector<uint64_t> keys;
        out.hx.clear(), out.hy.clear();
        for (size_t i = 0; i < in.hx.size(); i++) {
            uint64_t key = (uint64_t)(uint32_t)(int32_t)std::floor(in.hx[i] / side) << 32 |
                           (uint32_t)(int32_t)std::floor(in.hy[i] / side);
            if (std::find(keys.begin(), keys.end(), key) != keys.end())
                continue;
            keys.push_back(key);
            out.hx.push_back(in.hx[i]);
            out.hy.push_back(in.hy[i]);
        }
        if (out.hx.size() <= max)
            break;
    }
    return out;
}

// A tracker starts afresh, centred on the robot (its grid is track_size_m square).
static void tracker_restart(const slam_t *s, Tracker *t, int first, const Pose &at)
{
    const double r = s->p.resolution, half = t->grid->width() * r / 2;
    const Grid &g = *s->grid;
    t->grid->clear();
    /* On the map's lattice, and holding the walls the map has of this place: the recent
     * keyframes' hits come on top. */
    const double block = r * (1 << Grid::LEVELS);     /* the pyramids' blocks line up: copied whole */
    t->grid->set_origin(g.origin_x() + std::round((at.x - half - g.origin_x()) / block) * block,
                        g.origin_y() + std::round((at.y - half - g.origin_y()) / block) * block);
    t->grid->copy_likelihood(g);
    t->first = first;
    t->count = 0;
    t->centre = at;
}

// Keyframe k's hits into both trackers; a tracker that has lived track_keyframes keyframes (or
// whose robot nears its grid's edge) starts again from k. They start half a life apart, so the
// one matched against always holds at least half a life of keyframes.
static void tracker_add(slam_t *s, int k, const Pose &pose, const Scan &sc)
{
    const int life = std::max(2, (int)s->p.track_keyframes);
    const double reach = s->p.track_size_m / 2 - s->p.free_range - 1;
    for (int i = 0; i < 2; i++) {
        Tracker &t = s->trk[i];
        bool far = std::hypot(pose.x - t.centre.x, pose.y - t.centre.y) > reach;
        if (t.first < 0 ? (i == 0 || k >= life / 2) : (t.count >= life || far))
            tracker_restart(s, &t, k, pose);
        if (t.first >= 0) {
            t.grid->add_hits(pose, sc);
            t.count++;
        }
    }
}

// The tracker to match against: the one holding more keyframes.
static const Grid &tracker_grid(const slam_t *s)
{
    const Tracker &a = s->trk[0], &b = s->trk[1];
    return (b.first >= 0 && b.count > a.count) ? *b.grid : *a.grid;
}

// After an optimization: the map shown and the trackers drawn again from the moved keyframes.
static void rerender(slam_t *s)
{
    s->grid->clear();
    for (const Keyframe &k : s->kfs)
        s->grid->integrate(k.pose, k.scan);
    for (Tracker &t : s->trk) {
        if (t.first < 0)
            continue;
        t.grid->clear();
        t.grid->copy_likelihood(*s->grid);
        for (int i = t.first; i < (int)s->kfs.size(); i++)
            t.grid->add_hits(s->kfs[i].pose, s->kfs[i].scan);
    }
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

// The older keyframe the newest one may be back at: the nearest of those at least loop_min_gap
// keyframes back, within loop_radius plus what the drift since may have added. -1 if none.
static int loop_candidate(const slam_t *s, int k)
{
    const slam_params_t &p = s->p;
    const Keyframe &cur = s->kfs[k];
    int best = -1;
    double best_d = INFINITY;
    for (int j = 0; j <= k - p.loop_min_gap && cur.path - s->kfs[j].path >= p.loop_min_path; j++) {
        double d = std::hypot(s->kfs[j].pose.x - cur.pose.x, s->kfs[j].pose.y - cur.pose.y);
        double radius = p.loop_radius + (cur.drift - s->kfs[j].drift);
        if (d < std::min(radius, 2 * p.loop_radius) && d < best_d) {
            best_d = d;
            best = j;
        }
    }
    return best;
}

// The stretch of path around keyframe j (up to loop_chain keyframes each way, none of the last
// loop_min_gap) as a grid of their hits around keyframe j: what the robot saw when it was there.
// One grid, kept between attempts: its pages are touched once.
static const Grid &chain_grid(slam_t *s, int j, int k)
{
    const slam_params_t &p = s->p;
    const Pose &c = s->kfs[j].pose;
    Grid &local = *s->chain;
    const double half = local.width() * p.resolution / 2;
    local.clear();
    local.set_origin(c.x - half, c.y - half);
    local.begin_batch();
    for (int i = std::max(0, j - (int)p.loop_chain); i <= std::min(k - (int)p.loop_min_gap, j + (int)p.loop_chain); i++)
        local.add_hits(s->kfs[i].pose, s->kfs[i].few);
    local.end_batch();
    return local;
}

// Match the newest keyframe against the path around an older one it may be back at; a match
// that is clear (no rival elsewhere in the window), inside the window and within the drift the
// path between could have gathered becomes a loop edge, and the graph is optimized when the
// correction is large and confirmed.
static void try_loop(slam_t *s)
{
    const slam_params_t &p = s->p;
    int k = (int)s->kfs.size() - 1;
    if (!p.loop_closure || k - s->last_loop_try < p.loop_every || k < p.loop_min_gap)
        return;
    s->last_loop_try = k;
    const Keyframe &cur = s->kfs[k];
    int best = loop_candidate(s, k);
    if (best < 0)
        return;
    s->st.loop_candidates++;
    const Pose &c = s->kfs[best].pose;
    const Grid &local = chain_grid(s, best, k);
    /* The window covers what the matcher may have drifted along the path between the two. */
    const double drift = p.loop_drift + (cur.drift - s->kfs[best].drift);
    const double wxy = std::min(std::max(p.loop_search_xy, drift + 0.5), p.search_max_xy);
    MatchWindow coarse;
    coarse.xy = wxy, coarse.th = p.loop_search_th, coarse.step_th = 0.02, coarse.refine = false;
    coarse.prior_xy = coarse.prior_th = 0;
    coarse.rival_radius = 0.3, coarse.rival_floor = 0.9 * p.loop_max_rival;
    coarse.floor = 0.9 * p.loop_min_score;     /* no closure below it: the search prunes most of a wide window */
    coarse.seen_only = false;
    coarse.max_evals = p.loop_max_evals;
    Pose m1, m2;
    /* Along a corridor the scan fits nearly as well a metre further on: such a match is no
     * closure (on the office route 1 closure in 3 was 0.8-1.6 m wrong before this check). */
    bool cut = false;
    double rival = 0, csc = local.match(cur.few, cur.pose, coarse, &m1, &rival, nullptr, &cut);
    if (cut) {                  /* fits poorly everywhere: no place found in time */
        s->st.loop_cut++;
        return;
    }
    if (rival > p.loop_max_rival * csc) {
        s->st.loop_ambiguous++;
        return;
    }
    /* A best pose at the window's edge is a maximum cut off by the window, not a place found
     * (along the office's corridors such closures were 1.4-1.9 m wrong); and the scan matcher does
     * not drift by more than a few cm per metre between the two keyframes. */
    Pose moved = between(cur.pose, m1);
    if (std::fabs(m1.x - cur.pose.x) > wxy - 2 * p.resolution || std::fabs(m1.y - cur.pose.y) > wxy - 2 * p.resolution ||
        std::fabs(moved.th) > p.loop_search_th - 2 * coarse.step_th || std::hypot(moved.x, moved.y) > drift) {
        s->st.loop_implausible++;
        return;
    }
    MatchWindow fine;
    fine.xy = 0.1, fine.th = 0.02, fine.step_th = 0.004, fine.prior_xy = fine.prior_th = 0, fine.seen_only = false;
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
    /* Within 0.1 m and 0.03 rad, and what the tracking may have drifted between the two. */
    const double between_drift = recent ? cur.drift - s->kfs[s->pending_edge.b].drift : 0;
    if (!recent || std::hypot(agree.x, agree.y) > 0.1 + between_drift || std::fabs(agree.th) > 0.03 + between_drift / 10) {
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

// The prior and the window of a scan's match: how far the odometry may have erred since the
// last scan grows with what it measured (a robot whose scans come a metre apart errs by
// decimetres between them; one scanning every 5 cm, by millimetres).
static MatchWindow track_window(const slam_t *s, const Pose &moved)
{
    const slam_params_t &p = s->p;
    double dist = std::hypot(moved.x, moved.y), turn = std::fabs(moved.th);
    double exy = p.odom_noise_xy * dist, eth = p.odom_noise_th * turn + p.odom_noise_thd * dist;
    MatchWindow w;
    w.xy = p.search_xy + 3 * exy, w.th = p.search_th + 3 * eth, w.step_th = p.step_th;
    w.prior_xy = p.prior_xy + exy, w.prior_th = p.prior_th + eth;
    if (!s->have_odom) {        /* after an odometry restart the robot may have moved unseen */
        w.xy *= 3;
        w.th *= 3;
        w.prior_xy *= 3;
        w.prior_th *= 3;
    }
    w.xy = std::min(w.xy, p.search_max_xy);
    w.th = std::min(w.th, p.search_max_th);
    return w;
}

// The scan matched around the odometry's prediction; a poor match (or one the window cut off)
// searches again in a window twice as wide, with a prior half as firm, until the match is good
// or the window as wide as allowed: the odometry is a prior, not the truth. A match far outside
// what the odometry could have erred is a disagreement, counted.
static double track(slam_t *s, const Scan &all, const Pose &guess, const Pose &moved, Pose *out)
{
    const slam_params_t &p = s->p;
    const Grid &g = tracker_grid(s);
    /* Only the hits on cells the map has seen: a hit on a part of a wall never seen scores
     * nothing but by sliding the robot back onto what is known. */
    Scan seen = s->grid->seen_hits(all, guess);
    const Scan sc = thin(seen.hx.size() >= 20 ? seen : all, (size_t)p.match_points);
    MatchWindow win = track_window(s, moved);
    win.seen_only = false;
    const double sxy = win.prior_xy, sth = win.prior_th;
    bool edge;
    double score = g.match(sc, guess, win, out, nullptr, &edge);
    const double contra = s->grid->contradiction(all, *out, p.l_min / 2);
    while ((score < p.grow_score || edge) && (win.xy < p.search_max_xy || win.th < p.search_max_th)) {
        /* Each wider window at twice the angular step (a coarse search), the pose it finds then
         * searched again nearby at the fine step. */
        win.xy = std::min(2 * win.xy, p.search_max_xy);
        win.th = std::min(2 * win.th, p.search_max_th);
        win.prior_xy *= 2;
        win.prior_th *= 2;
        win.step_th *= 2;
        win.max_evals = p.loop_max_evals;
        Pose m, f;
        g.match(sc, guess, win, &m, nullptr, &edge);
        MatchWindow fine;
        fine.xy = 2 * p.resolution, fine.th = win.step_th, fine.step_th = p.step_th, fine.prior_xy = fine.prior_th = 0;
        fine.seen_only = false;
        double sc2 = g.match(sc, m, fine, &f);
        s->st.window_grown++;
        /* Along a corridor a pose a metre away scores nearly as well, and a robot entering a
         * place not mapped yet scores poorly where it is: the wider window's pose is taken only
         * when it scores clearly better and puts no more hits where the map is surely free. */
        if (sc2 > score + p.grow_gain && s->grid->contradiction(all, f, p.l_min / 2) <= contra + 0.02) {
            score = sc2;
            *out = f;
        }
    }
    Pose d = between(guess, *out);
    if (std::hypot(d.x / sxy, d.y / sxy) + std::fabs(d.th / sth) > p.disagree_sigma)
        s->st.odometry_disagreements++;
    return score;
}

// How far the tracking may have drifted over a step of `step` m: loop_drift_per_m of it for a
// match of loop_drift_score, more for a poorer one, less for a better (a simulator's scans fit
// their map at 0.9 and drift by millimetres a metre; a real robot's at 0.5-0.8, by centimetres).
static double drift_step(const slam_t *s, double step)
{
    const slam_params_t &p = s->p;
    double f = (1 - std::min(s->st.last_score, 0.99)) / (1 - p.loop_drift_score);
    return step * p.loop_drift_per_m * std::clamp(f, 0.1, 3.0);
}

// A new scan drawn into the grid at the robot's pose; the walls it clears are counted (a
// re-render draws them again, uncounted).
static void add_to_grid(slam_t *s, const Scan &sc)
{
    int64_t cleared = s->grid->cleared();
    if (!s->grid->integrate(s->last_pose, sc))
        s->st.off_grid++;
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
        Pose m;
        double score = track(s, sc, guess, s->have_odom ? between(s->last_odom, o) : Pose{}, &m);
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
            double step = s->kfs.empty() ? 0 : std::hypot(s->last_pose.x - s->kfs.back().pose.x,
                                                          s->last_pose.y - s->kfs.back().pose.y);
            double path = s->kfs.empty() ? 0 : s->kfs.back().path + step;
            double drift = s->kfs.empty() ? 0 : s->kfs.back().drift + drift_step(s, step);
            s->kfs.push_back({ s->last_pose, sc, thin(sc, (size_t)s->p.match_points), path, drift });
            s->odom_since_kf = 0;
            s->st.keyframes = (int64_t)s->kfs.size();
            add_to_grid(s, sc);
            tracker_add(s, (int)s->kfs.size() - 1, s->last_pose, sc);
            try_loop(s);
        } else {
            add_to_grid(s, sc);     /* past the bound the map still grows */
            tracker_add(s, (int)s->kfs.size(), s->last_pose, sc);
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

extern "C" void slam_get_stats(const slam_t *s, slam_stats_t *st)
{
    *st = s->st;
}
