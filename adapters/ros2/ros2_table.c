/* ros2_table: reads the system file's `ros2:` table. */
#include "adapters/ros2/ros2_table.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static int read_qos(const marie_node_t *v, int *qos, marie_errors_t *errs)
{
    static const char *const names[] = {[ROS2_QOS_SENSOR] = "sensor", [ROS2_QOS_DEFAULT] = "default",
                                        [ROS2_QOS_LATCHED] = "latched"};
    const char *s;
    if (marie_node_str(v, &s, errs) < 0)
        return -1;
    for (int i = 0; i < 3; i++)
        if (strcmp(s, names[i]) == 0)
            return *qos = i, 0;
    marie_node_error(errs, v, "qos: sensor, default or latched, not '%s'", s);
    return -1;
}

static int read_entry(const marie_node_t *n, ros2_entry_cfg_t *e, marie_errors_t *errs)
{
    static const char *const keys[] = {"channel", "topic", "direction", "type", "rate_hz", "frame", "qos", "tf", NULL};
    *e = (ros2_entry_cfg_t){.type = "", .qos = -1, .tf = true, .node = n};
    if (n->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, n, "ros2 topic: expected a mapping such as {channel: LASER, topic: /scan}");
        return -1;
    }
    const marie_node_t *v;
    const char *dir = "to_ros";
    if (marie_node_check_keys(n, keys, "ros2 topic", errs) < 0)
        return -1;
    if (!marie_node_get(n, "channel") || !marie_node_get(n, "topic")) {
        marie_node_error(errs, n, "ros2 topic: channel and topic are required");
        return -1;
    }
    if (marie_node_str(marie_node_get(n, "channel"), &e->channel, errs) < 0 ||
        marie_node_str(marie_node_get(n, "topic"), &e->topic, errs) < 0 ||
        ((v = marie_node_get(n, "direction")) && marie_node_str(v, &dir, errs) < 0) ||
        ((v = marie_node_get(n, "type")) && marie_node_str(v, &e->type, errs) < 0) ||
        ((v = marie_node_get(n, "rate_hz")) && marie_node_double(v, &e->rate_hz, errs) < 0) ||
        ((v = marie_node_get(n, "frame")) && marie_node_str(v, &e->frame, errs) < 0) ||
        ((v = marie_node_get(n, "qos")) && read_qos(v, &e->qos, errs) < 0) ||
        ((v = marie_node_get(n, "tf")) && marie_node_bool(v, &e->tf, errs) < 0))
        return -1;
    char dds[256];
    if (ros2_dds_topic_name(e->topic, dds, sizeof dds) < 0) {
        marie_node_error(errs, marie_node_get(n, "topic"), "topic '%s' is not a ROS 2 name (such as /scan)", e->topic);
        return -1;
    }
    if (strcmp(dir, "to_ros") != 0 && strcmp(dir, "from_ros") != 0) {
        marie_node_error(errs, marie_node_get(n, "direction"), "direction: to_ros or from_ros, not '%s'", dir);
        return -1;
    }
    e->from_ros = dir[0] == 'f';
    if (e->rate_hz < 0 || e->rate_hz > 100000) {
        marie_node_error(errs, marie_node_get(n, "rate_hz"), "rate_hz: 0 (every message) to 100000");
        return -1;
    }
    return 0;
}

/* The same ROS 2 topic both ways would feed the bridge its own output. */
static int check_pairs(const ros2_table_t *t, marie_errors_t *errs)
{
    for (int i = 0; i < t->n; i++)
        for (int k = 0; k < i; k++) {
            char a[256], b[256];
            ros2_dds_topic_name(t->entries[i].topic, a, sizeof a);
            ros2_dds_topic_name(t->entries[k].topic, b, sizeof b);
            bool same_topic = strcmp(a, b) == 0, same_channel = strcmp(t->entries[i].channel, t->entries[k].channel) == 0;
            if ((same_topic || same_channel) && t->entries[i].from_ros != t->entries[k].from_ros) {
                marie_node_error(errs, t->entries[i].node, "ros2 topic: %s '%s' goes both ways (line %d): a loop",
                                 same_topic ? "topic" : "channel", same_topic ? t->entries[i].topic : t->entries[i].channel,
                                 t->entries[k].node->line);
                return -1;
            }
            if (same_topic && !t->entries[i].from_ros) {
                marie_node_error(errs, t->entries[i].node, "ros2 topic: '%s' already has a writer (line %d)",
                                 t->entries[i].topic, t->entries[k].node->line);
                return -1;
            }
        }
    return 0;
}

int ros2_table_read(const marie_node_t *n, ros2_table_t *t, marie_errors_t *errs)
{
    *t = (ros2_table_t){.domain_id = -1};
    if (!n)
        return 0;
    static const char *const keys[] = {"domain_id", "topics", NULL};
    const marie_node_t *v, *topics = marie_node_get(n, "topics");
    int64_t dom;
    if (marie_node_check_keys(n, keys, "ros2", errs) < 0)
        return -1;
    if ((v = marie_node_get(n, "domain_id"))) {
        if (marie_node_int(v, &dom, errs) < 0)
            return -1;
        if (dom < 0 || dom > 232) {
            marie_node_error(errs, v, "ros2 domain_id: 0 to 232 (ROS 2's range)");
            return -1;
        }
        t->domain_id = (int)dom;
    }
    if (!topics)
        return 0;
    if (topics->kind != MARIE_NODE_SEQ) {
        marie_node_error(errs, topics, "ros2 topics: expected a list of {channel, topic, ...}");
        return -1;
    }
    if (!(t->entries = calloc(topics->n ? topics->n : 1, sizeof *t->entries)))
        return -1;
    for (size_t i = 0; i < topics->n; i++) {
        if (read_entry(topics->items[i], &t->entries[t->n], errs) < 0) {
            ros2_table_clear(t);
            return -1;
        }
        t->n++;
    }
    if (check_pairs(t, errs) < 0) {
        ros2_table_clear(t);
        return -1;
    }
    return 0;
}

void ros2_table_clear(ros2_table_t *t)
{
    free(t->entries);
    *t = (ros2_table_t){.domain_id = -1};
}
