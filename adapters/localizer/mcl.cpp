// mcl: particle filter localization. The likelihood field is a log-probability per field cell
// (adapters/localizer/field.h), so weighing a beam is one table look-up; beams that the cloud as
// a whole cannot explain are skipped (AMCL's beam skipping), and a scan is judged at the
// estimate by tracing its beams through the map.
#include "adapters/localizer/mcl.h"
#include "adapters/localizer/field.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <new>
#include <random>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <Eigen/Dense>

namespace {

double wrap(double a)
{
    a = std::fmod(a + M_PI, 2 * M_PI);
    if (a < 0)
        a += 2 * M_PI;
    return a - M_PI;
}

}  // namespace

struct mcl {
    mcl_params_t p_{};
    lfield fd_;                         // the map as the localizer sees it
    double sigma_ = 0;                  // sigma_hit widened by the map's cells
    std::vector<float> llf_;            // log likelihood of a beam ending in each field cell
    float ll_out_ = 0;                  // ... outside the map
    double llf_range_max_ = -1;         // range_max the field was built for
    mcl_fit_t fit_{};                   // the last update's scan judged at the estimate
    std::vector<float> bl_;             // weigh's scratch: log likelihood per particle and beam ...
    std::vector<uint8_t> bad_;          // ... and whether the beam is unexplained there
    double skipped_ = 0, cluster_mass_ = 1;

    // Particles (structure of arrays; weights normalised to sum 1).
    Eigen::ArrayXd x_, y_, th_, w_;
    std::mt19937_64 rng_;

    bool have_odom_ = false;
    double odom_[3] = {0, 0, 0};        // odometry pose at the last sensor update
    double w_slow_ = 0, w_fast_ = 0, lik_ = 0;
    int64_t updates_ = 0, resamples_ = 0;

    double gauss(double sigma)
    {
        return sigma > 0 ? std::normal_distribution<double>(0.0, sigma)(rng_) : 0.0;
    }
    double uniform() { return std::uniform_real_distribution<double>(0.0, 1.0)(rng_); }

    void resize(int n)
    {
        x_.resize(n); y_.resize(n); th_.resize(n);
        w_.setConstant(n, 1.0 / n);
    }

    void random_free_pose(double *x, double *y, double *th)
    {
        const auto &fc = fd_.free_cells;
        int32_t c = fc[std::uniform_int_distribution<size_t>(0, fc.size() - 1)(rng_)];
        int mw = fd_.w / fd_.k;
        *x = fd_.ox + (c % mw + uniform()) * fd_.map_res;
        *y = fd_.oy + (c / mw + uniform()) * fd_.map_res;
        *th = (uniform() * 2 - 1) * M_PI;
    }

    // A random pose in free space within inject_radius of `around`, any heading: the filter's
    // own recovery stays near where it was (a far jump is the search's to make, seek.h).
    void near_pose(const double around[3], double *x, double *y, double *th)
    {
        for (int k = 0; k < 20; k++) {
            double r = p_.inject_radius * std::sqrt(uniform()), a = uniform() * 2 * M_PI;
            *x = around[0] + r * std::cos(a);
            *y = around[1] + r * std::sin(a);
            int c = fd_.cell(*x, *y);
            if (c >= 0 && fd_.kind[(size_t)c] == lfield::FREE)
                break;
        }
        *th = (uniform() * 2 - 1) * M_PI;
    }

    void build_llf(double range_max)
    {
        double zr = p_.z_rand / std::max(range_max, 1.0);
        double k = 1.0 / (2 * sigma_ * sigma_);
        llf_.resize(fd_.dist.size());
        for (size_t i = 0; i < fd_.dist.size(); i++) {
            double d = std::min<double>(fd_.dist[i], p_.max_dist);
            llf_[i] = (float)std::log(p_.z_hit * std::exp(-d * d * k) + zr);
        }
        ll_out_ = (float)std::log(p_.z_hit * std::exp(-p_.max_dist * p_.max_dist * k) + zr);
        llf_range_max_ = range_max;
    }

