/* ros2_conv: the conversions of marie's messages to and from ROS 2's, one table keyed by port. */
#include "adapters/ros2/ros2_conv.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ros2_types.h"

/* ---- arena ---- */

struct ros2_arena_chunk {
    ros2_arena_chunk_t *next;
    size_t size, used;
    _Alignas(16) unsigned char data[];
};

void *ros2_arena_alloc(ros2_arena_t *a, size_t n)
{
    n = (n + 15) & ~(size_t)15;
    ros2_arena_chunk_t *h = a->head;
    if (!h || h->size - h->used < n) {
        size_t size = n > 65536 ? n : 65536;
        if (!(h = malloc(sizeof *h + size)))
            return NULL;
        *h = (ros2_arena_chunk_t){a->head, size, 0};
        a->head = h;
    }
    void *p = h->data + h->used;
    h->used += n;
    return memset(p, 0, n);
}

void ros2_arena_rewind(ros2_arena_t *a)
{
    ros2_arena_chunk_t *keep = NULL;
    for (ros2_arena_chunk_t *h = a->head, *next; h; h = next) {
        next = h->next;
        if (!keep || h->size > keep->size) {
            free(keep);
            keep = h;
        } else {
            free(h);
        }
    }
    if (keep)
        *keep = (ros2_arena_chunk_t){NULL, keep->size, 0};
    a->head = keep;
}

void ros2_arena_free(ros2_arena_t *a)
{
    ros2_arena_rewind(a);
    free(a->head);
    a->head = NULL;
}

/* ---- shared pieces ---- */

static void ros2_stamp(int64_t utime, int32_t *sec, uint32_t *nanosec)
{
    int64_t s = utime >= 0 ? utime / 1000000 : -((-utime + 999999) / 1000000);
    *sec = (int32_t)s;
    *nanosec = (uint32_t)((utime - s * 1000000) * 1000);
}

int64_t ros2_utime(int32_t sec, uint32_t nanosec) { return (int64_t)sec * 1000000 + nanosec / 1000; }

double ros2_yaw(double x, double y, double z, double w)
{
    double n = x * x + y * y + z * z + w * w;
    if (!(n > 1e-12) || !isfinite(n))
        return NAN;
    return atan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z);   /* needs no normalizing */
}

static void yaw_quat(double yaw, geometry_msgs_msg_dds__Quaternion_ *q)
{
    *q = (geometry_msgs_msg_dds__Quaternion_){0, 0, sin(yaw / 2), cos(yaw / 2)};
}

void ros2_map_to_odom(const double m[3], const double o[3], double out[3])
{
    /* T_map_odom = T_map_base * inverse(T_odom_base) */
    double th = m[2] - o[2], c = cos(th), s = sin(th);
    out[0] = m[0] - (c * o[0] - s * o[1]);
    out[1] = m[1] - (s * o[0] + c * o[1]);
    out[2] = atan2(sin(th), cos(th));
}

static void header(std_msgs_msg_dds__Header_ *h, int64_t utime, const char *frame)
{
    ros2_stamp(utime, &h->stamp.sec, &h->stamp.nanosec);
    h->frame_id = (char *)frame;
}

static int64_t stamp_of(const ros2_ctx_t *x, const std_msgs_msg_dds__Header_ *h)
{
    int64_t t = ros2_utime(h->stamp.sec, h->stamp.nanosec);
    return t > 0 ? t : x->now_us;
}

/* covariance over (x, y, yaw) <-> ROS 2's 6x6 over (x, y, z, roll, pitch, yaw) */
static const int cov6[3] = {0, 1, 5};
static void cov_to_ros(const double in[9], double out[36])
{
    memset(out, 0, 36 * sizeof *out);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            out[cov6[i] * 6 + cov6[j]] = in[i * 3 + j];
}
static bool cov_from_ros(const double in[36], double out[9])
{
    for (int i = 0; i < 36; i++)
        if (!isfinite(in[i]))
            return false;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            out[i * 3 + j] = in[cov6[i] * 6 + cov6[j]];
    return true;
}

