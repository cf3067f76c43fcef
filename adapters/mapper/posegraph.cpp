// posegraph: 2D pose graph optimization with Ceres (as Ceres's own pose_graph_2d example).
#include "adapters/mapper/posegraph.hpp"

#include <ceres/ceres.h>

namespace mapper {

namespace {

struct RelativeCost {
    RelativeCost(const Pose &z, double sxy, double sth) : z_(z), wxy_(1 / sxy), wth_(1 / sth) {}

    template <typename T>
    bool operator()(const T *a, const T *b, T *r) const
    {
        T c = ceres::cos(a[2]), s = ceres::sin(a[2]);
        T dx = b[0] - a[0], dy = b[1] - a[1];
        T e = b[2] - a[2] - T(z_.th);
        r[0] = (c * dx + s * dy - T(z_.x)) * T(wxy_);
        r[1] = (-s * dx + c * dy - T(z_.y)) * T(wxy_);
        r[2] = ceres::atan2(ceres::sin(e), ceres::cos(e)) * T(wth_);
        return true;
    }

    Pose z_;
    double wxy_, wth_;
};

}  // namespace

OptResult optimize(std::vector<Pose> &nodes, const std::vector<Edge> &edges, int max_iterations, int fixed_upto)
{
    OptResult res;
    if (nodes.size() < 2 || edges.empty()) {
        res.message = "nothing to optimize";
        return res;
    }
    std::vector<double> x(nodes.size() * 3);
    for (size_t i = 0; i < nodes.size(); i++) {
        x[3 * i] = nodes[i].x;
        x[3 * i + 1] = nodes[i].y;
        x[3 * i + 2] = nodes[i].th;
    }
    ceres::Problem problem;
    for (const Edge &e : edges) {
        if (e.a < 0 || e.b < 0 || e.a >= (int)nodes.size() || e.b >= (int)nodes.size() || e.a == e.b)
            continue;
        auto *cost = new ceres::AutoDiffCostFunction<RelativeCost, 3, 3, 3>(new RelativeCost(e.z, e.sigma_xy, e.sigma_th));
        problem.AddResidualBlock(cost, e.loop ? new ceres::CauchyLoss(1.0) : nullptr, &x[3 * e.a], &x[3 * e.b]);
    }
    if (!problem.HasParameterBlock(&x[0])) {
        res.message = "the first node has no edge";
        return res;
    }
    for (int i = 0; i <= fixed_upto && i < (int)nodes.size(); i++)
        if (problem.HasParameterBlock(&x[3 * i]))
            problem.SetParameterBlockConstant(&x[3 * i]);
    ceres::Solver::Options opt;
    opt.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    std::string why;
    if (!opt.IsValid(&why))
        opt.linear_solver_type = ceres::DENSE_QR;
    opt.max_num_iterations = max_iterations;
    opt.num_threads = 1;
    opt.logging_type = ceres::SILENT;
    ceres::Solver::Summary sum;
    ceres::Solve(opt, &problem, &sum);
    res.ok = sum.IsSolutionUsable();
    res.iterations = (int)sum.iterations.size();
    res.initial_cost = sum.initial_cost;
    res.final_cost = sum.final_cost;
    res.message = sum.message;
    if (!res.ok)
        return res;
    for (size_t i = 0; i < nodes.size(); i++)
        nodes[i] = { x[3 * i], x[3 * i + 1], wrap(x[3 * i + 2]) };
    return res;
}

}  // namespace mapper