    // Random particles answer a drop of the fit only when the scan contradicts the map at the
    // estimate; what merely stands in front of the walls draws none (nor a jump to a look-alike).
    bool inject_allowed() const
    {
        return p_.alpha_slow > 0 && p_.alpha_fast > 0 && fit_.contradiction > p_.inject_contradiction;
    }
    void motion(const double o0[3], const double o1[3]);
    std::vector<uint8_t> outliers(const std::vector<uint8_t> &bad, const Eigen::ArrayXd &br, const Eigen::ArrayXd &bc,
                                  const Eigen::ArrayXd &bs);
    void weigh(const mcl_scan_t *scan);
    void resample();
};

static double estimate(const mcl_t *f, double pose[3], double cov[9]);

extern "C" void mcl_params_default(mcl_params_t *p)
{
    const mcl_params_t d = MCL_PARAMS_DEFAULTS;
    *p = d;
}

extern "C" mcl_t *mcl_create(const occmap_t *map, const mcl_params_t *p, uint64_t seed)
{
    if (!map || !p || p->particles_max < 1 || p->particles_min < 1 || p->particles_min > p->particles_max ||
        !(p->sigma_hit > 0) || p->max_beams < 1) {
        errno = EINVAL;
        return nullptr;
    }
    mcl_t *f = new (std::nothrow) mcl;
    if (!f) {
        errno = ENOMEM;
        return nullptr;
    }
    try {
        f->p_ = *p;
        f->rng_.seed(seed);
        if (!f->fd_.build(map, 0.05)) {
            int e = errno;
            delete f;
            errno = e;
            return nullptr;
        }
        if (f->fd_.free_cells.empty())
            f->fd_.free_cells.push_back(0);
        // A wall lies anywhere within its cell: a coarse map's cells widen the spread.
        f->sigma_ = std::sqrt(p->sigma_hit * p->sigma_hit + map->resolution * map->resolution / 12);
        f->build_llf(30.0);
        double zero[3] = {0, 0, 0}, sig[3] = {0, 0, 0};
        mcl_init_pose(f, zero, sig);
    } catch (...) {
        delete f;
        errno = ENOMEM;
        return nullptr;
    }
    return f;
}

extern "C" void mcl_destroy(mcl_t *f)
{
    delete f;
}

extern "C" void mcl_init_pose(mcl_t *f, const double pose[3], const double sigma[3])
{
    int n = f->p_.particles_max;
    f->resize(n);
    for (int i = 0; i < n; i++) {
        f->x_[i] = pose[0] + f->gauss(sigma[0]);
        f->y_[i] = pose[1] + f->gauss(sigma[1]);
        f->th_[i] = wrap(pose[2] + f->gauss(sigma[2]));
    }
    f->have_odom_ = false;
    f->w_slow_ = f->w_fast_ = 0;
    f->fit_ = mcl_fit_t{};
}

extern "C" void mcl_init_global(mcl_t *f)
{
    int n = f->p_.particles_max;
    f->resize(n);
    for (int i = 0; i < n; i++) {
        double x, y, th;
        f->random_free_pose(&x, &y, &th);
        f->x_[i] = x;
        f->y_[i] = y;
        f->th_[i] = th;
    }
    f->have_odom_ = false;
    f->w_slow_ = f->w_fast_ = 0;
    f->fit_ = mcl_fit_t{};
}

// The odometry motion model (rotate, translate, rotate) with noise growing with each part.
void mcl::motion(const double o0[3], const double o1[3])
{
    double dx = o1[0] - o0[0], dy = o1[1] - o0[1];
    double trans = std::hypot(dx, dy);
    double rot1 = trans < 0.01 ? 0.0 : wrap(std::atan2(dy, dx) - o0[2]);
    // Driving backwards: treat as a negative translation, not a half turn.
    if (std::fabs(rot1) > M_PI / 2) {
        rot1 = wrap(rot1 - M_PI);
        trans = -trans;
    }
    double rot2 = wrap(o1[2] - o0[2] - rot1);
    const double a[4] = { p_.alpha1, p_.alpha2, p_.alpha3, p_.alpha4 };
    double s_r1 = std::sqrt(a[0] * rot1 * rot1 + a[1] * trans * trans);
    double s_t = std::sqrt(a[2] * trans * trans + a[3] * (rot1 * rot1 + rot2 * rot2));
    double s_r2 = std::sqrt(a[0] * rot2 * rot2 + a[1] * trans * trans);
    for (Eigen::Index i = 0; i < x_.size(); i++) {
        double r1 = rot1 - gauss(s_r1), t = trans - gauss(s_t), r2 = rot2 - gauss(s_r2);
        double h = th_[i] + r1;
        x_[i] += t * std::cos(h);
        y_[i] += t * std::sin(h);
        th_[i] = wrap(h + r2);
    }
}

