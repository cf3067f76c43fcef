// posegraph: 2D pose graph optimization (relative-pose edges, robust loop closures) with Ceres.
#ifndef ADAPTERS_MAPPER_POSEGRAPH_HPP
#define ADAPTERS_MAPPER_POSEGRAPH_HPP

#include <string>
#include <vector>

#include "adapters/mapper/scangrid.hpp"

namespace mapper {

struct Edge {
    int a = 0, b = 0;                 // node b measured from node a
    Pose z;
    double sigma_xy = 0.05, sigma_th = 0.02;
    bool loop = false;                // loop closures get a robust loss: a wrong one must not bend the map
};

struct OptResult {
    bool ok = false;
    int iterations = 0;
    double initial_cost = 0, final_cost = 0;
    std::string message;
};

// Moves nodes (node 0 held fixed) to best agree with the edges.
OptResult optimize(std::vector<Pose> &nodes, const std::vector<Edge> &edges, int max_iterations = 50, int fixed_upto = 0);

}  // namespace mapper
#endif
