/* bench_adapters: cost of a localizer update, of a lost robot's search over the whole map (the
 * office and nav2's warehouse), planning time on the office map, and the cost of one arbitration
 * cycle. TSV rows: bench metric value unit baseline ratio. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/behaviours/arbiter.h"
#include "map/occmap.h"
#include "adapters/localizer/mcl.h"
#include "adapters/localizer/reloc.h"
#include "adapters/planner/planner.h"
#include "bench/bench.h"
#include "core/time.h"
#include "tests/adapters/simworld.h"

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double pct(double *v, int n, double q)
{
    qsort(v, n, sizeof(double), cmp_double);
    int i = (int)ceil(q * n) - 1;
    return v[i < 0 ? 0 : i >= n ? n - 1 : i];
}

static void row(const char *metric, double value, const char *unit)
{
    bench_row("adapters", metric, value, unit, NAN);
}

static occmap_t *office(const char **which)
{
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load("sim/worlds/office.yaml", &errs);
    marie_errors_clear(&errs);
    *which = "sim/worlds/office";
    if (!m) {
        *which = "generated 40x30 m office";
        m = occmap_make_office(40, 30, 0.05, 11);
    }
    return m;
}

static void bench_localizer(const occmap_t *m, int particles, int beams, const char *tag)
{
    mcl_params_t p;
    mcl_params_default(&p);
    p.particles_min = p.particles_max = particles;
    p.max_beams = beams;
    mcl_t *f = mcl_create(m, &p, 1);
    /* In the main corridor, moving along it. */
    simrobot_t r = { { 10, 15, 0 }, { 0, 0, 0 }, 1.0, 0, 0.01, 0.01, { 3 } };
    double sig[3] = { 0.1, 0.1, 0.05 };
    mcl_init_pose(f, r.truth, sig);
    float ranges[181];
    enum { N = 60 };
    double t[N];
    for (int i = 0; i < N + 1; i++) {
        sim_move(&r, m, 0.5, 0.0, 0.2);
        sim_scan(&r, m, ranges, 181, 8.0, 0.01, 0.0);
        mcl_scan_t s = { ranges, 181, -M_PI / 2, M_PI / 180, 0.05, 8.0 };
        int64_t t0 = marie_mono_us();
        mcl_step(f, r.odom, &s, true);
        if (i > 0)
            t[i - 1] = (marie_mono_us() - t0) / 1e3;
    }
    char name[96];
    snprintf(name, sizeof(name), "localizer_update_%s_median", tag);
    row(name, pct(t, N, 0.5), "ms");
    snprintf(name, sizeof(name), "localizer_update_%s_p90", tag);
    row(name, pct(t, N, 0.9), "ms");
    mcl_destroy(f);
}

static void bench_planner(const occmap_t *m, const char *algo, const char *tag)
{
    planner_params_t p;
    planner_params_default(&p);
    p.algorithm = algo;
    planner_t *pl = planner_create(m, &p, 7);
    enum { N = 40 };
    double t[N];
    int ok = 0, n = 0;
    simrng_t rng = { 12345 };
    double W = m->width * m->resolution, H = m->height * m->resolution;
    while (n < N) {
        double s[3] = { m->origin_x + sim_uniform(&rng) * W, m->origin_y + sim_uniform(&rng) * H, 0 };
        double g[3] = { m->origin_x + sim_uniform(&rng) * W, m->origin_y + sim_uniform(&rng) * H, 0 };
        if (!planner_free(pl, s[0], s[1]) || !planner_free(pl, g[0], g[1]) || hypot(g[0] - s[0], g[1] - s[1]) < 10)
            continue;
        double *P = NULL;
        int np = 0;
        int64_t t0 = marie_mono_us();
        int rc = planner_plan(pl, s, g, &P, &np);
        t[n++] = (marie_mono_us() - t0) / 1e3;
        ok += rc == 0;
        free(P);
    }
    char name[96];
    snprintf(name, sizeof(name), "planner_%s_median", tag);
    row(name, pct(t, N, 0.5), "ms");
    snprintf(name, sizeof(name), "planner_%s_p90", tag);
    row(name, pct(t, N, 0.9), "ms");
    snprintf(name, sizeof(name), "planner_%s_success", tag);
    row(name, 100.0 * ok / N, "%");
    planner_destroy(pl);
}