// Beam skipping: a beam most of the cloud cannot explain (bad: per particle and beam) is
// something the map lacks, when from the estimate it ends in free space with nothing of the map
// on its way (a beam seen through a wall or past the map's edge is evidence against the cloud,
// never skipped); none when too many would go, or the cloud is spread.
std::vector<uint8_t> mcl::outliers(const std::vector<uint8_t> &bad, const Eigen::ArrayXd &br, const Eigen::ArrayXd &bc,
                                   const Eigen::ArrayXd &bs)
{
    const int nb = (int)br.size();
    const Eigen::Index n = x_.size();
    std::vector<uint8_t> skip((size_t)nb, 0);
    int nskip = 0;
    double est[3], cov[9];
    bool one = estimate(this, est, cov) > 0.8;     // a spread cloud cannot tell what the map lacks
    double ec = std::cos(est[2]), es = std::sin(est[2]);
    double ex = est[0] + ec * p_.laser_x - es * p_.laser_y, ey = est[1] + es * p_.laser_x + ec * p_.laser_y;
    for (int j = 0; j < nb && one; j++) {
        double a = est[2] + p_.laser_theta + std::atan2(bs[j], bc[j]);
        if (fd_.verdict(ex, ey, std::cos(a), std::sin(a), br[j], 3 * sigma_) != lfield::SHORTER)
            continue;
        double share = 0;
        for (Eigen::Index i = 0; i < n; i++)
            share += bad[(size_t)i * nb + j] ? w_[i] : 0.0;
        skip[(size_t)j] = share > p_.outlier_share;
        nskip += skip[(size_t)j];
    }
    if (nskip > p_.outlier_max * nb || nskip == nb)
        std::fill(skip.begin(), skip.end(), 0);
    return skip;
}

void mcl::weigh(const mcl_scan_t *scan)
{
    if (scan->range_max != llf_range_max_)
        build_llf(scan->range_max);
    // Evenly spread subset of the valid beams (max-range readings carry no hit).
    std::vector<int> valid;
    valid.reserve(scan->n);
    for (int k = 0; k < scan->n; k++) {
        float r = scan->ranges[k];
        if (std::isfinite(r) && r > scan->range_min && r < scan->range_max)
            valid.push_back(k);
    }
    int nb = std::min<int>((int)valid.size(), p_.max_beams);
    if (nb == 0)
        return;
    Eigen::ArrayXd br(nb), bc(nb), bs(nb);
    for (int j = 0; j < nb; j++) {
        int k = valid[(size_t)((double)j * valid.size() / nb)];
        double a = scan->angle_min + k * scan->angle_increment;
        br[j] = scan->ranges[k];
        bc[j] = std::cos(a);
        bs[j] = std::sin(a);
    }
    // Each particle's log likelihood per beam, and whether the beam is explained there.
    const Eigen::Index n = x_.size();
    bl_.resize((size_t)n * nb);
    bad_.resize((size_t)n * nb);
    std::vector<float> &bl = bl_;
    std::vector<uint8_t> &bad = bad_;
    const float far = (float)p_.outlier_distance;
    for (Eigen::Index i = 0; i < n; i++) {
        double c = std::cos(th_[i]), s = std::sin(th_[i]);
        double lx = x_[i] + c * p_.laser_x - s * p_.laser_y;
        double ly = y_[i] + s * p_.laser_x + c * p_.laser_y;
        double lc = std::cos(th_[i] + p_.laser_theta), ls = std::sin(th_[i] + p_.laser_theta);
        for (int j = 0; j < nb; j++) {
            int cell = fd_.cell(lx + br[j] * (lc * bc[j] - ls * bs[j]), ly + br[j] * (ls * bc[j] + lc * bs[j]));
            size_t at = (size_t)i * nb + j;
            bl[at] = cell < 0 ? ll_out_ : llf_[(size_t)cell];
            bad[at] = cell < 0 || fd_.dist[(size_t)cell] > far;
        }
    }
    std::vector<uint8_t> skip = outliers(bad, br, bc, bs);
    int nskip = (int)std::count(skip.begin(), skip.end(), 1);
    skipped_ = (double)nskip / nb;
    Eigen::ArrayXd ll(n);
    for (Eigen::Index i = 0; i < n; i++) {
        double sum = 0;
        for (int j = 0; j < nb; j++)
            if (!skip[(size_t)j])
                sum += bl[(size_t)i * nb + j];
        ll[i] = sum;
    }
    // Recovery bookkeeping on the per-beam geometric-mean likelihood (no underflow).
    double avg = (ll / (nb - nskip)).exp().mean();
    lik_ = avg;
    if (w_slow_ == 0) {
        w_slow_ = w_fast_ = avg;
    } else {
        w_slow_ += p_.alpha_slow * (avg - w_slow_);
        w_fast_ += p_.alpha_fast * (avg - w_fast_);
    }
    Eigen::ArrayXd lw = w_.max(1e-300).log() + ll;
    lw -= lw.maxCoeff();
    w_ = lw.exp();
    w_ /= w_.sum();
}

