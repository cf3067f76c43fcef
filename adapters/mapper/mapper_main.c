/* marie-mapper: builds the occupancy grid from laser and odometry (scan matching, pose graph
 * with loop closures) and publishes it with the robot's pose in it. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/common/posebuf.h"
#include "adapters/common/scanwait.h"
#include "adapters/mapper/mapper_params.h"
#include "adapters/mapper/slam.h"
#include "core/clear.h"
#include "core/component.h"
#include "map/occmap.h"

typedef struct {
    slam_t *slam;
    posebuf_t odom;
    scanwait_t wait;            /* a scan newer than the newest odometry */
    int64_t last_scan_utime;
    double last_distance;
    bool changed;                   /* keyframes added since the last map message */
    int64_t last_map_pub;           /* the last whole map's time: its readers' map_utime */
    occmap_t *sent;                 /* what the readers hold: the last whole map and the updates since */
    slam_stats_t seen;              /* counters already reported */
} mapper_t;

static void report(marie_component_t *c, mapper_t *s)
{
    slam_stats_t st;
    slam_get_stats(s->slam, &st);
    marie_component_count(c, "keyframes", st.keyframes - s->seen.keyframes);
    marie_component_count(c, "match_failures", st.match_failures - s->seen.match_failures);
    marie_component_count(c, "loop_candidates", st.loop_candidates - s->seen.loop_candidates);
    marie_component_count(c, "loop_ambiguous", st.loop_ambiguous - s->seen.loop_ambiguous);
    marie_component_count(c, "loop_implausible", st.loop_implausible - s->seen.loop_implausible);
    marie_component_count(c, "cells_cleared", st.cells_cleared - s->seen.cells_cleared);
    marie_component_count(c, "loop_cut", st.loop_cut - s->seen.loop_cut);
    marie_component_count(c, "window_grown", st.window_grown - s->seen.window_grown);
    marie_component_count(c, "odometry_disagreements", st.odometry_disagreements - s->seen.odometry_disagreements);
    if (st.off_grid > s->seen.off_grid) {
        marie_component_count(c, "off_grid", st.off_grid - s->seen.off_grid);
        if (s->seen.off_grid == 0)      /* once: the counter says how often since */
            marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "off_grid",
                                  "the robot's scans reach past the map's %.0f m square (size_m): not mapped there",
                                  ((const mapper_params_t *)marie_component_params(c))->slam.size_m);
    }
    if (st.loop_closures > s->seen.loop_closures) {
        marie_component_count(c, "loop_closures", st.loop_closures - s->seen.loop_closures);
        if (st.optimizations > s->seen.optimizations)
            marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "loop_closed", "loop closed: %lld keyframes optimized in %.1f ms",
                                  (long long)st.keyframes, st.last_opt_ms);
        else
            marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "loop_closed",
                                  "loop closed: agrees with the map within loop_optimize_xy/_th (kept in the graph)");
    }
    s->seen = st;
}

static void process(marie_component_t *c, mapper_t *s, const marie_laser_scan_t *scan)
{
    const mapper_params_t *q = marie_component_params(c);
    double odom[3], pose[3];
    if (!posebuf_at(&s->odom, scan->utime, odom))
        return;
    if ((double)(scan->utime - posebuf_newest(&s->odom)) / 1e6 > q->odom_timeout_s) {
        marie_component_count(c, "scans_stale_odometry", 1);
        return;
    }
    slam_scan_t ss = { scan->ranges, scan->nranges, scan->angle_min, scan->angle_increment, scan->range_min,
                       scan->range_max };
    int r = slam_add_scan(s->slam, odom, &ss, pose);
    if (r < 0) {
        marie_component_bad_input(c, "bad_scan", "scan at %lld refused", (long long)scan->utime);
        return;
    }
    s->last_scan_utime = scan->utime;
    marie_component_count(c, "scans", 1);
    if (r > 0)
        s->changed = true;
    report(c, s);
    marie_pose_cov_t out = { .utime = scan->utime, .frame = "map", .pose = { pose[0], pose[1], pose[2] } };
    /* Scan matching pins the pose to a few cells; the covariance says so to the planner and viewer. */
    out.cov[0] = out.cov[4] = 0.05 * 0.05;
    out.cov[8] = 0.02 * 0.02;
    marie_port_publish(marie_port(c, "pose"), &out);
}

