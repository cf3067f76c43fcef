// bench_mapper: the mapper's costs: one scan update (match + keyframe), the map rendered for a
// message, a 2000-node pose graph optimized as the mapper does it, the grid's memory for a
// 100 x 100 m world.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "adapters/mapper/posegraph.hpp"
#include "adapters/mapper/scangrid.hpp"
#include "adapters/mapper/slam.h"
#include "bench/bench.h"
#include "tests/adapters/simworld.h"

using clk = std::chrono::steady_clock;

static double ms(clk::time_point a, clk::time_point b)
{
    return std::chrono::duration<double, std::milli>(b - a).count();
}

static double pct(std::vector<double> v, double q)
{
    std::sort(v.begin(), v.end());
    size_t i = (size_t)std::max(0.0, std::ceil(q * v.size()) - 1);
    return v[std::min(i, v.size() - 1)];
}

static void row(const char *metric, double value, const char *unit)
{
    bench_row("mapper", metric, value, unit, NAN);
}

int main()
{
    marie_errors_t errs = {};
    occmap_t *world = occmap_load("sim/worlds/office.yaml", &errs);
    if (!world) {
        fprintf(stderr, "bench_mapper: cannot load sim/worlds/office.yaml (run from the repository)\n");
        return 1;
    }
    slam_params_t p;
    slam_params_default(&p);
    simrobot_t r = {};
    r.truth[0] = 2.0, r.truth[1] = 15.7;
    r.v_scale = 1.01, r.gyro_bias = 0.005, r.v_noise = 0.02, r.w_noise = 0.01, r.rng.s = 5;
    slam_t *s = slam_create(&p, r.truth);
    std::vector<double> upd, render;
    float ranges[181];
    for (int step = 0; step < 1200; step++) {
        double v = 0.6, w = step % 600 < 580 ? 0.0 : M_PI / 2;   /* down the corridor and back */
        sim_scan(&r, world, ranges, 181, 8.0, 0.01, 0.01);
        slam_scan_t sc = { ranges, 181, -M_PI / 2, M_PI / 180, 0.05, 8.0 };
        auto t0 = clk::now();
        slam_add_scan(s, r.odom, &sc, nullptr);
        upd.push_back(ms(t0, clk::now()));
        if (step % 50 == 49) {
            t0 = clk::now();
            occmap_t *m = slam_render(s);
            render.push_back(ms(t0, clk::now()));
            occmap_destroy(m);
        }
        sim_move(&r, world, w ? 0.0 : v, w, 0.1);
    }
    row("scan_update_181_median", pct(upd, 0.5), "ms");
    row("scan_update_181_p90", pct(upd, 0.9), "ms");
    row("scan_update_181_max", pct(upd, 1.0), "ms");
    row("map_render_median", pct(render, 0.5), "ms");
    slam_destroy(s);
    occmap_destroy(world);

    /* A 2000-node graph built the way the mapper builds it: ten laps of a 10 m square (0.2 m
     * steps) on odometry that turns 0.17 degree too far per step, with closures to the first lap
     * found as the robot drives (ten per 175 nodes, 100 in all), the graph optimized as they
     * come. The row is the last optimization: 2000 nodes, 100 loop edges; the ATE says it
     * converged. Solved once from raw odometry instead (6 rad of heading drift), the robust loss
     * takes every closure for an outlier: 50 iterations and metres of error (docs/mapping.md). */
    std::mt19937 rng(1);
    std::normal_distribution<double> n01(0, 1);
    std::vector<mapper::Pose> truth, nodes;
    std::vector<mapper::Edge> edges;
    mapper::Pose t;
    for (int i = 0; i < 2000; i++) {
        truth.push_back(t);
        t = mapper::compose(t, { 0.2, 0, (i % 50 == 49) ? M_PI / 2 : 0 });
    }
    nodes.push_back(truth[0]);
    double opt_ms = NAN;
    mapper::OptResult res;
    for (int i = 1; i < 2000; i++) {
        mapper::Edge e;
        e.a = i - 1, e.b = i;
        e.z = mapper::between(truth[i - 1], truth[i]);
        e.z.x += 0.01 * n01(rng), e.z.th += 0.003 + 0.002 * n01(rng);
        edges.push_back(e);
        nodes.push_back(mapper::compose(nodes.back(), e.z));
        if (i < 424 || (1999 - i) % 175 != 0)
            continue;
        for (int k = 0; k < 10; k++) {
            int b = i - (int)(rng() % 175), a = b % 200;
            mapper::Edge l;
            l.a = a, l.b = b, l.z = mapper::between(truth[a], truth[b]), l.loop = true;
            edges.push_back(l);
        }
        auto t0 = clk::now();
        res = mapper::optimize(nodes, edges);
        opt_ms = ms(t0, clk::now());
    }
    double se = 0;
    for (size_t i = 0; i < nodes.size(); i++)
        se += std::pow(nodes[i].x - truth[i].x, 2) + std::pow(nodes[i].y - truth[i].y, 2);
    row("posegraph_2000_nodes", opt_ms, "ms");
    row("posegraph_2000_nodes_iterations", res.iterations, "count");
    row("posegraph_2000_nodes_ate", std::sqrt(se / (double)nodes.size()), "m");
    if (!res.ok)
        fprintf(stderr, "bench_mapper: optimization failed: %s\n", res.message.c_str());
    mapper::GridParams gp;
    slam_params_default(&gp);
    mapper::Grid big(2000, 2000, 0, 0, gp);
    row("grid_100x100m_memory", big.memory_bytes() / 1048576.0, "MiB");
    return 0;
}