static void pose_to_ros(const marie_pose2d_t *p, geometry_msgs_msg_dds__Pose_ *o)
{
    o->position = (geometry_msgs_msg_dds__Point_){p->x, p->y, 0};
    yaw_quat(p->theta, &o->orientation);
}

static bool pose_from_ros(const geometry_msgs_msg_dds__Pose_ *o, marie_pose2d_t *p)
{
    const geometry_msgs_msg_dds__Quaternion_ *q = &o->orientation;
    p->x = o->position.x;
    p->y = o->position.y;
    p->theta = ros2_yaw(q->x, q->y, q->z, q->w);
    return isfinite(p->x) && isfinite(p->y) && isfinite(p->theta) && isfinite(o->position.z);
}

static bool frame_ok(const ros2_ctx_t *x, const char *frame) { return !x->frame || strcmp(frame, x->frame) == 0; }

#define FAIL(reason) do { *why = reason; return -1; } while (0)

void *ros2_tf_one(ros2_ctx_t *x, int64_t utime, const char *parent, const char *child, double px, double py, double yaw)
{
    tf2_msgs_msg_dds__TFMessage_ *m = ros2_arena_alloc(&x->arena, sizeof *m);
    geometry_msgs_msg_dds__TransformStamped_ *t = ros2_arena_alloc(&x->arena, sizeof *t);
    if (!m || !t)
        return NULL;
    header(&t->header, utime, parent);
    t->child_frame_id = (char *)child;
    t->transform.translation = (geometry_msgs_msg_dds__Vector3_){px, py, 0};
    yaw_quat(yaw, &t->transform.rotation);
    m->transforms = (dds_sequence_geometry_msgs_msg_dds__TransformStamped_){1, 1, t, false};
    return m;
}

/* ---- LaserScan: marie's "at or beyond range_max" is ROS 2's +inf (REP 117) ---- */

static int laser_to(ros2_ctx_t *x, const void *in, void *out)
{
    const marie_laser_scan_t *m = in;
    sensor_msgs_msg_dds__LaserScan_ *r = out;
    float *ranges = ros2_arena_alloc(&x->arena, (size_t)m->nranges * sizeof *ranges + 1);
    if (!ranges)
        return -1;
    for (int i = 0; i < m->nranges; i++)
        ranges[i] = m->ranges[i] >= m->range_max ? INFINITY : m->ranges[i];
    header(&r->header, m->utime, x->frame);
    r->angle_min = m->angle_min;
    r->angle_increment = m->angle_increment;
    r->angle_max = m->angle_min + m->angle_increment * (float)(m->nranges > 0 ? m->nranges - 1 : 0);
    r->range_min = m->range_min;
    r->range_max = m->range_max;
    r->ranges = (dds_sequence_float){(uint32_t)m->nranges, (uint32_t)m->nranges, ranges, false};
    r->intensities = (dds_sequence_float){(uint32_t)m->nintensities, (uint32_t)m->nintensities, m->intensities, false};
    return 0;
}

static int laser_from(ros2_ctx_t *x, const void *in, void *out, const char **why)
{
    const sensor_msgs_msg_dds__LaserScan_ *r = in;
    marie_laser_scan_t *m = out;
    if (!isfinite(r->angle_min) || !isfinite(r->angle_increment) || !isfinite(r->range_min) ||
        !isfinite(r->range_max) || !(r->range_max > r->range_min) || r->range_min < 0)
        FAIL("LaserScan: angles or range limits not finite or not ordered");
    if (r->ranges._length > 100000 || r->intensities._length > 100000)
        FAIL("LaserScan: more than 100000 beams");
    for (uint32_t i = 0; i < r->intensities._length; i++)
        if (!isfinite(r->intensities._buffer[i]))
            FAIL("LaserScan: an intensity is not finite");
    float *ranges = ros2_arena_alloc(&x->arena, r->ranges._length * sizeof *ranges + 1);
    if (!ranges)
        FAIL("out of memory");
    /* +inf and NaN (no return) become range_max, marie's "saw nothing"; -inf (too close, REP 117) 0 */
    for (uint32_t i = 0; i < r->ranges._length; i++) {
        float v = r->ranges._buffer[i];
        ranges[i] = isnan(v) || v == INFINITY ? r->range_max : v == -INFINITY ? 0.0f : v;
    }
    *m = (marie_laser_scan_t){stamp_of(x, &r->header), r->angle_min, r->angle_increment, r->range_min, r->range_max,
                              (int32_t)r->ranges._length, ranges, (int32_t)r->intensities._length,
                              r->intensities._buffer};
    return 0;
}