static bool scan_ok(marie_component_t *c, mapper_t *s, const marie_laser_scan_t *m)
{
    if (m->nranges <= 0 || m->nranges > 10000 || !isfinite(m->angle_min) || !isfinite(m->angle_increment) ||
        m->angle_increment == 0 || !(m->range_max > 0) || !isfinite(m->range_max) || !isfinite(m->range_min)) {
        marie_component_bad_input(c, "bad_scan", "laser scan with %d beams, increment %g, range_max %g", m->nranges,
                                  m->angle_increment, m->range_max);
        return false;
    }
    if (m->utime <= s->last_scan_utime) {
        /* An old scan would be matched from where the robot is now: it would smear the map. */
        marie_component_count(c, "scans_out_of_order", 1);
        return false;
    }
    return true;
}

static void on_scan_at_odometry(marie_component_t *c, const marie_laser_scan_t *m)
{
    process(c, marie_component_user(c), m);
}

static void on_scan(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    mapper_t *s = marie_component_user(c);
    const marie_laser_scan_t *m = msg;
    if (!scan_ok(c, s, m))
        return;
    scanwait_scan(&s->wait, c, &s->odom, m, on_scan_at_odometry);
}

static void on_odom(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    mapper_t *s = marie_component_user(c);
    const marie_odometry_t *m = msg;
    if (!isfinite(m->pose.x) || !isfinite(m->pose.y) || !isfinite(m->pose.theta)) {
        marie_component_bad_input(c, "bad_odometry", "odometry pose is not finite");
        return;
    }
    double jump;
    if (posebuf_frame_changed(&s->odom, m, s->last_distance, &jump)) {
        /* The next scan is matched from the last map pose. */
        marie_component_count(c, "odometry_restarts", 1);
        marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "odometry_restart",
                              "odometry frame jumped by %.2f m: matching from the last map pose", jump);
        posebuf_clear(&s->odom);
        slam_odometry_reset(s->slam);
        scanwait_drop(&s->wait);
    }
    s->last_distance = m->distance;
    posebuf_add(&s->odom, m->utime, (const double[3]){ m->pose.x, m->pose.y, m->pose.theta });
    scanwait_odometry(&s->wait, c, m->utime, on_scan_at_odometry);
}

/* The smallest rectangle holding every cell of `now` that differs from `was` (same geometry);
 * false when none does. */
static bool changed_rect(const occmap_t *was, const occmap_t *now, int r[4])
{
    int x0 = now->width, y0 = now->height, x1 = -1, y1 = -1;
    for (int y = 0; y < now->height; y++) {
        const int8_t *a = was->cells + (size_t)y * now->width, *b = now->cells + (size_t)y * now->width;
        if (!memcmp(a, b, (size_t)now->width))
            continue;
        int lo = 0, hi = now->width - 1;
        while (a[lo] == b[lo])
            lo++;
        while (a[hi] == b[hi])
            hi--;
        x0 = lo < x0 ? lo : x0;
        x1 = hi > x1 ? hi : x1;
        y0 = y < y0 ? y : y0;
        y1 = y;
    }
    r[0] = x0, r[1] = y0, r[2] = x1 - x0 + 1, r[3] = y1 - y0 + 1;
    return x1 >= 0;
}

/* Only the rectangle that changed since what the readers hold, when the map is large, its frame
 * the same and a whole map is not due: 1 when sent (or nothing changed), 0 when the whole map
 * must go. A reader that lost an update is mended by the next whole map: without republish_s
 * every map goes whole. */
static int publish_update(marie_component_t *c, mapper_t *s, const occmap_t *m, int64_t now, bool due)
{
    const mapper_params_t *q = marie_component_params(c);
    const occmap_t *o = s->sent;
    if (due || !o || q->update_cells <= 0 || !(q->republish_s > 0) || (int64_t)m->width * m->height < q->update_cells ||
        m->width != o->width || m->height != o->height || m->resolution != o->resolution ||
        m->origin_x != o->origin_x || m->origin_y != o->origin_y)
        return 0;
    int r[4];
    if (!changed_rect(o, m, r))
        return 1;
    if ((int64_t)r[2] * r[3] * 2 > (int64_t)m->width * m->height)
        return 0;       /* most of it changed (a closure re-rendered it): the whole map is as small */
    int8_t *cells = malloc((size_t)r[2] * r[3]);
    if (!cells)
        return 0;
    for (int y = 0; y < r[3]; y++) {
        const int8_t *row = m->cells + (size_t)(r[1] + y) * m->width + r[0];
        memcpy(cells + (size_t)y * r[2], row, (size_t)r[2]);
        memcpy(s->sent->cells + (size_t)(r[1] + y) * m->width + r[0], row, (size_t)r[2]);
    }
    marie_occupancy_grid_update_t u = { .utime = now, .map_utime = s->last_map_pub, .x = r[0], .y = r[1],
                                        .width = r[2], .height = r[3], .ncells = r[2] * r[3], .cells = cells };
    if (marie_port_publish(marie_port(c, "map_update"), &u) == 0)
        marie_component_count(c, "map_updates", 1);
    free(cells);
    return 1;
}

