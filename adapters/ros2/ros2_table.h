/* ros2_table: the system file's `ros2:` table (which channel goes to which ROS 2 topic, which
 * way, how often), read with the position of every entry for its errors. */
#ifndef ROS2_TABLE_H
#define ROS2_TABLE_H

#include <stdbool.h>

#include "adapters/ros2/ros2_dds.h"
#include "core/config.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    const char *channel, *topic;
    bool from_ros;              /* direction: from_ros (into marie) or to_ros (the default) */
    const char *type;           /* a ROS 2 type where a channel has several ("" otherwise) */
    double rate_hz;             /* at most this often (0: every message) */
    const char *frame;          /* header.frame_id in place of the parameter's (NULL: that) */
    int qos;                    /* a ros2_qos_t in place of the kind's, or -1 */
    bool tf;                    /* odometry and poses: also their transform on /tf */
    const marie_node_t *node;   /* for errors at its position */
} ros2_entry_cfg_t;

typedef struct {
    int domain_id;              /* -1: ROS_DOMAIN_ID, else 0 */
    ros2_entry_cfg_t *entries;
    int n;
} ros2_table_t;

/* Read `ros2:` (n may be NULL: an empty table). -1 with file:line:col reasons in errs. The
 * strings point into the node, which must outlive the table. */
int ros2_table_read(const marie_node_t *n, ros2_table_t *t, marie_errors_t *errs);
void ros2_table_clear(ros2_table_t *t);

#ifdef __cplusplus
}
#endif
#endif
