/* marie-planner: plans a path to the mission's goal on the inflated map (A* or OMPL), and plans
 * again when the goal changes or the laser shows the path blocked. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "map/occmap.h"
#include "map/livemap.h"
#include "adapters/common/posebuf.h"
#include "adapters/planner/planner.h"
#include "core/clear.h"
#include "core/component.h"
#include "adapters/planner/planner_main_params.h"

typedef struct {
    const pln_params_t *q;
    planner_t *pl;
    livemap_t live;             /* the map from the bus (MAP, MAP_UPDATE) */
    bool have_pose, have_goal, want_plan;
    double pose[3];             /* the newest POSE, and the time it is for */
    int64_t pose_utime;
    posebuf_t odom;             /* recent odometry: the pose at a scan's time (see pose_at) */
    double odom_to_map[3];      /* map pose of the odometry frame, from the newest POSE */
    bool have_odom_to_map;
    marie_goal_t goal;          /* strings not kept */
    char goal_name[64];
    double *path;
    int npath;
    int8_t status;
    int64_t last_plan, last_check, last_publish;
    double check_period_s;
    double *pts;
    int pts_cap;
    char last_failure[320];     /* said once per goal until it changes */
} pln_t;

static double secs(int64_t us)
{
    return (double)us / 1e6;
}

static void publish_path(marie_component_t *c, pln_t *s)
{
    marie_pose2d_t *poses = calloc(s->npath ? s->npath : 1, sizeof(*poses));
    if (!poses)
        return;
    for (int i = 0; i < s->npath; i++)
        poses[i] = (marie_pose2d_t){ s->path[3 * i], s->path[3 * i + 1], s->path[3 * i + 2] };
    marie_path_t m = { .utime = marie_component_now(c), .goal_id = s->goal.id, .status = s->status,
                       .nposes = s->npath, .poses = poses };
    marie_port_publish(marie_port(c, "path"), &m);
    s->last_publish = marie_component_now(c);
    free(poses);
}

/* A failed plan, said when it is new for this goal (a failure retried every few seconds is
 * counted, not said again): which end is blocked and why, or that no path was found. */
static void say_failure(marie_component_t *c, pln_t *s, int err, const double goal[3], int64_t dt, const char *why)
{
    char what[160];
    if (err == EINVAL)
        planner_blocked(s->pl, s->pose, goal, what, sizeof what);
    else
        snprintf(what, sizeof what, "no path found from (%.2f, %.2f)", s->pose[0], s->pose[1]);
    char line[sizeof s->last_failure];
    snprintf(line, sizeof line, "goal %d '%s' (%.2f, %.2f): %s", s->goal.id, s->goal_name, goal[0], goal[1], what);
    if (strcmp(line, s->last_failure) == 0)
        return;
    snprintf(s->last_failure, sizeof s->last_failure, "%s", line);
    marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "no_path", "%s after %.0f ms (%s)", line, dt / 1e3, why);
}

