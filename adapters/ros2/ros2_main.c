/* marie-ros2: the Application Adapter that makes marie and ROS 2 one system: the channels the
 * system file's `ros2:` table names become ROS 2 topics on Cyclone DDS, and back (docs/ros2.md). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "adapters/ros2/ros2_conv.h"
#include "adapters/ros2/ros2_dds.h"
#include "adapters/ros2/ros2_params.h"
#include "adapters/ros2/ros2_table.h"
#include "core/auth.h"
#include "core/clear.h"
#include "core/component.h"
#include "map/occmap.h"
#include "ros2_types.h"

#define ODOM_RING 64

typedef struct {
    const ros2_kind_t *kind;
    marie_port_t *port;
    dds_entity_t dds;               /* writer (to ROS 2) or reader (from ROS 2) */
    const char *topic, *frame, *child;
    int64_t min_gap_us, last_us;
    bool tf;
} entry_t;

typedef struct {
    marie_component_t *c;
    const ros2_params_t *q;
    ros2_dds_t *dds;
    ros2_table_t table;
    entry_t *entries;
    int n;
    dds_entity_t tf, tf_static, map_writer;
    ros2_ctx_t x;
    struct { int64_t utime; double pose[3]; } odom[ODOM_RING];
    int odom_n, odom_head;
    marie_auth_t *auth;
    char sender[160];
    int64_t last_seq;
    int32_t goal_id;
} bridge_t;

static const ros2_params_t *params_of(marie_component_t *c) { return marie_component_params(c); }

static const char *frame_param(const ros2_params_t *q, const char *name)
{
    if (!name)
        return NULL;
    if (!strcmp(name, "map_frame")) return q->map_frame;
    if (!strcmp(name, "odom_frame")) return q->odom_frame;
    if (!strcmp(name, "base_frame")) return q->base_frame;
    if (!strcmp(name, "laser_frame")) return q->laser_frame;
    return q->camera_frame;
}

/* ---- marie -> ROS 2 ---- */

static bool throttled(entry_t *e, int64_t now)
{
    if (e->min_gap_us && e->last_us && now - e->last_us < e->min_gap_us && now >= e->last_us)
        return true;
    e->last_us = now;
    return false;
}

static void remember_odom(bridge_t *b, const marie_odometry_t *m)
{
    b->odom[b->odom_head].utime = m->utime;
    memcpy(b->odom[b->odom_head].pose, (double[3]){m->pose.x, m->pose.y, m->pose.theta}, sizeof b->odom[0].pose);
    b->odom_head = (b->odom_head + 1) % ODOM_RING;
    b->odom_n += b->odom_n < ODOM_RING;
}

/* The odometry pose nearest in time to a pose estimate, for map -> odom. */
static const double *odom_at(const bridge_t *b, int64_t utime)
{
    const double *best = NULL;
    int64_t gap = INT64_MAX;
    for (int i = 0; i < b->odom_n; i++) {
        int64_t d = llabs(b->odom[i].utime - utime);
        if (d < gap)
            gap = d, best = b->odom[i].pose;
    }
    return best;
}

static void write_tf(bridge_t *b, const entry_t *e, const void *msg)
{
    void *tf = NULL;
    const ros2_params_t *q = b->q;
    if (e->kind->marie == &marie_type_odometry_t) {
        const marie_odometry_t *m = msg;
        tf = ros2_tf_one(&b->x, m->utime, e->frame, e->child, m->pose.x, m->pose.y, m->pose.theta);
    } else if (e->kind->marie == &marie_type_pose_cov_t) {
        const marie_pose_cov_t *m = msg;
        const double *o = odom_at(b, m->utime), mp[3] = {m->pose.x, m->pose.y, m->pose.theta};
        double t[3];
        if (!o || (m->frame && strcmp(m->frame, "odom") == 0))
            return;     /* no odometry yet, or an estimate that is not in the map */
        ros2_map_to_odom(mp, o, t);
        tf = ros2_tf_one(&b->x, m->utime, e->frame, q->odom_frame, t[0], t[1], t[2]);
    }
    if (tf && dds_write(b->tf, tf) < 0)
        marie_component_count(b->c, "ros2_write_failed", 1);
}

static void on_marie(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    bridge_t *b = marie_component_user(c);
    if (p == marie_port(c, "odometry"))
        remember_odom(b, msg);
    int64_t now = marie_component_now(c);
    for (int i = 0; i < b->n; i++) {
        entry_t *e = &b->entries[i];
        if (e->port != p || !e->kind->to_ros || throttled(e, now))
            continue;
        ros2_arena_rewind(&b->x.arena);
        b->x.frame = e->frame;
        b->x.child = e->child;
        b->x.now_us = now;
        void *sample = ros2_arena_alloc(&b->x.arena, e->kind->desc->m_size);
        if (!sample || e->kind->to(&b->x, msg, sample) < 0) {
            marie_component_count(c, "ros2_unconvertible", 1);
            continue;
        }
        if (dds_write(e->dds, sample) < 0)
            marie_component_count(c, "ros2_write_failed", 1);
        else
            marie_component_count(c, "to_ros2", 1);
        if (e->tf)
            write_tf(b, e, msg);
    }
}

