/* marie-explore: the explore mission: sends the planner to the cheapest reachable frontier of the
 * live map until none is left, giving up on goals the planner cannot reach or the robot does not
 * reach in time. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "map/livemap.h"
#include "adapters/mission/explore.h"
#include "adapters/mission/explore_main_params.h"
#include "core/clear.h"
#include "core/component.h"
#include "map/occmap.h"

#define MAX_BLACK 256

typedef struct {
    livemap_t live;             /* the map from the bus (MAP, MAP_UPDATE) */
    occmap_t *map;              /* the same for explore_frontiers */
    double pose[3];
    bool have_pose, have_goal, done;
    double goal[2];
    int32_t goal_id;
    int64_t goal_since, last_choice, empty_since;
    double black[2 * MAX_BLACK];
    int nblack;
} exp_t;

/* explore_frontiers works on an occmap: made again from the live map when it changes. */
static void use_live_map(exp_t *s)
{
    occmap_t *om = livemap_occmap(&s->live);
    if (om) {
        occmap_destroy(s->map);
        s->map = om;
    }
}

static void on_map(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    exp_t *s = marie_component_user(c);
    if (livemap_take_full(&s->live, c, msg)) {
        use_live_map(s);
        marie_component_count(c, "maps", 1);
    }
}

static void on_map_update(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    exp_t *s = marie_component_user(c);
    if (livemap_take_update(&s->live, c, msg))
        use_live_map(s);
}

static void on_pose(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    exp_t *s = marie_component_user(c);
    const marie_pose_cov_t *m = msg;
    s->pose[0] = m->pose.x;
    s->pose[1] = m->pose.y;
    s->pose[2] = m->pose.theta;
    s->have_pose = true;
}

static void give_up(marie_component_t *c, exp_t *s, const char *why)
{
    if (s->nblack < MAX_BLACK) {
        s->black[2 * s->nblack] = s->goal[0];
        s->black[2 * s->nblack + 1] = s->goal[1];
        s->nblack++;
    }
    marie_component_count(c, "goals_given_up", 1);
    marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "frontier_given_up", "frontier (%.2f, %.2f) given up: %s",
                          s->goal[0], s->goal[1], why);
    s->have_goal = false;
}

static void on_path(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    exp_t *s = marie_component_user(c);
    const marie_path_t *m = msg;
    if (s->have_goal && m->goal_id == s->goal_id && m->status != MARIE_PATH_T_STATUS_OK)
        give_up(c, s, "the planner has no path");
}

static void send_goal(marie_component_t *c, exp_t *s)
{
    const exp_params_t *q = marie_component_params(c);
    char name[32];
    snprintf(name, sizeof(name), "frontier-%d", s->goal_id);
    marie_goal_t g = { .utime = marie_component_now(c), .id = s->goal_id, .name = name,
                       .pose = { s->goal[0], s->goal[1], 0 }, .tolerance = q->tolerance };
    marie_port_publish(marie_port(c, "goal"), &g);
}

static void tick(marie_component_t *c, int64_t overruns)
{
    exp_t *s = marie_component_user(c);
    const exp_params_t *q = marie_component_params(c);
    int64_t now = marie_component_now(c);
    if (!s->map || !s->have_pose || s->done)
        return;
    if (s->have_goal && hypot(s->goal[0] - s->pose[0], s->goal[1] - s->pose[1]) < q->tolerance) {
        marie_component_count(c, "frontiers_reached", 1);
        s->have_goal = false;
    }
    if (s->have_goal && (double)(now - s->goal_since) / 1e6 > q->goal_timeout_s)
        give_up(c, s, "not reached in time");
    if (s->have_goal && (double)(now - s->last_choice) / 1e6 < q->replan_s) {
        send_goal(c, s);
        return;
    }
    explore_frontier_t f[1];
    int n = explore_frontiers(s->map, &q->explore, s->pose[0], s->pose[1], s->black, s->nblack, f, 1);
    s->last_choice = now;
    if (n < 0)
        return;
    if (n == 0) {
        /* A map a moment old may not show what the last goal uncovered: done only when it stays so. */
        if (!s->empty_since)
            s->empty_since = now;
        if ((double)(now - s->empty_since) / 1e6 >= q->done_after_s) {
            s->done = true;
            s->have_goal = false;
            marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "explore_done",
                                  "no reachable frontier left (%d given up)", s->nblack);
        }
        return;
    }
    s->empty_since = 0;
    bool same = s->have_goal && hypot(f[0].x - s->goal[0], f[0].y - s->goal[1]) < 0.5;
    if (!same) {
        s->goal[0] = f[0].x;
        s->goal[1] = f[0].y;
        s->goal_id++;
        s->goal_since = now;
        s->have_goal = true;
        marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "frontier_goal", "frontier %d at (%.2f, %.2f): %d cells, %.1f m away",
                              s->goal_id, f[0].x, f[0].y, f[0].cells, f[0].path_m);
    }
    send_goal(c, s);
}

static void quit(marie_component_t *c)
{
    exp_t *s = marie_component_user(c);
    MARIE_CLEAR(s->map, occmap_destroy);
    livemap_free(&s->live);
}

static int init(marie_component_t *c)
{
    exp_t *s = marie_component_user(c);
    const exp_params_t *q = marie_component_params(c);
    quit(c);
    memset(s, 0, sizeof(*s));
    if (!(q->rate_hz > 0 && q->rate_hz <= 100) || !(q->explore.robot_radius >= 0) || !(q->tolerance > 0)) {
        marie_component_fail_reason(c, "rate_hz in (0, 100], robot_radius >= 0 and tolerance > 0 expected");
        return -1;
    }
    if (marie_port_on_message(marie_port(c, "map"), on_map) ||
        marie_port_on_message(marie_port(c, "map_update"), on_map_update) || marie_port_on_message(marie_port(c, "pose"), on_pose) ||
        marie_port_on_message(marie_port(c, "path"), on_path)) {
        marie_component_fail_reason(c, "cannot subscribe to inputs");
        return -1;
    }
    return marie_component_every(c, q->rate_hz, tick) ? 0 : -1;
}

static const marie_port_spec_t ports[] = {
    { "map", &marie_type_occupancy_grid_t, MARIE_IN, MARIE_PUSH, "MAP" },
    { "map_update", &marie_type_occupancy_grid_update_t, MARIE_IN, MARIE_PUSH, "MAP_UPDATE" },
    { "pose", &marie_type_pose_cov_t, MARIE_IN, MARIE_PUSH, "POSE" },
    { "path", &marie_type_path_t, MARIE_IN, MARIE_PUSH, "PATH" },
    { "goal", &marie_type_goal_t, MARIE_OUT, MARIE_PUSH, "GOAL" },
    { 0 },
};

static const marie_param_spec_t params[] = EXP_PARAMS;

static const marie_component_def_t def = {
    .kind = "explore", .ports = ports, .params = params, .params_size = sizeof(exp_params_t),
    .on_init = init, .on_quit = quit,
};

int main(int argc, char **argv)
{
    exp_t s = { 0 };
    return marie_main(&def, argc, argv, &s);
}