static void plan(marie_component_t *c, pln_t *s, const char *why)
{
    if (!s->pl) {
        marie_component_count(c, "plans_without_map", 1);
        return;
    }
    s->want_plan = false;
    s->last_plan = marie_component_now(c);
    double goal[3] = { s->goal.pose.x, s->goal.pose.y, s->goal.pose.theta };
    double *poses = NULL;
    int n = 0;
    int64_t t0 = marie_mono_us();
    int err = planner_plan(s->pl, s->pose, goal, &poses, &n) < 0 ? errno : 0;
    int layer = planner_obstacle_count(s->pl);
    bool laser_only = err == EINVAL && (planner_blocked(s->pl, s->pose, goal, NULL, 0) & PLANNER_BY_LASER);
    if ((err == ENOENT || laser_only) && layer > 0) {
        /* The map has a way (or room at the start and goal) the laser layer closes. In a
         * corridor barely wider than the robot one misplaced return does that, and the scans of
         * a robot waiting for a path keep it there: forget the layer and plan on the map (as a
         * costmap is cleared before a retry). Avoid still stops the robot short of whatever is
         * really there, and a path the layer blocks again is planned again. */
        marie_component_count(c, "obstacles_forgotten", 1);
        marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "obstacles_forgotten",
                              "goal %d: %s %d laser obstacle cells: forgotten, planning on the map", s->goal.id,
                              laser_only ? "start or goal covered by" : "no path past", layer);
        planner_clear_obstacles(s->pl);
        err = planner_plan(s->pl, s->pose, goal, &poses, &n) < 0 ? errno : 0;
    }
    int64_t dt = marie_mono_us() - t0;
    free(s->path);
    s->path = poses;
    s->npath = err == 0 ? n : 0;
    int ends = err == EINVAL ? planner_blocked(s->pl, s->pose, goal, NULL, 0) : 0;
    s->status = err == 0 ? MARIE_PATH_T_STATUS_OK : (ends & PLANNER_START_BLOCKED) ? MARIE_PATH_T_STATUS_INVALID_START
              : err == EINVAL ? MARIE_PATH_T_STATUS_INVALID_GOAL : MARIE_PATH_T_STATUS_NO_PATH;
    marie_component_count(c, err == 0 ? "plans" : "plan_failures", 1);
    if (err == 0) {
        marie_debug("goal %d: %d poses in %.1f ms (%s)", s->goal.id, n, dt / 1e3, why);
        s->last_failure[0] = 0;
    } else {
        say_failure(c, s, err, goal, dt, why);
    }
    publish_path(c, s);
}

/* Distance from a pose to a path's polyline. */
static double path_distance(const double *path, int n, const double pose[3])
{
    double best = INFINITY;
    for (int i = 0; i + 1 < n; i++) {
        double ax = path[3 * i], ay = path[3 * i + 1], dx = path[3 * i + 3] - ax, dy = path[3 * i + 4] - ay;
        double l2 = dx * dx + dy * dy;
        double t = l2 > 0 ? ((pose[0] - ax) * dx + (pose[1] - ay) * dy) / l2 : 0;
        t = t < 0 ? 0 : t > 1 ? 1 : t;
        best = fmin(best, hypot(ax + t * dx - pose[0], ay + t * dy - pose[1]));
    }
    return best;
}

static void on_goal(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    pln_t *s = marie_component_user(c);
    const marie_goal_t *m = msg;
    if (!isfinite(m->pose.x) || !isfinite(m->pose.y) || !isfinite(m->pose.theta)) {
        marie_component_bad_input(c, "bad_goal", "goal %d is not finite", m->id);
        return;
    }
    bool same = s->have_goal && m->id == s->goal.id && m->pose.x == s->goal.pose.x && m->pose.y == s->goal.pose.y;
    if (same)
        return;                 /* the mission repeats its goal; nothing changed */
    s->goal = *m;
    s->goal.name = NULL;
    snprintf(s->goal_name, sizeof(s->goal_name), "%s", m->name ? m->name : "");
    s->have_goal = true;
    s->want_plan = true;
    if (s->have_pose)
        plan(c, s, "new goal");
}

/* The behaviours saw no progress along the path: forget the laser obstacles (a phantom may
 * be what closes the way) and plan afresh. */
static void on_replan(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    pln_t *s = marie_component_user(c);
    const marie_goal_t *m = msg;
    if (!s->have_goal || m->id != s->goal.id || !s->pl)
        return;
    marie_component_count(c, "replans_asked", 1);
    marie_info("goal %d: the robot makes no progress: laser obstacles forgotten, planning again", m->id);
    planner_clear_obstacles(s->pl);
    if (s->have_pose)
        plan(c, s, "no progress");
}

