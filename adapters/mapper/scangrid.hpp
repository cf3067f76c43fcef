// scangrid: the mapper's log-odds grid, its smoothed likelihood for matching with a pyramid of
// maxima over it, and the matcher (branch-and-bound correlative search, then Gauss-Newton on the
// bilinear likelihood).
#ifndef ADAPTERS_MAPPER_SCANGRID_HPP
#define ADAPTERS_MAPPER_SCANGRID_HPP

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "adapters/mapper/slam_params.h"

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

// The grid reads the mapper's own parameters (resolution, l_hit, l_miss, l_min, l_max, sigma).
using GridParams = slam_params_t;

struct MatchWindow {
    double xy = 0.2, th = 0.1, step_th = 0.008;
    bool refine = true;
    // How far the prediction may be trusted (m, rad; 0: not at all). Along a corridor or into a
    // room whose far wall is out of range the scan cannot tell how far the robot went, and
    // without a prior the match slides towards the part of the map already seen.
    double prior_xy = 0.15, prior_th = 0.1;
    // > 0: match() also finds the best score of the poses at least this far (m) from the best
    // one, its rival: a rival nearly as good says the place looks alike along some direction.
    double rival_radius = 0;
    double rival_floor = 0;                    // ... and only one scoring above this share of the best
    // The search looks only for poses scoring above this (weighted): a caller that would refuse
    // less prunes most of the window at once. match() returns 0 when none does.
    double floor = 0;
    // > 0: the search scores at most this many regions and poses (each costs a pass over the
    // points): a wide window over a place that fits poorly everywhere prunes little.
    long max_evals = 0;
    // Match only the hits that land on cells the map has seen (tracking: a new wall's part would
    // pull the match back onto the known map); a grid of hits alone has seen nothing.
    bool seen_only = true;
};

// Memory from calloc: pages the map never reaches are never touched (a 400 m square grid costs
// what the robot's bounding box does).
template <typename T>
class ZeroArray {
public:
    ZeroArray() = default;
    explicit ZeroArray(size_t n) : p_(static_cast<T *>(std::calloc(n ? n : 1, sizeof(T)))), n_(n) {}
    ZeroArray(const ZeroArray &) = delete;
    ZeroArray &operator=(const ZeroArray &) = delete;
    ZeroArray(ZeroArray &&o) noexcept : p_(o.p_), n_(o.n_) { o.p_ = nullptr, o.n_ = 0; }
    ZeroArray &operator=(ZeroArray &&o) noexcept
    {
        std::swap(p_, o.p_);
        std::swap(n_, o.n_);
        return *this;
    }
    ~ZeroArray() { std::free(p_); }
    bool ok() const { return p_ != nullptr; }
    T &operator[](size_t i) { return p_[i]; }
    const T &operator[](size_t i) const { return p_[i]; }
    T *data() { return p_; }
    const T *data() const { return p_; }
    size_t size() const { return n_; }

private:
    T *p_ = nullptr;
    size_t n_ = 0;
};