/* ---- ROS 2 -> marie ---- */

/* Goals from ROS 2 become requests signed inside the bridge, which alone holds the key. */
static int sign_goal(bridge_t *b, marie_goal_request_t *r, uint8_t mac[MARIE_AUTH_MAC_LEN])
{
    int64_t seq = marie_auth_next_seq(NULL);
    b->last_seq = seq > b->last_seq ? seq : b->last_seq + 1;
    r->sender = b->sender;
    r->seq = b->last_seq;
    r->utime = r->goal.utime = marie_wall_us();
    r->goal.id = ++b->goal_id;
    r->goal.priority = (int32_t)b->q->goal_priority;
    r->goal.tolerance = b->q->goal_tolerance;
    return marie_auth_sign_goal_request(b->auth, r, mac);
}

static void from_sample(bridge_t *b, entry_t *e, const void *sample)
{
    marie_component_t *c = b->c;
    ros2_arena_rewind(&b->x.arena);
    b->x.frame = e->frame;
    b->x.now_us = marie_component_now(c);
    b->x.source = e->topic;
    void *msg = ros2_arena_alloc(&b->x.arena, e->kind->marie->size);
    const char *why = "out of memory";
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    if (!msg || e->kind->from(&b->x, sample, msg, &why) < 0) {
        marie_component_bad_input(c, "bad_ros2", "%s: %s", e->topic, why);
        return;
    }
    if (marie_component_state(c) != MARIE_STATE_RUNNING) {
        marie_component_count(c, "ignored_not_running", 1);
        return;
    }
    if (throttled(e, b->x.now_us)) {
        marie_component_count(c, "ros2_rate_limited", 1);
        return;
    }
    if (e->kind->marie == &marie_type_goal_request_t && sign_goal(b, msg, mac) < 0) {
        marie_component_count(c, "request_errors", 1);
        return;
    }
    if (marie_port_publish(e->port, msg) == 0)
        marie_component_count(c, "from_ros2", 1);
}

static void take_all(bridge_t *b, entry_t *e)
{
    void *samples[16] = {NULL};
    dds_sample_info_t infos[16];
    int n;
    while ((n = dds_take(e->dds, samples, infos, 16, 16)) > 0) {
        for (int i = 0; i < n; i++)
            if (infos[i].valid_data)
                from_sample(b, e, samples[i]);
        dds_return_loan(e->dds, samples, n);
    }
}

static void count_refused(bridge_t *b)
{
    uint64_t bad = ros2_dds_take_bad_cdr();
    if (bad)
        marie_component_bad_input(b->c, "bad_cdr", "%llu DDS samples that do not decode as their type",
                                  (unsigned long long)bad);
    char topic[256], type[256];
    uint64_t wrong = ros2_dds_take_wrong_types(b->dds, topic, sizeof topic, type, sizeof type);
    if (wrong)
        marie_component_bad_input(b->c, "wrong_type", "a ROS 2 writer on %s has type %s: not read", topic, type);
}

static void on_dds(marie_loop_t *loop, int fd, short revents, void *user)
{
    bridge_t *b = user;
    ros2_dds_drain(b->dds);
    for (int i = 0; i < b->n; i++)
        if (!b->entries[i].kind->to_ros)
            take_all(b, &b->entries[i]);
    count_refused(b);
}

/* ---- set-up ---- */

static int fail(marie_component_t *c, marie_errors_t *errs, const char *fallback)
{
    marie_component_fail_reason(c, "%s", errs->n ? errs->msgs[0] : fallback);
    marie_errors_clear(errs);
    return -1;
}

/* The kind for an entry: the port of its direction bound to its channel. */
static const ros2_kind_t *kind_for(marie_component_t *c, const ros2_entry_cfg_t *ec, marie_errors_t *errs)
{
    size_t nk;
    const ros2_kind_t *k = ros2_kinds(&nk), *found = NULL;
    bool channel_seen = false;
    for (size_t i = 0; i < nk && !found; i++) {
        if (k[i].to_ros == ec->from_ros || strcmp(marie_port_channel(marie_port(c, k[i].port)), ec->channel) != 0)
            continue;
        channel_seen = true;
        if (!ec->type[0] || strcmp(ec->type, k[i].ros_type) == 0)
            found = &k[i];
    }
    if (!found && channel_seen)
        marie_node_error(errs, ec->node, "ros2 topic: channel %s does not go as %s", ec->channel, ec->type);
    else if (!found)
        marie_node_error(errs, ec->node, "ros2 topic: no port of marie-ros2 %s channel %s (bind one in its ports:)",
                         ec->from_ros ? "writes" : "reads", ec->channel);
    return found;
}