void mcl::resample()
{
    const Eigen::Index n = x_.size();
    std::vector<double> cdf((size_t)n);
    double acc = 0;
    for (Eigen::Index i = 0; i < n; i++)
        cdf[(size_t)i] = acc += w_[i];
    // Augmented MCL's share (a drop of the fast average below the slow one), and while the scan
    // goes on contradicting the map, a share that grows with it.
    double inject = 0, est[3], cov[9];
    if (inject_allowed()) {
        inject = std::max(w_slow_ > 0 ? 1.0 - w_fast_ / w_slow_ : 0.0, 0.5 * (fit_.contradiction - p_.inject_contradiction));
        estimate(this, est, cov);
    }

    std::vector<double> nx, ny, nt;
    nx.reserve(p_.particles_max); ny.reserve(p_.particles_max); nt.reserve(p_.particles_max);
    std::unordered_set<uint64_t> bins;
    size_t target = (size_t)p_.particles_min;
    while (nx.size() < (size_t)p_.particles_max && (nx.size() < target || nx.size() < (size_t)p_.particles_min)) {
        double x, y, th;
        if (inject > 0 && uniform() < inject) {
            near_pose(est, &x, &y, &th);
        } else {
            double u = uniform() * acc;
            size_t i = (size_t)(std::lower_bound(cdf.begin(), cdf.end(), u) - cdf.begin());
            if (i >= (size_t)n)
                i = (size_t)n - 1;
            x = x_[(Eigen::Index)i]; y = y_[(Eigen::Index)i]; th = th_[(Eigen::Index)i];
        }
        nx.push_back(x); ny.push_back(y); nt.push_back(th);
        uint64_t key = ((uint64_t)(uint32_t)(int32_t)std::floor(x / p_.bin_xy) << 40) ^
                       ((uint64_t)(uint32_t)(int32_t)std::floor(y / p_.bin_xy) << 16) ^
                       (uint64_t)(uint32_t)(int32_t)std::floor((th + M_PI) / p_.bin_theta);
        if (bins.insert(key).second && bins.size() > 1) {
            // KLD bound (Fox 2003): samples needed so the histogram is within kld_err.
            double k = (double)bins.size() - 1, a = 2.0 / (9 * k);
            double b = 1 - a + std::sqrt(a) * p_.kld_z;
            target = (size_t)std::ceil(k / (2 * p_.kld_err) * b * b * b);
        }
    }
    int m = (int)nx.size();
    resize(m);
    for (int i = 0; i < m; i++) {
        x_[i] = nx[(size_t)i]; y_[i] = ny[(size_t)i]; th_[i] = nt[(size_t)i];
    }
    if (inject > 0)  // the injected particles answered this drop; start tracking afresh
        w_slow_ = w_fast_ = 0;
    resamples_++;
}

