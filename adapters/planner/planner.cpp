// planner: A* (map/gridpath.h) or OMPL geometric planning in R2 over an inflated occupancy grid.
// The inflation comes from the map's clearance (map/clearance.h); laser obstacles are stamped as
// robot-radius disks.
#include "adapters/planner/planner.h"
#include "core/err.h"
#include "map/clearance.h"
#include "map/gridpath.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <unordered_map>
#include <vector>

#include <ompl/base/spaces/RealVectorStateSpace.h>
#include <ompl/geometric/PathSimplifier.h>
#include <ompl/geometric/SimpleSetup.h>
#include <ompl/geometric/planners/prm/PRM.h>
#include <ompl/geometric/planners/rrt/RRTConnect.h>
#include <ompl/util/Console.h>
#include <ompl/util/RandomNumbers.h>

namespace ob = ompl::base;
namespace og = ompl::geometric;

struct planner {
    planner_params_t p_{};             // p_.algorithm is the caller's: algo_ is what is kept
    planner_algo_t algo_ = PLANNER_GRID;
    double footprint_ = 0;              // the robot's own radius, without the clearance
    int w_ = 0, h_ = 0;
    double res_ = 0, ox_ = 0, oy_ = 0;
    std::vector<uint8_t> static_free_;  // the robot fits here according to the map
    std::vector<float> dist_;           // m to the nearest map obstacle
    std::vector<int8_t> cells_;         // the map's cells, to say why a place is refused
    std::vector<uint16_t> dyn_;         // how many laser obstacle disks cover each cell
    std::unordered_map<int, double> obstacles_;  // cell -> last time seen
    std::vector<std::pair<int, int>> disk_;      // cell offsets within the robot radius
    std::unique_ptr<og::SimpleSetup> ss_;
    bool layer_changed_ = false;

    bool cell_free(int cx, int cy) const
    {
        if (cx < 0 || cy < 0 || cx >= w_ || cy >= h_)
            return false;
        size_t i = (size_t)cy * w_ + cx;
        return static_free_[i] && dyn_[i] == 0;
    }
    bool free_xy(double x, double y) const
    {
        double fx = (x - ox_) / res_, fy = (y - oy_) / res_;
        if (fx < 0 || fy < 0)
            return false;
        return cell_free((int)fx, (int)fy);
    }
    void stamp(int cell, int delta)
    {
        int cx = cell % w_, cy = cell / w_;
        for (auto &d : disk_) {
            int x = cx + d.first, y = cy + d.second;
            if (x >= 0 && y >= 0 && x < w_ && y < h_)
                dyn_[(size_t)y * w_ + x] = (uint16_t)(dyn_[(size_t)y * w_ + x] + delta);
        }
    }
    // Nearest free point within max_d of (x, y), searching outwards ring by ring.
    bool snap(double &x, double &y, double max_d) const
    {
        if (free_xy(x, y))
            return true;
        int cx = (int)std::floor((x - ox_) / res_), cy = (int)std::floor((y - oy_) / res_);
        int rmax = (int)std::ceil(max_d / res_);
        double best = INFINITY;
        int bx = 0, by = 0;
        for (int r = 1; r <= rmax && !std::isfinite(best); r++)
            for (int dy = -r; dy <= r; dy++)
                for (int dx = -r; dx <= r; dx++) {
                    if (std::max(std::abs(dx), std::abs(dy)) != r || !cell_free(cx + dx, cy + dy))
                        continue;
                    double d = std::hypot(dx, dy);
                    if (d < best && d * res_ <= max_d) { best = d; bx = cx + dx; by = cy + dy; }
                }
        if (!std::isfinite(best))
            return false;
        x = ox_ + (bx + 0.5) * res_;
        y = oy_ + (by + 0.5) * res_;
        return true;
    }
};

extern "C" void planner_params_default(planner_params_t *p)
{
    const planner_params_t d = PLANNER_PARAMS_DEFAULTS;
    *p = d;
}

extern "C" int planner_algorithm(const char *name)
{
    static const char *const names[] = { "rrtconnect", "prm", "grid" };   // planner_algo_t's order
    for (int i = 0; name && i < 3; i++)
        if (strcmp(name, names[i]) == 0)
            return i;
    return marie_fail(EINVAL);
}