static int open_entry(bridge_t *b, const ros2_entry_cfg_t *ec, entry_t *e, marie_errors_t *errs)
{
    marie_component_t *c = b->c;
    if (!(e->kind = kind_for(c, ec, errs)))
        return -1;
    e->port = marie_port(c, e->kind->port);
    e->topic = ec->topic;
    e->frame = ec->frame ? ec->frame : frame_param(b->q, e->kind->frame);
    e->child = frame_param(b->q, e->kind->child);
    e->min_gap_us = ec->rate_hz > 0 ? (int64_t)(1e6 / ec->rate_hz) : 0;
    e->tf = ec->tf && !ec->from_ros && (e->kind->marie == &marie_type_odometry_t || e->kind->marie == &marie_type_pose_cov_t);
    if (e->kind->marie == &marie_type_goal_request_t && !b->auth) {
        marie_node_error(errs, ec->node, "ros2 topic: goals from ROS 2 are signed requests: set marie-ros2's key_file");
        return -1;
    }
    ros2_qos_t qos = ec->qos >= 0 ? (ros2_qos_t)ec->qos : e->kind->qos;
    e->dds = ec->from_ros ? ros2_dds_reader(b->dds, e->topic, e->kind->desc, qos)
                          : ros2_dds_writer(b->dds, e->topic, e->kind->desc, qos);
    if (e->dds < 0) {
        marie_node_error(errs, ec->node, "ros2 topic %s: %s", e->topic, dds_strretcode(e->dds));
        return -1;
    }
    if (!ec->from_ros && marie_port_on_message(e->port, on_marie) < 0) {
        marie_node_error(errs, ec->node, "ros2 topic %s: cannot subscribe to %s", e->topic, ec->channel);
        return -1;
    }
    return 0;
}

/* REP 105's fixed part: where the laser sits on the base (latched, as robot_state_publisher does). */
static int publish_static(bridge_t *b)
{
    b->tf_static = ros2_dds_writer(b->dds, "/tf_static", &tf2_msgs_msg_dds__TFMessage__desc, ROS2_QOS_LATCHED);
    ros2_arena_rewind(&b->x.arena);
    void *m = ros2_tf_one(&b->x, marie_wall_us(), b->q->base_frame, b->q->laser_frame, b->q->laser_x,
                          b->q->laser_y, b->q->laser_yaw);
    return b->tf_static < 0 || !m || dds_write(b->tf_static, m) < 0 ? -1 : 0;
}

/* A map file on /map, latched, as ROS 2's map_server serves it. */
static int publish_map_file(bridge_t *b)
{
    marie_errors_t errs = {0};
    occmap_t *m = occmap_load(b->q->map, &errs);
    if (!m)
        return fail(b->c, &errs, "map: cannot load");
    marie_occupancy_grid_t g = {marie_component_now(b->c), (float)m->resolution, m->width, m->height,
                                {m->origin_x, m->origin_y, 0}, m->width * m->height, m->cells};
    const ros2_kind_t *k = ros2_kind_find("map", NULL);
    b->map_writer = ros2_dds_writer(b->dds, b->q->map_topic, k->desc, ROS2_QOS_LATCHED);
    ros2_arena_rewind(&b->x.arena);
    b->x.frame = b->q->map_frame;
    void *sample = ros2_arena_alloc(&b->x.arena, k->desc->m_size);
    int rc = b->map_writer < 0 || !sample || k->to(&b->x, &g, sample) < 0 || dds_write(b->map_writer, sample) < 0;
    occmap_destroy(m);
    if (rc) {
        marie_component_fail_reason(b->c, "map: cannot publish on %s", b->q->map_topic);
        return -1;
    }
    return 0;
}

static int load_key(bridge_t *b)
{
    char err[256], host[64] = "";
    if (!b->q->key_file[0])
        return 0;
    if (!(b->auth = marie_auth_load(b->q->key_file, err, sizeof err))) {
        marie_component_fail_reason(b->c, "key_file: %s", err);
        return -1;
    }
    gethostname(host, sizeof host - 1);
    snprintf(b->sender, sizeof b->sender, "%s@%s/ros2", marie_component_name(b->c), host);
    return 0;
}

static void quit(marie_component_t *c)
{
    bridge_t *b = marie_component_user(c);
    if (b->dds)
        marie_loop_remove_fd(marie_component_loop(c), ros2_dds_fd(b->dds));
    MARIE_CLEAR(b->dds, ros2_dds_destroy);
    MARIE_CLEAR(b->auth, marie_auth_destroy);
    free(b->entries);
    b->entries = NULL;
    b->n = 0;
    ros2_table_clear(&b->table);
    ros2_arena_free(&b->x.arena);
}