extern "C" int mcl_step(mcl_t *f, const double odom[3], const mcl_scan_t *scan, bool force)
{
    if (!f->have_odom_) {
        f->odom_[0] = odom[0]; f->odom_[1] = odom[1]; f->odom_[2] = odom[2];
        f->have_odom_ = true;
        if (!force)
            return 0;
    }
    double d = std::hypot(odom[0] - f->odom_[0], odom[1] - f->odom_[1]);
    double a = std::fabs(wrap(odom[2] - f->odom_[2]));
    if (!force && d < f->p_.update_min_d && a < f->p_.update_min_a)
        return 0;
    f->motion(f->odom_, odom);
    f->odom_[0] = odom[0]; f->odom_[1] = odom[1]; f->odom_[2] = odom[2];
    if (scan && scan->n > 0 && scan->ranges) {
        f->weigh(scan);
        double pose[3], cov[9];
        f->cluster_mass_ = estimate(f, pose, cov);
        mcl_judge(f, pose, scan, &f->fit_);
    }
    f->updates_++;
    double ess = 1.0 / f->w_.square().sum();
    if (ess < f->p_.resample_ess * (double)f->w_.size() ||
        (f->inject_allowed() && f->w_slow_ > 0 && f->w_fast_ < 0.5 * f->w_slow_))
        f->resample();
    return 1;
}

static void weighted_stats(const mcl_t *f, const std::vector<Eigen::Index> *sel, double pose[3], double cov[9])
{
    double sw = 0, mx = 0, my = 0, sc = 0, ss = 0;
    auto each = [&](auto fn) {
        if (sel)
            for (Eigen::Index i : *sel) fn(i);
        else
            for (Eigen::Index i = 0; i < f->x_.size(); i++) fn(i);
    };
    each([&](Eigen::Index i) {
        double w = f->w_[i];
        sw += w; mx += w * f->x_[i]; my += w * f->y_[i];
        sc += w * std::cos(f->th_[i]); ss += w * std::sin(f->th_[i]);
    });
    if (sw <= 0)
        sw = 1;
    mx /= sw; my /= sw;
    double mt = std::atan2(ss, sc);
    Eigen::Matrix3d c = Eigen::Matrix3d::Zero();
    each([&](Eigen::Index i) {
        Eigen::Vector3d d(f->x_[i] - mx, f->y_[i] - my, wrap(f->th_[i] - mt));
        c += f->w_[i] * d * d.transpose();
    });
    c /= sw;
    pose[0] = mx; pose[1] = my; pose[2] = mt;
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 3; k++)
            cov[r * 3 + k] = c(r, k);
}

// The estimate, and the share of the weight it stands for.
static double estimate(const mcl_t *f, double pose[3], double cov[9])
{
    weighted_stats(f, nullptr, pose, cov);
    if (cov[0] + cov[4] < 0.25)
        return 1;
    // Several hypotheses: report the heaviest 1 m cell's neighbourhood, not their average.
    std::unordered_map<uint64_t, double> mass;
    uint64_t best = 0;
    double bestw = -1;
    for (Eigen::Index i = 0; i < f->x_.size(); i++) {
        uint64_t key = ((uint64_t)(uint32_t)(int32_t)std::floor(f->x_[i]) << 32) |
                       (uint32_t)(int32_t)std::floor(f->y_[i]);
        double &m = mass[key];
        m += f->w_[i];
        if (m > bestw) { bestw = m; best = key; }
    }
    double cx = (int32_t)(uint32_t)(best >> 32) + 0.5, cy = (int32_t)(uint32_t)best + 0.5;
    std::vector<Eigen::Index> sel;
    double in = 0;
    for (Eigen::Index i = 0; i < f->x_.size(); i++)
        if (std::hypot(f->x_[i] - cx, f->y_[i] - cy) < 1.5) {
            sel.push_back(i);
            in += f->w_[i];
        }
    if (!sel.empty())
        weighted_stats(f, &sel, pose, cov);
    return in;
}