extern "C" planner_t *planner_create(const occmap_t *map, const planner_params_t *p, uint64_t seed)
{
    int algo = p ? planner_algorithm(p->algorithm) : -1;
    if (!map || algo < 0 || !(p->robot_radius >= 0) || !(p->robot_clearance >= 0) || !(p->time_limit > 0)) {
        errno = EINVAL;
        return nullptr;
    }
    static bool seeded = false;
    if (!seeded) {
        // OMPL's seed is process-wide and may only be set before its first generator exists.
        if (seed)
            ompl::RNG::setSeed(seed);
        ompl::msg::setLogLevel(ompl::msg::LOG_WARN);
        seeded = true;
    }
    planner_t *pl = new (std::nothrow) planner;
    if (!pl) {
        errno = ENOMEM;
        return nullptr;
    }
    try {
        pl->p_ = *p;
        pl->algo_ = (planner_algo_t)algo;
        pl->p_.robot_radius = p->robot_radius + p->robot_clearance;   // everything below inflates by both
        pl->footprint_ = p->robot_radius;
        pl->w_ = map->width;
        pl->h_ = map->height;
        pl->res_ = map->resolution;
        pl->ox_ = map->origin_x;
        pl->oy_ = map->origin_y;
        size_t ncell = (size_t)map->width * map->height;
        // The same clearance marie-eval picks its goals with (map/clearance.h).
        std::unique_ptr<float, decltype(&std::free)> cl(occmap_clearance(map, p->unknown_is_free), &std::free);
        if (!cl)
            throw std::bad_alloc();
        pl->dist_.assign(cl.get(), cl.get() + ncell);
        pl->cells_.assign(map->cells, map->cells + ncell);
        pl->static_free_.resize(ncell);
        pl->dyn_.assign(ncell, 0);
        for (size_t i = 0; i < ncell; i++)
            pl->static_free_[i] = pl->dist_[i] > pl->p_.robot_radius;
        int rr = (int)std::ceil(pl->p_.robot_radius / map->resolution);
        for (int dy = -rr; dy <= rr; dy++)
            for (int dx = -rr; dx <= rr; dx++)
                if (std::hypot(dx, dy) * map->resolution <= pl->p_.robot_radius + map->resolution * 0.5)
                    pl->disk_.emplace_back(dx, dy);

        auto space = std::make_shared<ob::RealVectorStateSpace>(2);
        ob::RealVectorBounds b(2);
        b.setLow(0, map->origin_x);
        b.setHigh(0, map->origin_x + map->width * map->resolution);
        b.setLow(1, map->origin_y);
        b.setHigh(1, map->origin_y + map->height * map->resolution);
        space->setBounds(b);
        pl->ss_.reset(new og::SimpleSetup(space));
        pl->ss_->setStateValidityChecker([pl](const ob::State *s) {
            const auto *v = s->as<ob::RealVectorStateSpace::StateType>();
            return pl->free_xy(v->values[0], v->values[1]);
        });
        // Check motions at half a cell so no wall corner is skipped.
        pl->ss_->getSpaceInformation()->setStateValidityCheckingResolution(
            0.5 * map->resolution / space->getMaximumExtent());
        ob::PlannerPtr planner;
        if (pl->algo_ == PLANNER_PRM) {
            planner = std::make_shared<og::PRM>(pl->ss_->getSpaceInformation());
        } else {
            auto rrt = std::make_shared<og::RRTConnect>(pl->ss_->getSpaceInformation());
            if (p->range > 0)
                rrt->setRange(p->range);
            planner = rrt;
        }
        pl->ss_->setPlanner(planner);
        pl->ss_->setup();
    } catch (...) {
        delete pl;
        errno = ENOMEM;
        return nullptr;
    }
    return pl;
}

extern "C" void planner_destroy(planner_t *pl)
{
    delete pl;
}

extern "C" bool planner_free(const planner_t *pl, double x, double y)
{
    return pl->free_xy(x, y);
}

