/* ros2_dds: the DDS side of marie-ros2: a Cyclone DDS participant on ROS 2's conventions (topic
 * rt/NAME, ROS_DOMAIN_ID, ROS 2's QoS per kind of data) with a wake-up fd for the marie loop. */
#ifndef ROS2_DDS_H
#define ROS2_DDS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <dds/dds.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ROS 2's QoS profiles as its nodes use them (rmw_qos_profile_*, rclcpp's presets). */
typedef enum {
    ROS2_QOS_SENSOR,    /* sensor data: best effort, keep last 5, volatile */
    ROS2_QOS_DEFAULT,   /* commands and the rest: reliable, keep last 10, volatile */
    ROS2_QOS_LATCHED,   /* /map, /tf_static: reliable, keep last 1, transient local */
    ROS2_QOS_TF,        /* /tf: reliable, keep last 100, volatile (tf2's broadcaster) */
    ROS2_QOS_CLOCK,     /* /clock: best effort, keep last 1 (rclcpp::ClockQoS) */
} ros2_qos_t;

typedef struct ros2_dds ros2_dds_t;

/* A participant on domain_id (0-232). NULL with a reason in err. */
ros2_dds_t *ros2_dds_create(int domain_id, char *err, size_t errlen);
void ros2_dds_destroy(ros2_dds_t *d);           /* NULL is a no-op; deletes every entity */

/* Readable when a reader may hold samples (a listener on Cyclone's thread writes it); the loop
 * then calls ros2_dds_drain and takes from its readers. */
int ros2_dds_fd(const ros2_dds_t *d);
void ros2_dds_drain(ros2_dds_t *d);

/* "/scan" or "scan" -> "rt/scan"; 0, or -1 (EINVAL) for a name ROS 2 would refuse. */
int ros2_dds_topic_name(const char *ros_name, char *out, size_t len);

/* A writer or reader of ros_name (a ROS 2 name) with desc's type; readers ignore this
 * participant's own writers and wake ros2_dds_fd. A negative DDS return code on failure. */
dds_entity_t ros2_dds_writer(ros2_dds_t *d, const char *ros_name, const dds_topic_descriptor_t *desc, ros2_qos_t q);
dds_entity_t ros2_dds_reader(ros2_dds_t *d, const char *ros_name, const dds_topic_descriptor_t *desc, ros2_qos_t q);

/* Samples Cyclone refused to deserialize (malformed CDR, lying lengths) since the last call:
 * counted from its warnings, for every participant of this process. */
uint64_t ros2_dds_take_bad_cdr(void);

/* Remote writers seen on one of the readers' topics under another type name since the last
 * call (a wrong type under a known name); *topic says the last one. */
uint64_t ros2_dds_take_wrong_types(ros2_dds_t *d, char *topic, size_t len, char *type, size_t tlen);

#ifdef __cplusplus
}
#endif
#endif