static int domain_of(const ros2_table_t *t)
{
    const char *env = getenv("ROS_DOMAIN_ID");
    return t->domain_id >= 0 ? t->domain_id : env && *env ? atoi(env) : 0;
}

static int init(marie_component_t *c)
{
    quit(c);    /* init again after a failure starts from scratch */
    bridge_t *b = marie_component_user(c);
    *b = (bridge_t){.c = c, .q = params_of(c), .goal_id = 1000000};
    marie_errors_t errs = {0};
    const marie_system_t *sys = marie_component_system(c);
    char err[256];
    if (load_key(b) < 0 || ros2_table_read(sys ? sys->ros2 : NULL, &b->table, &errs) < 0)
        return errs.n ? fail(c, &errs, "") : -1;
    if (!(b->dds = ros2_dds_create(domain_of(&b->table), err, sizeof err))) {
        marie_component_fail_reason(c, "%s", err);
        return -1;
    }
    b->tf = ros2_dds_writer(b->dds, "/tf", &tf2_msgs_msg_dds__TFMessage__desc, ROS2_QOS_TF);
    if (!(b->entries = calloc(b->table.n ? b->table.n : 1, sizeof *b->entries)))
        return -1;
    for (; b->n < b->table.n; b->n++)
        if (open_entry(b, &b->table.entries[b->n], &b->entries[b->n], &errs) < 0)
            return fail(c, &errs, "ros2 table");
    /* a pose's map -> odom needs the odometry even when no topic carries it */
    if (marie_port_on_message(marie_port(c, "odometry"), on_marie) < 0 || b->tf < 0 || publish_static(b) < 0 ||
        (b->q->map[0] && publish_map_file(b) < 0) ||
        marie_loop_add_fd(marie_component_loop(c), ros2_dds_fd(b->dds), POLLIN, on_dds, b) < 0) {
        marie_component_fail_reason(c, "DDS set-up failed");
        return -1;
    }
    return 0;
}

static const marie_port_spec_t ports[] = {
    {"laser", &marie_type_laser_scan_t, MARIE_IN, MARIE_PUSH, "LASER"},
    {"odometry", &marie_type_odometry_t, MARIE_IN, MARIE_PUSH, "ODOMETRY"},
    {"pose", &marie_type_pose_cov_t, MARIE_IN, MARIE_PUSH, "POSE"},
    {"map", &marie_type_occupancy_grid_t, MARIE_IN, MARIE_PUSH, "MAP"},
    {"path", &marie_type_path_t, MARIE_IN, MARIE_PUSH, "PATH"},
    {"motor", &marie_type_motor_command_t, MARIE_IN, MARIE_PUSH, "MOTOR_COMMAND"},
    {"estop", &marie_type_estop_t, MARIE_IN, MARIE_PUSH, "ESTOP"},
    {"camera", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "CAMERA_IMAGE"},
    {"clock", &marie_type_sim_clock_t, MARIE_IN, MARIE_PUSH, "MARIE_CLOCK"},
    {"heartbeat", &marie_type_heartbeat_t, MARIE_IN, MARIE_PUSH, "MARIE_HEARTBEAT"},
    {"ros_scan", &marie_type_laser_scan_t, MARIE_OUT, MARIE_PUSH, "ROS2_SCAN"},
    {"ros_odom", &marie_type_odometry_t, MARIE_OUT, MARIE_PUSH, "ROS2_ODOM"},
    {"ros_initialpose", &marie_type_pose_cov_t, MARIE_OUT, MARIE_PUSH, "INITIALPOSE"},
    {"ros_map", &marie_type_occupancy_grid_t, MARIE_OUT, MARIE_PUSH, "ROS2_MAP"},
    {"ros_path", &marie_type_path_t, MARIE_OUT, MARIE_PUSH, "ROS2_PATH"},
    {"ros_cmd_vel", &marie_type_motor_command_t, MARIE_OUT, MARIE_PUSH, "TELEOP"},
    {"ros_goal", &marie_type_goal_request_t, MARIE_OUT, MARIE_PUSH, "GOAL_REQUEST"},
    {"ros_estop", &marie_type_estop_t, MARIE_OUT, MARIE_PUSH, "ROS2_ESTOP"},
    {"ros_camera", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "ROS2_CAMERA"},
    {0},
};
static const marie_param_spec_t params[] = ROS2_PARAMS;
static const marie_component_def_t def = {
    .kind = "ros2", .ports = ports, .params = params, .params_size = sizeof(ros2_params_t),
    .on_init = init, .on_quit = quit,
};

int main(int argc, char **argv)
{
    bridge_t b = {0};
    return marie_main(&def, argc, argv, &b);
}