static void bench_arbitration(void)
{
    static float ranges[181];
    for (int k = 0; k < 181; k++)
        ranges[k] = 2.0f + (k % 7) * 0.1f;
    double path[3 * 50];
    for (int i = 0; i < 50; i++) {
        path[3 * i] = i * 0.5;
        path[3 * i + 1] = sin(i * 0.3);
        path[3 * i + 2] = 0;
    }
    arb_params_t p;
    arb_params_default(&p);
    arb_state_t s;
    arb_state_reset(&s);
    arb_inputs_t in = { .pose = { 3, 0.5, 0.1 }, .pose_age = 0.05, .path = path, .npath = 50, .path_age = 0.5,
                        .ranges = ranges, .nranges = 181, .angle_min = -M_PI / 2, .angle_increment = M_PI / 180,
                        .range_min = 0.05, .range_max = 8, .scan_age = 0.05, .estop_age = 0.1, .teleop_age = -1,
                        .reloc_age = -1 };
    arb_vote_t v[ARB_COUNT];
    enum { N = 200000 };
    int64_t t0 = marie_mono_us();
    volatile double sink = 0;
    for (int i = 0; i < N; i++) {
        in.pose[0] = 3 + (i % 100) * 0.01;
        int w = arb_decide(&p, &s, &in, v);
        sink += v[w].v;
    }
    row("arbitration_cycle", (marie_mono_us() - t0) * 1e3 / N, "ns");
}

/* A turn on the spot at (x, y), then the whole map searched for where its points fit: the median
 * of 5 searches, and whether the best place was the true one each time. */
static void bench_search(const occmap_t *m, double x, double y, const char *tag)
{
    mcl_params_t p;
    mcl_params_default(&p);
    mcl_t *f = mcl_create(m, &p, 1);
    simrobot_t r = { { x, y, 0.3 }, { 0, 0, 0 }, 1.0, 0, 0.005, 0.005, { 5 } };
    reloc_cloud_t *c = reloc_cloud_create();
    reloc_cloud_reset(c, r.odom);
    float ranges[181];
    for (int k = 0; k < 126; k++) {             /* 0.5 rad/s for 12.6 s, a scan every 0.1 s */
        sim_move(&r, m, 0, 0.5, 0.1);
        sim_scan(&r, m, ranges, 181, 8.0, 0.01, 0.0);
        mcl_scan_t s = { ranges, 181, -M_PI / 2, M_PI / 180, 0.05, 8.0 };
        reloc_cloud_add(c, r.odom, (const double[3]){ 0, 0, 0 }, &s);
    }
    enum { N = 5 };
    double t[N];
    int right = 0;
    for (int i = 0; i < N; i++) {
        reloc_hyp_t h[8];
        int64_t t0 = marie_mono_us();
        int n = reloc_search(f, c, h, 8);
        t[i] = (marie_mono_us() - t0) / 1e3;
        double now[3];
        if (n > 0)
            reloc_cloud_pose_now(c, (const double[3]){ h[0].x, h[0].y, h[0].theta }, r.odom, now);
        right += n > 0 && hypot(now[0] - r.truth[0], now[1] - r.truth[1]) < 0.2;
    }
    char name[96];
    snprintf(name, sizeof name, "relocalization_search_%s_median", tag);
    row(name, pct(t, N, 0.5), "ms");
    snprintf(name, sizeof name, "relocalization_search_%s_found", tag);
    row(name, 100.0 * right / N, "%");
    reloc_cloud_destroy(c);
    mcl_destroy(f);
}

int main(void)
{
    const char *which;
    occmap_t *m = office(&which);
    fprintf(stderr, "bench_adapters: map %s (%dx%d cells)\n", which, m->width, m->height);
    bench_localizer(m, 2000, 181, "2000x181");
    bench_localizer(m, 500, 60, "500x60");
    bench_search(m, 10.0, 15.0, "office");
    marie_errors_t errs = { 0 };
    occmap_t *wh = occmap_load("tests/data/nav2/warehouse.yaml", &errs);
    marie_errors_clear(&errs);
    if (wh)
        bench_search(wh, 0.0, 0.0, "nav2_warehouse");
    occmap_destroy(wh);
    bench_planner(m, "rrtconnect", "rrtconnect_office");
    bench_planner(m, "prm", "prm_office");
    bench_planner(m, "grid", "grid_office");
    bench_arbitration();
    occmap_destroy(m);
    return 0;
}