extern "C" void mcl_estimate(const mcl_t *f, double pose[3], double cov[9])
{
    estimate(f, pose, cov);
}

extern "C" void mcl_pose_at(const mcl_t *f, const double odom[3], double pose[3], double cov[9])
{
    mcl_estimate(f, pose, cov);
    if (!f->have_odom_)
        return;
    // Odometry delta expressed in the odometry pose of the last update, applied to the estimate.
    double dx = odom[0] - f->odom_[0], dy = odom[1] - f->odom_[1];
    double c = std::cos(f->odom_[2]), s = std::sin(f->odom_[2]);
    double lx = c * dx + s * dy, ly = -s * dx + c * dy;
    double pc = std::cos(pose[2]), ps = std::sin(pose[2]);
    pose[0] += pc * lx - ps * ly;
    pose[1] += ps * lx + pc * ly;
    pose[2] = wrap(pose[2] + odom[2] - f->odom_[2]);
}

extern "C" int mcl_count(const mcl_t *f) { return (int)f->x_.size(); }

extern "C" int mcl_particles(const mcl_t *f, float *xytw, int max)
{
    int n = std::min<int>(max, (int)f->x_.size());
    for (int i = 0; i < n; i++) {
        xytw[4 * i] = (float)f->x_[i];
        xytw[4 * i + 1] = (float)f->y_[i];
        xytw[4 * i + 2] = (float)f->th_[i];
        xytw[4 * i + 3] = (float)f->w_[i];
    }
    return n;
}

extern "C" int64_t mcl_updates(const mcl_t *f) { return f->updates_; }
extern "C" double mcl_likelihood(const mcl_t *f) { return f->lik_; }

extern "C" void mcl_judge(const mcl_t *f, const double pose[3], const mcl_scan_t *scan, mcl_fit_t *fit)
{
    *fit = mcl_fit_t{};
    const mcl_params_t &p = f->p_;
    double c = std::cos(pose[2]), s = std::sin(pose[2]);
    double lx = pose[0] + c * p.laser_x - s * p.laser_y, ly = pose[1] + s * p.laser_x + c * p.laser_y;
    for (int k = 0; k < scan->n; k++) {
        double r = scan->ranges[k];
        if (!std::isfinite(r) || r <= scan->range_min)
            continue;
        double a = pose[2] + p.laser_theta + scan->angle_min + k * scan->angle_increment;
        fit->beams++;
        switch (f->fd_.verdict(lx, ly, std::cos(a), std::sin(a), r >= scan->range_max ? -scan->range_max : r, 3 * f->sigma_)) {
        case lfield::HIT: fit->hit++; break;
        case lfield::SHORTER: fit->shorter++; break;
        case lfield::THROUGH: fit->through++; break;
        default: break;
        }
    }
    int says = fit->hit + fit->through;
    fit->contradiction = says >= 10 ? (double)fit->through / says : 0.0;
}

extern "C" void mcl_last_fit(const mcl_t *f, mcl_fit_t *fit, double *skipped, double *cluster_mass)
{
    if (fit)
        *fit = f->fit_;
    if (skipped)
        *skipped = f->skipped_;
    if (cluster_mass)
        *cluster_mass = f->cluster_mass_;
}

extern "C" double mcl_trace(const mcl_t *f, double x, double y, double angle, double max_r)
{
    return f->fd_.trace(x, y, std::cos(angle), std::sin(angle), max_r);
}

extern "C" mcl_place_t mcl_map_at(const mcl_t *f, double x, double y)
{
    int c = f->fd_.cell(x, y);
    if (c < 0)
        return MCL_OFF_MAP;
    uint8_t k = f->fd_.kind[(size_t)c];
    return k == lfield::FREE ? MCL_FREE : k == lfield::OCC ? MCL_WALL : MCL_UNKNOWN;
}

extern "C" const char *mcl_place_name(mcl_place_t where)
{
    static const char *const names[] = { "in free space", "inside a wall", "in unknown space", "off the map" };
    return names[where];
}

const lfield &mcl_field(const mcl *f)
{
    return f->fd_;
}

double mcl_sigma(const mcl *f)
{
    return f->sigma_;
}
