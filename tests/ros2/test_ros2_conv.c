/* test_ros2_conv: marie-ros2's conversions and its `ros2:` table, without DDS: REP 103/105/117
 * as a ROS 2 node reads them, what comes back, and the table's errors at their positions. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include <cmocka.h>

#include "adapters/ros2/ros2_conv.h"
#include "adapters/ros2/ros2_table.h"
#include "ros2_types.h"
#include "tests/proc.h"

static ros2_ctx_t ctx(const char *frame)
{
    return (ros2_ctx_t){.frame = frame, .child = "base_link", .source = "/test", .now_us = 5000000};
}

static void scan_no_return_is_inf_and_comes_back_as_range_max(void **state)
{
    float r[4] = {1.0f, 8.0f, 9.5f, 0.05f};
    marie_laser_scan_t m = {1500000, -1.0f, 0.5f, 0.1f, 8.0f, 4, r, 0, NULL};
    ros2_ctx_t x = ctx("laser");
    sensor_msgs_msg_dds__LaserScan_ s = {0};
    assert_int_equal(ros2_kind_find("laser", NULL)->to(&x, &m, &s), 0);
    assert_string_equal(s.header.frame_id, "laser");
    assert_int_equal(s.header.stamp.sec, 1);
    assert_int_equal(s.header.stamp.nanosec, 500000000);
    assert_true(s.ranges._buffer[0] == 1.0f && isinf(s.ranges._buffer[1]) && isinf(s.ranges._buffer[2]));
    assert_float_equal(s.angle_max, 0.5, 1e-6);
    marie_laser_scan_t back;
    const char *why;
    s.ranges._buffer[3] = NAN;
    assert_int_equal(ros2_kind_find("ros_scan", NULL)->from(&x, &s, &back, &why), 0);
    assert_true(back.ranges[1] == 8.0f && back.ranges[2] == 8.0f && back.ranges[3] == 8.0f);
    assert_int_equal(back.utime, 1500000);
    ros2_arena_free(&x.arena);
}

static void odometry_covariance_lands_on_x_y_yaw(void **state)
{
    marie_odometry_t m = {.utime = 10, .pose = {1, 2, M_PI / 2}, .v = 0.5, .omega = -0.1};
    for (int i = 0; i < 9; i++)
        m.cov[i] = i + 1;
    ros2_ctx_t x = ctx("odom");
    nav_msgs_msg_dds__Odometry_ o = {0};
    assert_int_equal(ros2_kind_find("odometry", NULL)->to(&x, &m, &o), 0);
    assert_string_equal(o.child_frame_id, "base_link");
    assert_float_equal(o.pose.covariance[0], 1, 0);
    assert_float_equal(o.pose.covariance[5], 3, 0);       /* x-yaw */
    assert_float_equal(o.pose.covariance[35], 9, 0);      /* yaw-yaw */
    assert_float_equal(o.pose.covariance[14], 0, 0);      /* z-z: not a planar robot's */
    assert_float_equal(o.pose.pose.orientation.z, sin(M_PI / 4), 1e-12);
    marie_odometry_t back;
    const char *why;
    assert_int_equal(ros2_kind_find("ros_odom", NULL)->from(&x, &o, &back, &why), 0);
    assert_float_equal(back.pose.theta, M_PI / 2, 1e-12);
    assert_memory_equal(back.cov, m.cov, sizeof m.cov);
    o.header.frame_id = "map";
    assert_int_equal(ros2_kind_find("ros_odom", NULL)->from(&x, &o, &back, &why), -1);
    ros2_arena_free(&x.arena);
}

static void map_to_odom_composes_back_to_the_pose(void **state)
{
    double map_pose[3] = {10, 5, 1.0}, odom_pose[3] = {2, -1, 0.3}, t[3];
    ros2_map_to_odom(map_pose, odom_pose, t);
    /* T_map_odom * T_odom_base == T_map_base */
    double c = cos(t[2]), s = sin(t[2]);
    assert_float_equal(t[0] + c * odom_pose[0] - s * odom_pose[1], map_pose[0], 1e-12);
    assert_float_equal(t[1] + s * odom_pose[0] + c * odom_pose[1], map_pose[1], 1e-12);
    assert_float_equal(t[2] + odom_pose[2], map_pose[2], 1e-12);
    assert_true(isnan(ros2_yaw(0, 0, 0, 0)));
    assert_float_equal(ros2_yaw(0, 0, 2 * sin(0.25), 2 * cos(0.25)), 0.5, 1e-12);  /* not normalized */
}