/* ---- Odometry (the /tf odom -> base_link is the bridge's) ---- */

static int odom_to(ros2_ctx_t *x, const void *in, void *out)
{
    const marie_odometry_t *m = in;
    nav_msgs_msg_dds__Odometry_ *r = out;
    header(&r->header, m->utime, x->frame);
    r->child_frame_id = (char *)x->child;
    pose_to_ros(&m->pose, &r->pose.pose);
    cov_to_ros(m->cov, r->pose.covariance);
    r->twist.twist.linear.x = m->v;
    r->twist.twist.angular.z = m->omega;
    return 0;
}

static int odom_from(ros2_ctx_t *x, const void *in, void *out, const char **why)
{
    const nav_msgs_msg_dds__Odometry_ *r = in;
    marie_odometry_t *m = out;
    *m = (marie_odometry_t){.utime = stamp_of(x, &r->header), .v = r->twist.twist.linear.x,
                            .omega = r->twist.twist.angular.z};
    if (!pose_from_ros(&r->pose.pose, &m->pose) || !cov_from_ros(r->pose.covariance, m->cov) ||
        !isfinite(m->v) || !isfinite(m->omega))
        FAIL("Odometry: pose, covariance or twist not finite");
    if (!frame_ok(x, r->header.frame_id))
        FAIL("Odometry: not in the odometry frame");
    return 0;
}

/* ---- PoseWithCovarianceStamped (the /tf map -> odom is the bridge's) ---- */

static int pose_to(ros2_ctx_t *x, const void *in, void *out)
{
    const marie_pose_cov_t *m = in;
    geometry_msgs_msg_dds__PoseWithCovarianceStamped_ *r = out;
    header(&r->header, m->utime, m->frame && strcmp(m->frame, "odom") == 0 ? "odom" : x->frame);
    pose_to_ros(&m->pose, &r->pose.pose);
    cov_to_ros(m->cov, r->pose.covariance);
    return 0;
}

static int pose_from(ros2_ctx_t *x, const void *in, void *out, const char **why)
{
    const geometry_msgs_msg_dds__PoseWithCovarianceStamped_ *r = in;
    marie_pose_cov_t *m = out;
    *m = (marie_pose_cov_t){.utime = stamp_of(x, &r->header), .frame = "map"};
    if (!pose_from_ros(&r->pose.pose, &m->pose) || !cov_from_ros(r->pose.covariance, m->cov))
        FAIL("PoseWithCovarianceStamped: pose or covariance not finite");
    if (!frame_ok(x, r->header.frame_id))
        FAIL("PoseWithCovarianceStamped: not in the map frame");
    return 0;
}

/* ---- OccupancyGrid: both use map_server's values (0 free .. 100 occupied, -1 unknown) ---- */

static int map_to(ros2_ctx_t *x, const void *in, void *out)
{
    const marie_occupancy_grid_t *m = in;
    nav_msgs_msg_dds__OccupancyGrid_ *r = out;
    header(&r->header, m->utime, x->frame);
    r->info.map_load_time = r->header.stamp;
    r->info.resolution = m->resolution;
    r->info.width = (uint32_t)m->width;
    r->info.height = (uint32_t)m->height;
    pose_to_ros(&m->origin, &r->info.origin);
    r->data = (dds_sequence_int8){(uint32_t)m->ncells, (uint32_t)m->ncells, m->cells, false};
    return 0;
}