static void on_pose(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    pln_t *s = marie_component_user(c);
    const marie_pose_cov_t *m = msg;
    if (!isfinite(m->pose.x) || !isfinite(m->pose.y) || !isfinite(m->pose.theta)) {
        marie_component_bad_input(c, "bad_pose", "pose is not finite");
        return;
    }
    s->pose[0] = m->pose.x;
    s->pose[1] = m->pose.y;
    s->pose[2] = m->pose.theta;
    s->pose_utime = m->utime;
    s->have_pose = true;
    /* A robot far from its path (found again elsewhere after being lost) needs a path from where
     * it is: following the old one would steer it across walls. */
    int64_t now = marie_component_now(c);
    if (s->have_goal && s->npath >= 2 && s->q->off_path > 0 && secs(now - s->last_plan) >= s->q->replan_min_s &&
        path_distance(s->path, s->npath, s->pose) > s->q->off_path) {
        marie_component_count(c, "replans_off_path", 1);
        plan(c, s, "the robot is off its path");
    }
    /* The localizer's pose is for an instant already past; odometry at that same instant gives
     * where the odometry frame lies in the map, and so the map pose at any later instant. */
    double o[3], inv[3];
    s->have_odom_to_map = posebuf_covers(&s->odom, m->utime, 100000) && posebuf_at(&s->odom, m->utime, o);
    if (s->have_odom_to_map) {
        pose2d_between(o, (const double[3]){ 0, 0, 0 }, inv);
        pose2d_compose(s->pose, inv, s->odom_to_map);
    }
}

static void on_odom(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    pln_t *s = marie_component_user(c);
    const marie_odometry_t *m = msg;
    if (!isfinite(m->pose.x) || !isfinite(m->pose.y) || !isfinite(m->pose.theta)) {
        marie_component_bad_input(c, "bad_odometry", "odometry pose is not finite");
        return;
    }
    if (m->utime < posebuf_newest(&s->odom)) {     /* a restarted odometry or a replayed log */
        posebuf_clear(&s->odom);
        s->have_odom_to_map = false;
    }
    posebuf_add(&s->odom, m->utime, (const double[3]){ m->pose.x, m->pose.y, m->pose.theta });
}

/* The robot's map pose at time t: the newest POSE moved on by odometry to t. Without odometry
 * only a POSE within 50 ms of t will do; false means the scan cannot be placed. */
static bool pose_at(const pln_t *s, int64_t t, double out[3])
{
    double o[3];
    if (s->have_odom_to_map && posebuf_covers(&s->odom, t, 100000) && posebuf_at(&s->odom, t, o)) {
        pose2d_compose(s->odom_to_map, o, out);
        return true;
    }
    if (llabs(t - s->pose_utime) > 50000)
        return false;
    memcpy(out, s->pose, sizeof s->pose);
    return true;
}

static void on_scan(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    pln_t *s = marie_component_user(c);
    const marie_laser_scan_t *m = msg;
    if (!s->have_pose || !s->q->use_scan || !s->pl)
        return;
    if (m->nranges < 0 || m->nranges > 10000 || !isfinite(m->angle_min) || !isfinite(m->angle_increment)) {
        marie_component_bad_input(c, "bad_scan", "scan with %d beams", m->nranges);
        return;
    }
    if (m->nranges > s->pts_cap) {
        double *n = realloc(s->pts, sizeof(double) * 2 * m->nranges);
        if (!n)
            return;
        s->pts = n;
        s->pts_cap = m->nranges;
    }
    /* Each return is placed from where the robot was when the scan was taken: with the newest
     * pose instead (older by the localizer's latency), a turning robot sees walls in free space. */
    double scan_pose[3];
    if (!pose_at(s, m->utime, scan_pose)) {
        marie_component_count(c, "scans_without_pose", 1);
        return;
    }
    double c0 = cos(scan_pose[2]), s0 = sin(scan_pose[2]);
    double lx = scan_pose[0] + c0 * s->q->laser_x - s0 * s->q->laser_y, ly = scan_pose[1] + s0 * s->q->laser_x + c0 * s->q->laser_y;
    int n = 0;
    for (int k = 0; k < m->nranges; k++) {
        double r = m->ranges[k];
        /* Only near returns matter for blocking, and they are the most precise. */
        if (!isfinite(r) || r <= m->range_min || r >= m->range_max || r > s->q->horizon)
            continue;
        double a = scan_pose[2] + s->q->laser_theta + m->angle_min + k * m->angle_increment;
        s->pts[2 * n] = lx + r * cos(a);
        s->pts[2 * n + 1] = ly + r * sin(a);
        n++;
    }
    int64_t now = marie_component_now(c);
    int added = planner_add_obstacles(s->pl, s->pts, n, secs(now));
    if (added)
        marie_component_count(c, "obstacle_cells", added);
    if (s->npath < 2 || secs(now - s->last_check) < s->check_period_s)
        return;
    s->last_check = now;
    int at = planner_path_blocked(s->pl, s->path, s->npath, s->pose[0], s->pose[1], s->q->horizon);
    if (at >= 0 && secs(now - s->last_plan) >= s->q->replan_min_s) {
        marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "path_blocked", "goal %d: segment %d blocked, replanning",
                              s->goal.id, at);
        plan(c, s, "path blocked");
    }
}