static void publish_map(marie_component_t *c, int64_t overruns)
{
    mapper_t *s = marie_component_user(c);
    const mapper_params_t *q = marie_component_params(c);
    int64_t now = marie_component_now(c);
    bool due = q->republish_s > 0 && (double)(now - s->last_map_pub) / 1e6 >= q->republish_s;
    if (!s->changed && !due)
        return;
    /* A large map is cropped to whole blocks, so that its frame stays while it grows inside one. */
    bool large = q->update_cells > 0 && s->sent && (int64_t)s->sent->width * s->sent->height >= q->update_cells;
    occmap_t *m = slam_render_blocks(s->slam, large ? q->map_block : 1);
    if (!m)
        return;
    s->changed = false;
    if (publish_update(c, s, m, now, due)) {
        occmap_destroy(m);
        return;
    }
    marie_occupancy_grid_t g = { .utime = now, .resolution = (float)m->resolution, .width = m->width,
                                 .height = m->height, .origin = { m->origin_x, m->origin_y, 0 },
                                 .ncells = m->width * m->height, .cells = m->cells };
    if (marie_port_publish(marie_port(c, "map"), &g) == 0)
        marie_component_count(c, "maps", 1);
    occmap_destroy(s->sent);
    s->sent = m;
    s->last_map_pub = now;
}

static void quit(marie_component_t *c)
{
    mapper_t *s = marie_component_user(c);
    MARIE_CLEAR(s->slam, slam_destroy);
    MARIE_CLEAR(s->sent, occmap_destroy);
    scanwait_free(&s->wait);
}

static int init(marie_component_t *c)
{
    mapper_t *s = marie_component_user(c);
    const mapper_params_t *q = marie_component_params(c);
    quit(c);    /* init again after a failure starts from scratch */
    posebuf_clear(&s->odom);
    scanwait_drop(&s->wait);
    s->last_scan_utime = INT64_MIN;
    s->last_distance = 0;
    s->changed = false;
    s->last_map_pub = 0;
    memset(&s->seen, 0, sizeof(s->seen));
    s->slam = slam_create(&q->slam, (const double[3]){ q->init_x, q->init_y, q->init_theta });
    if (!s->slam) {
        marie_component_fail_reason(c, "bad mapper parameters (resolution >= 0.01, size_m / resolution <= 8000, "
                                       "kf_dist and kf_angle > 0)");
        return -1;
    }
    if (!(q->map_hz > 0 && q->map_hz <= 100) || q->map_block < 1 || q->map_block > 4096) {
        marie_component_fail_reason(c, "map_hz must be in (0, 100], map_block in [1, 4096]");
        return -1;
    }
    if (marie_port_on_message(marie_port(c, "odom"), on_odom) || marie_port_on_message(marie_port(c, "scan"), on_scan)) {
        marie_component_fail_reason(c, "cannot subscribe to inputs");
        return -1;
    }
    return marie_component_every(c, q->map_hz, publish_map) ? 0 : -1;
}

static const marie_port_spec_t ports[] = {
    { "odom", &marie_type_odometry_t, MARIE_IN, MARIE_PUSH, "ODOMETRY" },
    { "scan", &marie_type_laser_scan_t, MARIE_IN, MARIE_PUSH, "LASER" },
    { "map", &marie_type_occupancy_grid_t, MARIE_OUT, MARIE_PUSH, "MAP" },
    { "map_update", &marie_type_occupancy_grid_update_t, MARIE_OUT, MARIE_PUSH, "MAP_UPDATE" },
    { "pose", &marie_type_pose_cov_t, MARIE_OUT, MARIE_PUSH, "POSE" },
    { 0 },
};

static const marie_param_spec_t params[] = MAPPER_PARAMS;

static const marie_component_def_t def = {
    .kind = "mapper", .ports = ports, .params = params, .params_size = sizeof(mapper_params_t),
    .on_init = init, .on_quit = quit,
};

int main(int argc, char **argv)
{
    mapper_t s = { 0 };
    return marie_main(&def, argc, argv, &s);
}
