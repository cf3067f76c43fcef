// scangrid: the mapper's log-odds grid, its smoothed likelihood for matching, and the matcher
// (correlative search, then Gauss-Newton on the bilinear likelihood).
#ifndef ADAPTERS_MAPPER_SCANGRID_HPP
#define ADAPTERS_MAPPER_SCANGRID_HPP

#include <cstddef>
#include <cstdint>
#include <vector>

namespace mapper {

struct Pose {
    double x = 0, y = 0, th = 0;
};
Pose compose(const Pose &a, const Pose &b);    // b given in frame a
Pose between(const Pose &a, const Pose &b);    // b seen from a
double wrap(double a);

// A scan reduced to what the grid needs, in the robot frame.
struct Scan {
    double ox = 0, oy = 0;                     // sensor position
    std::vector<float> hx, hy;                 // beam end points that hit something
    std::vector<float> fx, fy;                 // where each of those beams stops clearing: before the surface
    std::vector<float> mx, my;                 // where beams that saw nothing stop clearing
};

struct GridParams {
    double resolution = 0.05;
    double l_hit = 0.9, l_miss = -0.4, l_min = -2.0, l_max = 3.5;
    double l_occupied = 0.6;                   // log-odds above which a cell is a wall for matching
    double sigma = 0.05;                       // m
};

struct MatchWindow {
    double xy = 0.2, th = 0.1, step_th = 0.008;
    int step_cells = 1;                        // translation step of the correlative search
    bool refine = true;
    // How far the prediction may be trusted (m, rad; 0: not at all). Along a corridor or into a
    // room whose far wall is out of range the scan cannot tell how far the robot went, and
    // without a prior the match slides towards the part of the map already seen.
    double prior_xy = 0.15, prior_th = 0.1;
    // > 0: match() also finds the best score of the poses at least this far (m) from the best
    // one, its rival: a rival nearly as good says the place looks alike along some direction.
    double rival_radius = 0;
};

class Grid {
public:
    Grid(int width, int height, double ox, double oy, const GridParams &p);
    int width() const { return w_; }
    int height() const { return h_; }
    double origin_x() const { return ox_; }
    double origin_y() const { return oy_; }
    const GridParams &params() const { return p_; }
    // Integrate a scan seen from robot pose `at`.
    void integrate(const Pose &at, const Scan &s);
    void clear();
    // Cells touched so far, [x0, x1) x [y0, y1); empty when x1 <= x0.
    void bounds(int *x0, int *y0, int *x1, int *y1) const;
    float log_odds(int cx, int cy) const { return lo_[(size_t)cy * w_ + cx]; }
    bool seen(int cx, int cy) const { return seen_[(size_t)cy * w_ + cx] != 0; }
    // Best pose near `guess` for the scan's hits; the mean likelihood per hit (0..1), and the
    // pose in *out. Scans with fewer than 10 hits score 0.
    double match(const Scan &s, const Pose &guess, const MatchWindow &win, Pose *out, double *rival = nullptr) const;
    double score(const Scan &s, const Pose &at) const;
    size_t memory_bytes() const;
    // Walls (log-odds above l_occupied) that beams have since made free (log-odds below 0): a
    // moved obstacle, or a wall drawn out of place. Counted since creation, a cell again each
    // time it had turned a wall again.
    int64_t cleared() const { return cleared_; }

private:
    Scan seen_hits(const Scan &s, const Pose &guess) const;
    void stamp(int cx, int cy);
    void hit(int cx, int cy);
    void miss(int cx, int cy);
    double correlative(const Scan &s, const Pose &guess, const MatchWindow &win, Pose *out, double *rival) const;
    double refine(const Scan &s, const Pose &guess, const MatchWindow &win, Pose *pose) const;
    double sample(double x, double y, double *gx, double *gy) const;

    int w_, h_;
    double ox_, oy_;
    GridParams p_;
    std::vector<float> lo_;                    // log-odds
    std::vector<float> like_;                  // matching likelihood 0..1, max of the walls' kernels
    std::vector<uint8_t> seen_;
    enum : uint8_t { STAMPED = 1, WALL = 2 };  // wall_: likelihood stamped; a wall since last made free
    std::vector<uint8_t> wall_;
    std::vector<float> kernel_;
    int kr_;                                   // kernel radius, cells
    int bx0_, by0_, bx1_, by1_;
    int64_t cleared_ = 0;
};

}  // namespace mapper
#endif