// to_poses: the path's points as (x, y, heading) triples, each heading toward the next point,
// the last one the goal's: *poses malloc'd, *n of them. 0, or -1 with errno ENOMEM.
static int to_poses(const std::vector<std::pair<double, double>> &pts, double goal_heading, double **poses, int *n)
{
    double *out = (double *)std::malloc(pts.size() * 3 * sizeof(double));
    if (!out)
        return marie_fail(ENOMEM);
    for (size_t i = 0; i < pts.size(); i++) {
        out[3 * i] = pts[i].first;
        out[3 * i + 1] = pts[i].second;
        out[3 * i + 2] = i + 1 < pts.size() ? std::atan2(pts[i + 1].second - pts[i].second, pts[i + 1].first - pts[i].first)
                                             : goal_heading;
    }
    *poses = out;
    *n = (int)pts.size();
    return 0;
}

// The grid search: the default, and the answer when sampling finds nothing (it rarely finds a
// passage barely wider than the robot; the grid search always does).
static int grid_plan(planner_t *pl, const double start[3], const double goal[3], double sx, double sy, double gx,
                     double gy, double **poses, int *n)
{
    size_t nc = (size_t)pl->w_ * pl->h_;
    std::vector<uint8_t> pass(nc);
    for (size_t i = 0; i < nc; i++)
        pass[i] = pl->static_free_[i] && pl->dyn_[i] == 0;
    auto cell = [pl](double x, double y) {
        return (int)std::floor((y - pl->oy_) / pl->res_) * pl->w_ + (int)std::floor((x - pl->ox_) / pl->res_);
    };
    int *cells = nullptr, nn = 0;
    if (gridpath_find(pl->w_, pl->h_, pass.data(), cell(sx, sy), cell(gx, gy), &cells, &nn) < 0)
        return errno == ENOMEM ? -1 : marie_fail(ENOENT);
    nn = gridpath_shortcut(pl->w_, pl->h_, pass.data(), cells, nn);
    std::vector<std::pair<double, double>> pts;
    pts.emplace_back(start[0], start[1]);
    for (int i = 1; i + 1 < nn; i++)
        pts.emplace_back(pl->ox_ + (cells[i] % pl->w_ + 0.5) * pl->res_, pl->oy_ + (cells[i] / pl->w_ + 0.5) * pl->res_);
    std::free(cells);
    if (sx != start[0] || sy != start[1])
        pts.insert(pts.begin() + 1, {sx, sy});
    if (gx != goal[0] || gy != goal[1])
        pts.emplace_back(gx, gy);
    pts.emplace_back(goal[0], goal[1]);
    return to_poses(pts, goal[2], poses, n);
}

extern "C" int planner_plan(planner_t *pl, const double start[3], const double goal[3], double **poses, int *n)
{
    *poses = nullptr;
    *n = 0;
    double sx = start[0], sy = start[1], gx = goal[0], gy = goal[1];
    if (!pl->snap(sx, sy, pl->p_.robot_radius) || !pl->snap(gx, gy, pl->p_.robot_radius))
        return marie_fail(EINVAL);
    if (pl->algo_ == PLANNER_GRID)
        return grid_plan(pl, start, goal, sx, sy, gx, gy, poses, n);
    try {
        og::SimpleSetup &ss = *pl->ss_;
        if (pl->algo_ == PLANNER_PRM && !pl->layer_changed_)
            ss.getPlanner()->clearQuery();    // keep the roadmap between queries
        else
            ss.clear();
        pl->layer_changed_ = false;
        ob::ScopedState<ob::RealVectorStateSpace> s(ss.getStateSpace()), g(ss.getStateSpace());
        s[0] = sx; s[1] = sy;
        g[0] = gx; g[1] = gy;
        ss.setStartAndGoalStates(s, g);
        ob::PlannerStatus st = ss.solve(pl->p_.time_limit);
        if (st != ob::PlannerStatus::EXACT_SOLUTION)
            return grid_plan(pl, start, goal, sx, sy, gx, gy, poses, n);
        og::PathGeometric path = ss.getSolutionPath();
        if (pl->p_.simplify_time > 0) {
            // Shortcutting works on the path's states: give it enough of them (one per
            // metre), then drop the ones a straight line makes redundant.
            og::PathSimplifier simp(ss.getSpaceInformation());
            path.interpolate((unsigned)std::max(2.0, path.length() / 1.0));
            ompl::time::point t0 = ompl::time::now();
            while (ompl::time::seconds(ompl::time::now() - t0) < pl->p_.simplify_time &&
                   simp.shortcutPath(path, 30, 0, 0.33, 0.005))
                ;
            simp.reduceVertices(path, 0, 0, 0.33);
        }
        // Keep the exact start and goal asked for when snapping moved them.
        std::vector<std::pair<double, double>> pts;
        if (sx != start[0] || sy != start[1])
            pts.emplace_back(start[0], start[1]);
        for (size_t i = 0; i < path.getStateCount(); i++) {
            const auto *v = path.getState(i)->as<ob::RealVectorStateSpace::StateType>();
            pts.emplace_back(v->values[0], v->values[1]);
        }
        if (gx != goal[0] || gy != goal[1])
            pts.emplace_back(goal[0], goal[1]);
        if (pts.size() < 2)
            pts.emplace_back(goal[0], goal[1]);
        return to_poses(pts, goal[2], poses, n);
    } catch (...) {
        return marie_fail(ENOMEM);
    }
}