static int map_from(ros2_ctx_t *x, const void *in, void *out, const char **why)
{
    const nav_msgs_msg_dds__OccupancyGrid_ *r = in;
    marie_occupancy_grid_t *m = out;
    if ((uint64_t)r->info.width * r->info.height != r->data._length || r->info.width > 1000000 ||
        r->info.height > 1000000)
        FAIL("OccupancyGrid: width x height is not the number of cells");
    if (!isfinite(r->info.resolution) || !(r->info.resolution > 0))
        FAIL("OccupancyGrid: resolution not a positive number");
    for (uint32_t i = 0; i < r->data._length; i++)
        if (r->data._buffer[i] < -1 || r->data._buffer[i] > 100)
            FAIL("OccupancyGrid: a cell outside -1..100");
    *m = (marie_occupancy_grid_t){.utime = stamp_of(x, &r->header), .resolution = r->info.resolution,
                                  .width = (int32_t)r->info.width, .height = (int32_t)r->info.height,
                                  .ncells = (int32_t)r->data._length, .cells = r->data._buffer};
    if (!pose_from_ros(&r->info.origin, &m->origin))
        FAIL("OccupancyGrid: origin not finite");
    return 0;
}

/* ---- Path ---- */

static int path_to(ros2_ctx_t *x, const void *in, void *out)
{
    const marie_path_t *m = in;
    nav_msgs_msg_dds__Path_ *r = out;
    geometry_msgs_msg_dds__PoseStamped_ *ps = ros2_arena_alloc(&x->arena, (size_t)m->nposes * sizeof *ps + 1);
    if (!ps)
        return -1;
    header(&r->header, m->utime, x->frame);
    for (int i = 0; i < m->nposes; i++) {
        ps[i].header = r->header;
        pose_to_ros(&m->poses[i], &ps[i].pose);
    }
    r->poses = (dds_sequence_geometry_msgs_msg_dds__PoseStamped_){(uint32_t)m->nposes, (uint32_t)m->nposes, ps, false};
    return 0;
}

static int path_from(ros2_ctx_t *x, const void *in, void *out, const char **why)
{
    const nav_msgs_msg_dds__Path_ *r = in;
    marie_path_t *m = out;
    if (r->poses._length > 1000000)
        FAIL("Path: more than a million poses");
    marie_pose2d_t *p = ros2_arena_alloc(&x->arena, r->poses._length * sizeof *p + 1);
    if (!p)
        FAIL("out of memory");
    for (uint32_t i = 0; i < r->poses._length; i++)
        if (!pose_from_ros(&r->poses._buffer[i].pose, &p[i]))
            FAIL("Path: a pose is not finite");
    if (!frame_ok(x, r->header.frame_id))
        FAIL("Path: not in the map frame");
    *m = (marie_path_t){.utime = stamp_of(x, &r->header), .status = MARIE_PATH_T_STATUS_OK,
                        .nposes = (int32_t)r->poses._length, .poses = p};
    return 0;
}

/* ---- Twist (/cmd_vel): a differential drive takes linear.x and angular.z ---- */

static int twist_to(ros2_ctx_t *x, const void *in, void *out)
{
    const marie_motor_command_t *m = in;
    geometry_msgs_msg_dds__Twist_ *r = out;
    *r = (geometry_msgs_msg_dds__Twist_){.linear = {m->v, 0, 0}, .angular = {0, 0, m->omega}};
    return 0;
}

static int twist_from(ros2_ctx_t *x, const void *in, void *out, const char **why)
{
    const geometry_msgs_msg_dds__Twist_ *r = in;
    const double v[6] = {r->linear.x, r->linear.y, r->linear.z, r->angular.x, r->angular.y, r->angular.z};
    for (int i = 0; i < 6; i++)
        if (!isfinite(v[i]))
            FAIL("Twist: not finite");
    *(marie_motor_command_t *)out = (marie_motor_command_t){x->now_us, r->linear.x, r->angular.z, (char *)x->source};
    return 0;
}

/* ---- PoseStamped (/goal_pose) -> a goal request, signed by the bridge ---- */