static void bad_input_from_ros2_is_refused(void **state)
{
    ros2_ctx_t x = ctx("map");
    const char *why = NULL;
    geometry_msgs_msg_dds__Twist_ t = {.linear = {NAN, 0, 0}};
    marie_motor_command_t mc;
    assert_int_equal(ros2_kind_find("ros_cmd_vel", NULL)->from(&x, &t, &mc, &why), -1);
    int8_t cells[5] = {0, 100, -1, 0, 0};
    nav_msgs_msg_dds__OccupancyGrid_ g = {.header = {.frame_id = "map"}, .info = {.resolution = 0.05f, .width = 3,
                                          .height = 2, .origin = {.orientation = {.w = 1}}},
                                          .data = {5, 5, cells, false}};
    marie_occupancy_grid_t mg;
    assert_int_equal(ros2_kind_find("ros_map", NULL)->from(&x, &g, &mg, &why), -1);   /* 3x2 is not 5 */
    g.info.width = 5, g.info.height = 1;
    assert_int_equal(ros2_kind_find("ros_map", NULL)->from(&x, &g, &mg, &why), 0);
    cells[2] = 101;
    assert_int_equal(ros2_kind_find("ros_map", NULL)->from(&x, &g, &mg, &why), -1);
    geometry_msgs_msg_dds__PoseStamped_ p = {.header = {.frame_id = "odom"}, .pose = {.orientation = {.w = 1}}};
    marie_goal_request_t gr;
    assert_int_equal(ros2_kind_find("ros_goal", NULL)->from(&x, &p, &gr, &why), -1);
    p.header.frame_id = "map";
    assert_int_equal(ros2_kind_find("ros_goal", NULL)->from(&x, &p, &gr, &why), 0);
    uint8_t px[12] = {0};
    sensor_msgs_msg_dds__Image_ im = {.height = 2, .width = 2, .encoding = "rgb8", .step = 6, .data = {11, 11, px, false}};
    marie_image_t mi;
    assert_int_equal(ros2_kind_find("ros_camera", NULL)->from(&x, &im, &mi, &why), -1);   /* 6 x 2 > 11 */
    ros2_arena_free(&x.arena);
}

static void table_errors_name_their_position(void **state)
{
    static const char text[] =
        "ros2:\n"
        "  topics:\n"
        "    - {channel: LASER, topic: /scan}\n"
        "    - {channel: TELEOP, topic: /scan, direction: from_ros}\n";
    char path[] = "/tmp/test_ros2_conv_XXXXXX.yaml", where[80];
    assert_int_equal(test_write_temp(path, 5, text), 0);
    snprintf(where, sizeof where, "%s:4:7:", path);
    marie_errors_t errs = {0};
    marie_doc_t *doc = marie_doc_load(path, &errs);
    assert_non_null(doc);
    ros2_table_t t;
    assert_int_equal(ros2_table_read(marie_node_get(marie_doc_root(doc), "ros2"), &t, &errs), -1);
    assert_true(errs.n >= 1 && strstr(errs.msgs[0], where) && strstr(errs.msgs[0], "loop"));
    marie_errors_clear(&errs);
    marie_doc_destroy(doc);
    remove(path);
    char name[64];
    assert_int_equal(ros2_dds_topic_name("/a/b_c", name, sizeof name), 0);
    assert_string_equal(name, "rt/a/b_c");
    assert_int_equal(ros2_dds_topic_name("/a//b", name, sizeof name), -1);
    assert_int_equal(ros2_dds_topic_name("/2d", name, sizeof name), -1);
    assert_int_equal(ros2_dds_topic_name("/scan/", name, sizeof name), -1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(scan_no_return_is_inf_and_comes_back_as_range_max),
        cmocka_unit_test(odometry_covariance_lands_on_x_y_yaw),
        cmocka_unit_test(map_to_odom_composes_back_to_the_pose),
        cmocka_unit_test(bad_input_from_ros2_is_refused),
        cmocka_unit_test(table_errors_name_their_position),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