class Grid {
public:
    // Throws std::bad_alloc when the arrays cannot be had.
    Grid(int width, int height, double ox, double oy, const GridParams &p);
    int width() const { return w_; }
    int height() const { return h_; }
    double origin_x() const { return ox_; }
    double origin_y() const { return oy_; }
    // Moves the grid's frame; only an empty (cleared) grid may be moved.
    void set_origin(double ox, double oy) { ox_ = ox, oy_ = oy; }
    // Whether integrate() stamps the walls (cells above l_occupied) into the likelihood.
    void set_stamp_walls(bool on) { stamp_walls_ = on; }
    // The likelihood of `src` with its pyramid (same resolution, origins a whole number of
    // coarsest blocks apart: 2^LEVELS cells) where the two overlap, into this cleared grid.
    void copy_likelihood(const Grid &src);
    const GridParams &params() const { return p_; }
    // Integrate a scan seen from robot pose `at` into the log-odds; false when part of it fell off
    // the grid. (The map shown; it is not matched against.)
    bool integrate(const Pose &at, const Scan &s);
    // The scan's hits into the matching likelihood, each a Gaussian (max) around its cell: a grid
    // to match against, built from a few keyframes.
    void add_hits(const Pose &at, const Scan &s);
    // Between these, add_hits() leaves the pyramid alone; end_batch() builds it once over what
    // was touched (cheaper for a grid drawn whole from many keyframes).
    void begin_batch() { batch_ = true; }
    void end_batch();
    // The hits that land on cells this grid has seen (hit or passed), at `guess`.
    Scan seen_hits(const Scan &s, const Pose &guess) const;
    void clear();
    // Cells touched so far, [x0, x1) x [y0, y1); empty when x1 <= x0.
    void bounds(int *x0, int *y0, int *x1, int *y1) const;
    float log_odds(int cx, int cy) const { return lo_[(size_t)cy * w_ + cx]; }
    bool seen(int cx, int cy) const { return seen_[(size_t)cy * w_ + cx] != 0; }
    // Best pose near `guess` for the scan's hits; the mean likelihood per hit (0..1), and the
    // pose in *out. Scans with fewer than 10 hits score 0. *edge (may be NULL): the search's
    // best lay at the window's edge (a maximum the window cut off); *cut: the search stopped at
    // win.max_evals, its best is the best it had found.
    double match(const Scan &s, const Pose &guess, const MatchWindow &win, Pose *out, double *rival = nullptr,
                 bool *edge = nullptr, bool *cut = nullptr) const;
    double score(const Scan &s, const Pose &at) const;
    // Share of the scan's hits (all of them) that land where the map is surely free (log-odds
    // below l_free): a pose the map contradicts.
    double contradiction(const Scan &s, const Pose &at, double l_free) const;
    size_t memory_bytes() const;
    // Walls (log-odds above l_occupied) that beams have since made free (log-odds below 0): a
    // moved obstacle, or a wall drawn out of place. Counted since creation, a cell again each
    // time it had turned a wall again.
    int64_t cleared() const { return cleared_; }

    static constexpr int LEVELS = 6;           // the pyramid: blocks of 2 .. 64 cells

private:
    struct Search;
    void stamp(int cx, int cy);
    void raise(int cx, int cy, float v);
    void hit(int cx, int cy);
    void miss(int cx, int cy);
    void touch(int cx, int cy);
    double refine(const Scan &s, const Pose &guess, const MatchWindow &win, Pose *pose) const;
    double sample(double x, double y, double *gx, double *gy) const;
    void build_pyramid(int x0, int y0, int x1, int y1);

    int w_, h_;
    double ox_, oy_;
    GridParams p_;
    static constexpr double L_OCCUPIED = 0.6;  // log-odds above which a cell is a wall for matching
    ZeroArray<float> lo_;                      // log-odds
    ZeroArray<float> like_;                    // matching likelihood 0..1, max of the walls' kernels
    ZeroArray<uint8_t> seen_;
    enum : uint8_t { STAMPED = 1, WALL = 2 };  // wall_: likelihood stamped; a wall since last made free
    ZeroArray<uint8_t> wall_;
    // pyr_[l]: the likelihood's maximum over each aligned block of 2^(l+1) cells a side; quad_[l]
    // over the 2 x 2 blocks from it (a region of 2^(l+1) offsets puts a point on two blocks a side).
    ZeroArray<float> pyr_[LEVELS], quad_[LEVELS];
    int pw_[LEVELS], ph_[LEVELS];
    std::vector<float> kernel_;
    int kr_;                                   // kernel radius, cells
    int bx0_, by0_, bx1_, by1_;                // cells touched (the likelihood reaches kr_ further)
    int64_t cleared_ = 0;
    bool stamp_walls_ = false;
    bool used_logodds_ = false;                // integrate() wrote lo_ and seen_ since the last clear
    bool batch_ = false;
};

}  // namespace mapper
#endif