static int goal_from(ros2_ctx_t *x, const void *in, void *out, const char **why)
{
    const geometry_msgs_msg_dds__PoseStamped_ *r = in;
    marie_goal_request_t *m = out;
    *m = (marie_goal_request_t){.utime = x->now_us};
    if (!pose_from_ros(&r->pose, &m->goal.pose))
        FAIL("PoseStamped: pose not finite");
    if (!frame_ok(x, r->header.frame_id))
        FAIL("PoseStamped: a goal not in the map frame");
    m->goal.utime = x->now_us;
    m->goal.name = (char *)"ros2 goal";
    m->sender = (char *)x->source;     /* the bridge signs it as its own before it goes out */
    return 0;
}

/* ---- Bool (e-stop) ---- */

static int bool_to(ros2_ctx_t *x, const void *in, void *out)
{
    ((std_msgs_msg_dds__Bool_ *)out)->data = ((const marie_estop_t *)in)->pressed;
    return 0;
}

static int bool_from(ros2_ctx_t *x, const void *in, void *out, const char **why)
{
    *(marie_estop_t *)out = (marie_estop_t){x->now_us, ((const std_msgs_msg_dds__Bool_ *)in)->data, (char *)x->source};
    return 0;
}

/* ---- Image and CompressedImage ---- */

static const char *const encodings[] = {
    [MARIE_IMAGE_T_FORMAT_GRAY8] = "mono8", [MARIE_IMAGE_T_FORMAT_RGB8] = "rgb8", [MARIE_IMAGE_T_FORMAT_BGR8] = "bgr8",
};
static const int channels[] = {[MARIE_IMAGE_T_FORMAT_GRAY8] = 1, [MARIE_IMAGE_T_FORMAT_RGB8] = 3,
                               [MARIE_IMAGE_T_FORMAT_BGR8] = 3};

static int image_to(ros2_ctx_t *x, const void *in, void *out)
{
    const marie_image_t *m = in;
    sensor_msgs_msg_dds__Image_ *r = out;
    if (m->format < 0 || m->format > MARIE_IMAGE_T_FORMAT_BGR8 || m->width <= 0 || m->height <= 0 ||
        m->row_stride < m->width * channels[m->format] || (int64_t)m->row_stride * m->height > m->size)
        return -1;
    header(&r->header, m->utime, x->frame);
    r->width = (uint32_t)m->width;
    r->height = (uint32_t)m->height;
    r->encoding = (char *)encodings[m->format];
    r->step = (uint32_t)m->row_stride;
    r->data = (dds_sequence_uint8){(uint32_t)m->row_stride * (uint32_t)m->height,
                                   (uint32_t)m->row_stride * (uint32_t)m->height, m->data, false};
    return 0;
}

static int image_from(ros2_ctx_t *x, const void *in, void *out, const char **why)
{
    const sensor_msgs_msg_dds__Image_ *r = in;
    int f = -1;
    for (int i = 0; i <= MARIE_IMAGE_T_FORMAT_BGR8; i++)
        if (strcmp(r->encoding, encodings[i]) == 0)
            f = i;
    if (f < 0)
        FAIL("Image: an encoding marie does not carry (mono8, rgb8, bgr8)");
    if (r->width == 0 || r->width > 100000 || r->height > 100000 || r->step < r->width * (uint32_t)channels[f] ||
        (uint64_t)r->step * r->height > r->data._length)
        FAIL("Image: step x height is more than the data");
    *(marie_image_t *)out = (marie_image_t){stamp_of(x, &r->header), (int32_t)r->width, (int32_t)r->height,
                                            (int32_t)r->step, (int8_t)f, (int32_t)(r->step * r->height), r->data._buffer};
    return 0;
}

static int jpeg_to(ros2_ctx_t *x, const void *in, void *out)
{
    const marie_image_t *m = in;
    sensor_msgs_msg_dds__CompressedImage_ *r = out;
    if (m->format != MARIE_IMAGE_T_FORMAT_JPEG)
        return -1;
    header(&r->header, m->utime, x->frame);
    r->format = (char *)"jpeg";
    r->data = (dds_sequence_uint8){(uint32_t)m->size, (uint32_t)m->size, m->data, false};
    return 0;
}

