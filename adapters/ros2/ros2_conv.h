/* ros2_conv: marie's types <-> ROS 2 messages, one table keyed by marie type and port, following
 * REP 103 (SI units, x forward, counter-clockwise yaw) and REP 105 (map -> odom -> base_link). */
#ifndef ROS2_CONV_H
#define ROS2_CONV_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <dds/dds.h>

#include "adapters/ros2/ros2_dds.h"
#include "lcmtypes/marie_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Memory a conversion points its output into; rewound before each conversion. */
typedef struct ros2_arena_chunk ros2_arena_chunk_t;
typedef struct {
    ros2_arena_chunk_t *head;
} ros2_arena_t;
void *ros2_arena_alloc(ros2_arena_t *a, size_t n);      /* zeroed, 16-aligned; NULL when out of memory */
void ros2_arena_rewind(ros2_arena_t *a);                /* keeps the largest chunk */
void ros2_arena_free(ros2_arena_t *a);

typedef struct {
    const char *frame;          /* header.frame_id to write, or the frame a message must be in */
    const char *child;          /* child_frame_id (odometry) */
    const char *source;         /* what marie messages made from ROS 2 say they come from */
    int64_t now_us;             /* stamp for a ROS 2 message without one */
    ros2_arena_t arena;
} ros2_ctx_t;

/* One way of carrying a marie type over one of the bridge's ports. to_ros fills a ROS sample
 * (its sequences and strings point into the marie message or the arena) and returns 0, or -1
 * when this message cannot go on this topic (a JPEG frame on an Image topic). from_ros fills a
 * marie message (pointing into the sample or the arena) and returns 0, or -1 with *why when the
 * sample is bad input (not finite, inconsistent sizes, another frame). */
typedef struct {
    const char *port;                   /* the bridge's port (an input for to_ros) */
    const marie_type_t *marie;
    const char *ros_type;               /* "sensor_msgs/msg/LaserScan" */
    const dds_topic_descriptor_t *desc;
    ros2_qos_t qos;
    bool to_ros;
    const char *frame, *child;          /* default frames: parameter names (laser_frame, ...) */
    int (*to)(ros2_ctx_t *x, const void *marie_msg, void *ros_sample);
    int (*from)(ros2_ctx_t *x, const void *ros_sample, void *marie_msg, const char **why);
} ros2_kind_t;

/* The kind for a port and a ROS 2 type ("" or NULL: the port's first kind); NULL if none. */
const ros2_kind_t *ros2_kind_find(const char *port, const char *ros_type);
const ros2_kind_t *ros2_kinds(size_t *n);

/* Transforms and the stamps every conversion uses, for the bridge's /tf. */
int64_t ros2_utime(int32_t sec, uint32_t nanosec);
double ros2_yaw(double x, double y, double z, double w);    /* NAN for a quaternion of no length */
/* map -> odom from the robot's pose in the map and in the odometry frame at the same instant. */
void ros2_map_to_odom(const double map_pose[3], const double odom_pose[3], double out[3]);
/* A TFMessage of one transform parent -> child at (x, y, yaw), in the arena. NULL when out of memory. */
void *ros2_tf_one(ros2_ctx_t *x, int64_t utime, const char *parent, const char *child, double px, double py,
                  double yaw);

#ifdef __cplusplus
}
#endif
#endif