static const char *const laser_reason = "in an obstacle seen by the laser";

// Why the robot cannot stand at (x, y), or nullptr when it can (after planner_plan's snapping).
static const char *refusal(const planner_t *pl, double x, double y, char *buf, size_t len)
{
    double sx = x, sy = y;
    if (pl->snap(sx, sy, pl->p_.robot_radius))
        return nullptr;
    double fx = (x - pl->ox_) / pl->res_, fy = (y - pl->oy_) / pl->res_;
    if (!(fx >= 0 && fy >= 0 && fx < pl->w_ && fy < pl->h_))
        return "off the map";
    size_t i = (size_t)(int)fy * pl->w_ + (int)fx;
    if (pl->cells_[i] == OCCMAP_OCCUPIED)
        return "inside a wall";
    if (pl->cells_[i] != OCCMAP_FREE && !pl->p_.unknown_is_free)
        return "in unknown space";
    if (pl->static_free_[i] || pl->dist_[i] > pl->p_.robot_radius)
        return laser_reason;
    snprintf(buf, len, "%.2f m from a wall (the robot needs %.2f m)", std::max(0.0f, pl->dist_[i]), pl->p_.robot_radius);
    return buf;
}

extern "C" int planner_blocked(const planner_t *pl, const double start[3], const double goal[3], char *why, size_t why_len)
{
    char a[96], b[96];
    const char *ws = refusal(pl, start[0], start[1], a, sizeof a), *wg = refusal(pl, goal[0], goal[1], b, sizeof b);
    bool by_laser = (ws || wg) && (!ws || ws == laser_reason) && (!wg || wg == laser_reason);
    if (why && why_len) {
        if (ws && wg)
            snprintf(why, why_len, "start (%.2f, %.2f) %s; goal (%.2f, %.2f) %s", start[0], start[1], ws, goal[0], goal[1], wg);
        else if (ws || wg)
            snprintf(why, why_len, "%s (%.2f, %.2f) %s", ws ? "start" : "goal", ws ? start[0] : goal[0],
                     ws ? start[1] : goal[1], ws ? ws : wg);
        else
            snprintf(why, why_len, "start and goal free");
    }
    return (ws ? PLANNER_START_BLOCKED : 0) | (wg ? PLANNER_GOAL_BLOCKED : 0) | (by_laser ? PLANNER_BY_LASER : 0);
}