static int jpeg_from(ros2_ctx_t *x, const void *in, void *out, const char **why)
{
    const sensor_msgs_msg_dds__CompressedImage_ *r = in;
    if (strncmp(r->format, "jpeg", 4) != 0 && !strstr(r->format, "jpeg"))
        FAIL("CompressedImage: not JPEG");
    if (r->data._length > (1u << 30))
        FAIL("CompressedImage: larger than 1 GiB");
    *(marie_image_t *)out = (marie_image_t){.utime = stamp_of(x, &r->header), .format = MARIE_IMAGE_T_FORMAT_JPEG,
                                            .size = (int32_t)r->data._length, .data = r->data._buffer};
    return 0;
}

/* ---- Clock (use_sim_time) and diagnostics ---- */

static int clock_to(ros2_ctx_t *x, const void *in, void *out)
{
    rosgraph_msgs_msg_dds__Clock_ *r = out;
    ros2_stamp(((const marie_sim_clock_t *)in)->utime, &r->clock.sec, &r->clock.nanosec);
    return 0;
}

static char *textf(ros2_ctx_t *x, const char *fmt, long long v)
{
    char *s = ros2_arena_alloc(&x->arena, 24);
    if (s)
        snprintf(s, 24, fmt, v);
    return s ? s : (char *)"";
}

/* One heartbeat, one DiagnosticStatus: OK running, WARN degraded or not running, ERROR failed. */
static int diag_to(ros2_ctx_t *x, const void *in, void *out)
{
    const marie_heartbeat_t *m = in;
    diagnostic_msgs_msg_dds__DiagnosticArray_ *r = out;
    diagnostic_msgs_msg_dds__DiagnosticStatus_ *st = ros2_arena_alloc(&x->arena, sizeof *st);
    int nv = 6 + m->ncounters;
    diagnostic_msgs_msg_dds__KeyValue_ *kv = ros2_arena_alloc(&x->arena, (size_t)nv * sizeof *kv);
    char *name = ros2_arena_alloc(&x->arena, strlen(m->component) + 8);
    if (!st || !kv || !name)
        return -1;
    static const char *const states[] = {"created", "ready", "running", "paused", "failed", "exited", "degraded"};
    const char *state = m->state >= 0 && m->state <= 6 ? states[m->state] : "unknown";
    sprintf(name, "marie: %s", m->component);
    header(&r->header, m->utime, "");
    st->level = m->state == 2 ? 0 : m->state == 4 ? 2 : 1;
    st->name = name;
    st->hardware_id = m->host;
    st->message = m->reason && m->reason[0] ? m->reason : (char *)state;
    const char *keys[6] = {"state", "pid", "msgs_in", "msgs_out", "drops", "bad_input"};
    long long vals[6] = {0, m->pid, m->msgs_in, m->msgs_out, m->drops, m->bad_input};
    for (int i = 0; i < 6; i++)
        kv[i] = (diagnostic_msgs_msg_dds__KeyValue_){(char *)keys[i], i ? textf(x, "%lld", vals[i]) : (char *)state};
    for (int i = 0; i < m->ncounters; i++)
        kv[6 + i] = (diagnostic_msgs_msg_dds__KeyValue_){m->counters[i].name, textf(x, "%lld", m->counters[i].value)};
    st->values = (dds_sequence_diagnostic_msgs_msg_dds__KeyValue_){(uint32_t)nv, (uint32_t)nv, kv, false};
    r->status = (dds_sequence_diagnostic_msgs_msg_dds__DiagnosticStatus_){1, 1, st, false};
    return 0;
}

/* ---- the table ---- */