static void tick(marie_component_t *c, int64_t overruns)
{
    pln_t *s = marie_component_user(c);
    int64_t now = marie_component_now(c);
    if (!s->have_goal || !s->have_pose || !s->pl)
        return;
    /* A failed plan is retried (the obstacle may have gone); a good one is republished so a
     * late reader sees it. */
    if (s->want_plan || (s->status != MARIE_PATH_T_STATUS_OK && secs(now - s->last_plan) >= s->q->replan_min_s * 2))
        plan(c, s, s->want_plan ? "new goal" : "retry");
    else if (s->q->republish_s > 0 && secs(now - s->last_publish) >= s->q->republish_s)
        publish_path(c, s);
}

/* The live map (marie.occupancy_grid_t, 0..100 occupancy, -1 unknown, with the updates since)
 * replaces the planner's; a current path the robot would no longer fit along is planned again. */
static void use_live_map(marie_component_t *c, pln_t *s)
{
    occmap_t *om = livemap_occmap(&s->live);
    if (!om)
        return;
    for (size_t i = 0; i < (size_t)om->width * om->height; i++) {
        int8_t v = om->cells[i];
        om->cells[i] = v < 0 ? OCCMAP_UNKNOWN : v >= 65 ? OCCMAP_OCCUPIED : v < 20 ? OCCMAP_FREE : OCCMAP_UNKNOWN;
    }
    planner_t *pl = planner_create(om, &s->q->planner, (uint64_t)s->q->seed);
    int w = om->width, h = om->height;
    occmap_destroy(om);
    if (!pl) {
        marie_component_bad_input(c, "bad_map", "cannot build a planner on the %dx%d map", w, h);
        return;
    }
    planner_destroy(s->pl);
    s->pl = pl;
    if (s->npath >= 2 && planner_path_collides(s->pl, s->path, s->npath) >= 0) {
        marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "path_blocked", "goal %d: the new map blocks the path, replanning",
                              s->goal.id);
        plan(c, s, "map changed");
    } else if (s->have_goal && s->have_pose && s->status != MARIE_PATH_T_STATUS_OK) {
        plan(c, s, "new map");
    }
}

static void on_map(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    pln_t *s = marie_component_user(c);
    if (livemap_take_full(&s->live, c, msg)) {
        marie_component_count(c, "maps", 1);
        use_live_map(c, s);
    }
}

static void on_map_update(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    pln_t *s = marie_component_user(c);
    if (livemap_take_update(&s->live, c, msg))
        use_live_map(c, s);
}

static void quit(marie_component_t *c)
{
    pln_t *s = marie_component_user(c);
    MARIE_CLEAR(s->pl, planner_destroy);
    livemap_free(&s->live);
    MARIE_CLEAR(s->path, free);
    s->npath = 0;
    MARIE_CLEAR(s->pts, free);
    s->pts_cap = 0;
}

