// mcl: particle filter localization. The likelihood field is a log-probability per map cell,
// precomputed from an OpenCV distance transform, so weighing a beam is one table look-up.
#include "adapters/localizer/mcl.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <new>
#include <random>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

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
    // Map geometry and fields (copied from the occmap).
    int mw_ = 0, mh_ = 0;
    double res_ = 0, ox_ = 0, oy_ = 0;
    std::vector<float> dist_;           // m to the nearest occupied cell, capped at max_dist
    std::vector<float> llf_;            // log likelihood of a beam ending in each cell
    float ll_out_ = 0;                  // ... outside the map
    double llf_range_max_ = -1;         // range_max the field was built for
    std::vector<int32_t> free_;         // free cell indices, for global init and recovery

    // Particles (structure of arrays; weights normalised to sum 1).
    Eigen::ArrayXd x_, y_, th_, w_;
    std::mt19937_64 rng_;

    bool have_odom_ = false;
    double odom_[3] = {0, 0, 0};        // odometry pose at the last sensor update
    double w_slow_ = 0, w_fast_ = 0, lik_ = 0;
    int64_t updates_ = 0, resamples_ = 0;
    int quiet_ = 0;                     // updates left before a poor fit counts as lost

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
        int32_t c = free_[std::uniform_int_distribution<size_t>(0, free_.size() - 1)(rng_)];
        *x = ox_ + (c % mw_ + uniform()) * res_;
        *y = oy_ + (c / mw_ + uniform()) * res_;
        *th = (uniform() * 2 - 1) * M_PI;
    }

    void build_llf(double range_max)
    {
        double zr = p_.z_rand / std::max(range_max, 1.0);
        double k = 1.0 / (2 * p_.sigma_hit * p_.sigma_hit);
        llf_.resize(dist_.size());
        for (size_t i = 0; i < dist_.size(); i++)
            llf_[i] = (float)std::log(p_.z_hit * std::exp(-dist_[i] * dist_[i] * k) + zr);
        ll_out_ = (float)std::log(p_.z_hit * std::exp(-p_.max_dist * p_.max_dist * k) + zr);
        llf_range_max_ = range_max;
    }

    // A freshly spread cloud fits poorly by construction: give it time before calling it lost.
    bool lost() const { return quiet_ == 0 && p_.lost_likelihood > 0 && w_fast_ > 0 && w_fast_ < p_.lost_likelihood; }
    void motion(const double o0[3], const double o1[3]);
    void weigh(const mcl_scan_t *scan);
    void resample();
};

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
        f->mw_ = map->width;
        f->mh_ = map->height;
        f->res_ = map->resolution;
        f->ox_ = map->origin_x;
        f->oy_ = map->origin_y;
        f->rng_.seed(seed);
        // distanceTransform measures to the nearest zero pixel: occupied cells are the zeros.
        cv::Mat freeimg(map->height, map->width, CV_8U);
        for (int r = 0; r < map->height; r++)
            for (int c = 0; c < map->width; c++) {
                int8_t v = map->cells[(size_t)r * map->width + c];
                freeimg.at<uint8_t>(r, c) = v == OCCMAP_OCCUPIED ? 0 : 255;
                if (v == OCCMAP_FREE)
                    f->free_.push_back(r * map->width + c);
            }
        cv::Mat dist;
        cv::distanceTransform(freeimg, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
        f->dist_.resize((size_t)map->width * map->height);
        for (int r = 0; r < map->height; r++)
            for (int c = 0; c < map->width; c++)
                f->dist_[(size_t)r * map->width + c] =
                    (float)std::min<double>(dist.at<float>(r, c) * map->resolution, p->max_dist);
        if (f->free_.empty())
            f->free_.push_back(0);
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
    f->quiet_ = 20;
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
    f->quiet_ = 20;
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
    const double inv = 1.0 / res_;
    const Eigen::Index n = x_.size();
    Eigen::ArrayXd ll(n);
    for (Eigen::Index i = 0; i < n; i++) {
        double c = std::cos(th_[i]), s = std::sin(th_[i]);
        double lx = x_[i] + c * p_.laser_x - s * p_.laser_y;
        double ly = y_[i] + s * p_.laser_x + c * p_.laser_y;
        double lc = std::cos(th_[i] + p_.laser_theta), ls = std::sin(th_[i] + p_.laser_theta);
        double sum = 0;
        for (int j = 0; j < nb; j++) {
            double fx = (lx + br[j] * (lc * bc[j] - ls * bs[j]) - ox_) * inv;
            double fy = (ly + br[j] * (ls * bc[j] + lc * bs[j]) - oy_) * inv;
            if (fx >= 0 && fy >= 0 && fx < mw_ && fy < mh_)
                sum += llf_[(size_t)(int)fy * mw_ + (int)fx];
            else
                sum += ll_out_;
        }
        ll[i] = sum;
    }
    // Recovery bookkeeping on the per-beam geometric-mean likelihood (no underflow).
    double avg = (ll / nb).exp().mean();
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
    double inject = 0;
    if (p_.alpha_slow > 0 && p_.alpha_fast > 0 && w_slow_ > 0)
        inject = std::max(0.0, 1.0 - w_fast_ / w_slow_);
    if (lost())
        inject = std::max(inject, 0.5 * (1.0 - w_fast_ / p_.lost_likelihood));

    std::vector<double> nx, ny, nt;
    nx.reserve(p_.particles_max); ny.reserve(p_.particles_max); nt.reserve(p_.particles_max);
    std::unordered_set<uint64_t> bins;
    size_t target = (size_t)p_.particles_min;
    while (nx.size() < (size_t)p_.particles_max && (nx.size() < target || nx.size() < (size_t)p_.particles_min)) {
        double x, y, th;
        if (inject > 0 && uniform() < inject) {
            random_free_pose(&x, &y, &th);
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
    if (scan && scan->n > 0 && scan->ranges)
        f->weigh(scan);
    f->updates_++;
    if (f->quiet_ > 0)
        f->quiet_--;
    double ess = 1.0 / f->w_.square().sum();
    if (ess < f->p_.resample_ess * (double)f->w_.size() ||
        (f->w_slow_ > 0 && f->w_fast_ < 0.5 * f->w_slow_ && f->p_.alpha_fast > 0) || f->lost())
        f->resample();
    return 1;
}

extern "C" void mcl_reanchor(mcl_t *f, const double odom[3])
{
    f->odom_[0] = odom[0]; f->odom_[1] = odom[1]; f->odom_[2] = odom[2];
    f->have_odom_ = true;
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

extern "C" void mcl_estimate(const mcl_t *f, double pose[3], double cov[9])
{
    weighted_stats(f, nullptr, pose, cov);
    if (cov[0] + cov[4] < 0.25)
        return;
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
    for (Eigen::Index i = 0; i < f->x_.size(); i++)
        if (std::hypot(f->x_[i] - cx, f->y_[i] - cy) < 1.5)
            sel.push_back(i);
    if (!sel.empty())
        weighted_stats(f, &sel, pose, cov);
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
extern "C" int64_t mcl_resamples(const mcl_t *f) { return f->resamples_; }
extern "C" double mcl_likelihood(const mcl_t *f) { return f->lik_; }