#define T(pkg, type) #pkg "/msg/" #type, &pkg##_msg_dds__##type##__desc
static const ros2_kind_t kinds[] = {
    {"laser", &marie_type_laser_scan_t, T(sensor_msgs, LaserScan), ROS2_QOS_SENSOR, true, "laser_frame", NULL, laser_to, NULL},
    {"odometry", &marie_type_odometry_t, T(nav_msgs, Odometry), ROS2_QOS_DEFAULT, true, "odom_frame", "base_frame", odom_to, NULL},
    {"pose", &marie_type_pose_cov_t, T(geometry_msgs, PoseWithCovarianceStamped), ROS2_QOS_DEFAULT, true, "map_frame", NULL, pose_to, NULL},
    {"map", &marie_type_occupancy_grid_t, T(nav_msgs, OccupancyGrid), ROS2_QOS_LATCHED, true, "map_frame", NULL, map_to, NULL},
    {"path", &marie_type_path_t, T(nav_msgs, Path), ROS2_QOS_DEFAULT, true, "map_frame", NULL, path_to, NULL},
    {"motor", &marie_type_motor_command_t, T(geometry_msgs, Twist), ROS2_QOS_DEFAULT, true, NULL, NULL, twist_to, NULL},
    {"estop", &marie_type_estop_t, T(std_msgs, Bool), ROS2_QOS_DEFAULT, true, NULL, NULL, bool_to, NULL},
    {"camera", &marie_type_image_t, T(sensor_msgs, Image), ROS2_QOS_SENSOR, true, "camera_frame", NULL, image_to, NULL},
    {"camera", &marie_type_image_t, T(sensor_msgs, CompressedImage), ROS2_QOS_SENSOR, true, "camera_frame", NULL, jpeg_to, NULL},
    {"clock", &marie_type_sim_clock_t, T(rosgraph_msgs, Clock), ROS2_QOS_CLOCK, true, NULL, NULL, clock_to, NULL},
    {"heartbeat", &marie_type_heartbeat_t, T(diagnostic_msgs, DiagnosticArray), ROS2_QOS_DEFAULT, true, NULL, NULL, diag_to, NULL},
    {"ros_scan", &marie_type_laser_scan_t, T(sensor_msgs, LaserScan), ROS2_QOS_SENSOR, false, NULL, NULL, NULL, laser_from},
    {"ros_odom", &marie_type_odometry_t, T(nav_msgs, Odometry), ROS2_QOS_DEFAULT, false, "odom_frame", NULL, NULL, odom_from},
    {"ros_initialpose", &marie_type_pose_cov_t, T(geometry_msgs, PoseWithCovarianceStamped), ROS2_QOS_DEFAULT, false, "map_frame", NULL, NULL, pose_from},
    {"ros_map", &marie_type_occupancy_grid_t, T(nav_msgs, OccupancyGrid), ROS2_QOS_LATCHED, false, NULL, NULL, NULL, map_from},
    {"ros_path", &marie_type_path_t, T(nav_msgs, Path), ROS2_QOS_DEFAULT, false, "map_frame", NULL, NULL, path_from},
    {"ros_cmd_vel", &marie_type_motor_command_t, T(geometry_msgs, Twist), ROS2_QOS_DEFAULT, false, NULL, NULL, NULL, twist_from},
    {"ros_goal", &marie_type_goal_request_t, T(geometry_msgs, PoseStamped), ROS2_QOS_DEFAULT, false, "map_frame", NULL, NULL, goal_from},
    {"ros_estop", &marie_type_estop_t, T(std_msgs, Bool), ROS2_QOS_DEFAULT, false, NULL, NULL, NULL, bool_from},
    {"ros_camera", &marie_type_image_t, T(sensor_msgs, Image), ROS2_QOS_SENSOR, false, NULL, NULL, NULL, image_from},
    {"ros_camera", &marie_type_image_t, T(sensor_msgs, CompressedImage), ROS2_QOS_SENSOR, false, NULL, NULL, NULL, jpeg_from},
};

const ros2_kind_t *ros2_kinds(size_t *n)
{
    *n = sizeof kinds / sizeof kinds[0];
    return kinds;
}

const ros2_kind_t *ros2_kind_find(const char *port, const char *ros_type)
{
    for (size_t i = 0; i < sizeof kinds / sizeof kinds[0]; i++)
        if (strcmp(kinds[i].port, port) == 0 && (!ros_type || !*ros_type || strcmp(kinds[i].ros_type, ros_type) == 0))
            return &kinds[i];
    return NULL;
}