static int init(marie_component_t *c)
{
    pln_t *s = marie_component_user(c);
    const pln_params_t *q = s->q = marie_component_params(c);
    quit(c);
    s->have_goal = s->have_pose = s->want_plan = s->have_odom_to_map = false;
    posebuf_clear(&s->odom);
    const planner_params_t *p = &q->planner;
    if (planner_algorithm(p->algorithm) < 0) {
        marie_component_fail_reason(c, "algorithm: expected grid, rrtconnect or prm, got '%s'", p->algorithm);
        return -1;
    }
    if (!(p->robot_radius >= 0) || !(p->robot_clearance >= 0) || !(p->time_limit > 0)) {
        marie_component_fail_reason(c, "bad planner parameters (robot_radius, robot_clearance >= 0, time_limit > 0)");
        return -1;
    }
    const char *path = q->map;
    if (path[0]) {
        marie_errors_t errs = { 0 };
        occmap_t *map = occmap_load(path, &errs);
        if (!map) {
            marie_component_fail_reason(c, "map: %s", errs.n ? errs.msgs[0] : "cannot load");
            marie_errors_clear(&errs);
            return -1;
        }
        marie_info("map %s: %d x %d cells at %.3f m", path, map->width, map->height, map->resolution);
        s->pl = planner_create(map, p, (uint64_t)q->seed);
        occmap_destroy(map);
        if (!s->pl) {
            marie_component_fail_reason(c, "cannot build the planner on %s", path);
            return -1;
        }
    } else {
        marie_info("no map file: waiting for a map on %s", marie_port_channel(marie_port(c, "map")));
    }
    s->check_period_s = 1.0 / fmax(q->check_hz, 0.01);
    s->last_plan = s->last_check = s->last_publish = INT64_MIN / 2;
    if (marie_port_on_message(marie_port(c, "goal"), on_goal) || marie_port_on_message(marie_port(c, "pose"), on_pose) ||
        marie_port_on_message(marie_port(c, "scan"), on_scan) ||
        marie_port_on_message(marie_port(c, "odom"), on_odom) || marie_port_on_message(marie_port(c, "map"), on_map) ||
        marie_port_on_message(marie_port(c, "map_update"), on_map_update) ||
        marie_port_on_message(marie_port(c, "replan"), on_replan)) {
        marie_component_fail_reason(c, "cannot subscribe to inputs");
        return -1;
    }
    return marie_component_every(c, 2.0, tick) ? 0 : -1;
}

static const marie_port_spec_t ports[] = {
    { "goal", &marie_type_goal_t, MARIE_IN, MARIE_PUSH, "GOAL" },
    { "pose", &marie_type_pose_cov_t, MARIE_IN, MARIE_PUSH, "POSE" },
    { "scan", &marie_type_laser_scan_t, MARIE_IN, MARIE_PUSH, "LASER" },
    { "odom", &marie_type_odometry_t, MARIE_IN, MARIE_PUSH, "ODOMETRY" },
    { "map", &marie_type_occupancy_grid_t, MARIE_IN, MARIE_PUSH, "MAP" },
    { "map_update", &marie_type_occupancy_grid_update_t, MARIE_IN, MARIE_PUSH, "MAP_UPDATE" },
    { "replan", &marie_type_goal_t, MARIE_IN, MARIE_PUSH, "REPLAN" },
    { "path", &marie_type_path_t, MARIE_OUT, MARIE_PUSH, "PATH" },
    { 0 },
};

static const marie_param_spec_t params[] = PLN_PARAMS;

static const marie_component_def_t def = {
    .kind = "planner", .ports = ports, .params = params, .params_size = sizeof(pln_params_t), .on_init = init, .on_quit = quit,
};

int main(int argc, char **argv)
{
    pln_t s = { 0 };
    return marie_main(&def, argc, argv, &s);
}