extern "C" int planner_add_obstacles(planner_t *pl, const double *xy, int npoints, double now_s)
{
    int added = 0;
    for (auto it = pl->obstacles_.begin(); it != pl->obstacles_.end();) {
        if (now_s - it->second > pl->p_.obstacle_ttl) {
            pl->stamp(it->first, -1);
            it = pl->obstacles_.erase(it);
            pl->layer_changed_ = true;
        } else {
            ++it;
        }
    }
    for (int i = 0; i < npoints; i++) {
        double fx = (xy[2 * i] - pl->ox_) / pl->res_, fy = (xy[2 * i + 1] - pl->oy_) / pl->res_;
        if (!std::isfinite(fx) || !std::isfinite(fy) || fx < 0 || fy < 0 || fx >= pl->w_ || fy >= pl->h_)
            continue;
        int cell = (int)fy * pl->w_ + (int)fx;
        if (pl->dist_[(size_t)cell] < pl->p_.obstacle_margin)
            continue;                       // the map already explains this return
        auto r = pl->obstacles_.emplace(cell, now_s);
        if (r.second) {
            pl->stamp(cell, +1);
            added++;
            pl->layer_changed_ = true;
        } else {
            r.first->second = now_s;
        }
    }
    return added;
}

extern "C" void planner_clear_obstacles(planner_t *pl)
{
    std::fill(pl->dyn_.begin(), pl->dyn_.end(), 0);
    pl->obstacles_.clear();
    pl->layer_changed_ = true;
}

extern "C" int planner_obstacle_count(const planner_t *pl)
{
    return (int)pl->obstacles_.size();
}

extern "C" int planner_path_blocked(const planner_t *pl, const double *poses, int n, double x, double y, double horizon)
{
    if (n < 2 || pl->obstacles_.empty())
        return -1;
    // The path was valid on the map when planned; only the laser's obstacles can block it.
    // Exact point-to-segment distances (no sampling) so a path planned around an obstacle
    // never counts as blocked by it.
    int from = 0;
    double bd = INFINITY;
    for (int i = 0; i < n - 1; i++) {
        double ax = poses[3 * i], ay = poses[3 * i + 1], dx = poses[3 * i + 3] - ax, dy = poses[3 * i + 4] - ay;
        double l2 = dx * dx + dy * dy;
        double t = l2 > 0 ? std::clamp(((x - ax) * dx + (y - ay) * dy) / l2, 0.0, 1.0) : 0.0;
        double d = std::hypot(ax + t * dx - x, ay + t * dy - y);
        if (d < bd) { bd = d; from = i; }
    }
    const double clear = pl->p_.robot_radius - 0.5 * pl->res_;
    double walked = 0;
    for (int i = from; i < n - 1 && walked < horizon; i++) {
        double ax = poses[3 * i], ay = poses[3 * i + 1], dx = poses[3 * i + 3] - ax, dy = poses[3 * i + 4] - ay;
        double l2 = dx * dx + dy * dy;
        for (const auto &o : pl->obstacles_) {
            double ox = pl->ox_ + (o.first % pl->w_ + 0.5) * pl->res_, oy = pl->oy_ + (o.first / pl->w_ + 0.5) * pl->res_;
            // Right beside the robot is the avoid behaviour's business, not a reason to replan.
            if (std::hypot(ox - x, oy - y) < pl->p_.robot_radius + 0.1)
                continue;
            double t = l2 > 0 ? std::clamp(((ox - ax) * dx + (oy - ay) * dy) / l2, 0.0, 1.0) : 0.0;
            // Only the part of the path within the horizon counts.
            if (walked + t * std::sqrt(l2) > horizon)
                continue;
            if (std::hypot(ax + t * dx - ox, ay + t * dy - oy) < clear)
                return i;
        }
        walked += std::sqrt(l2);
    }
    return -1;
}

extern "C" int planner_path_collides(const planner_t *pl, const double *poses, int n)
{
    double step = pl->res_ * 0.5;
    for (int i = 0; i + 1 < n; i++) {
        double ax = poses[3 * i], ay = poses[3 * i + 1], bx = poses[3 * i + 3], by = poses[3 * i + 4];
        int k = std::max(1, (int)std::ceil(std::hypot(bx - ax, by - ay) / step));
        for (int j = 0; j <= k; j++) {
            double fx = (ax + (bx - ax) * j / k - pl->ox_) / pl->res_, fy = (ay + (by - ay) * j / k - pl->oy_) / pl->res_;
            if (!(fx >= 0 && fy >= 0 && fx < pl->w_ && fy < pl->h_))
                return i;
            if (pl->dist_[(size_t)(int)fy * pl->w_ + (int)fx] < pl->footprint_)
                return i;
        }
    }
    return -1;
}
