/* test_mailbox_bus: a marie-ca mailbox process over real LCM: newest value and ordering,
 * overflow, waiting and timed-out pulls, mistyped payloads, malformed requests, several
 * channels in one process, and the core's marie_port_pull as its client. */
#include <errno.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "core/component.h"
#include "ca/ca.h"
#include "core/time.h"
#include "lcmtypes/marie_gyro_t.h"
#include "lcmtypes/marie_occupancy_grid_t.h"
#include "lcmtypes/marie_odometry_t.h"
#include "lcmtypes/marie_pose2d_t.h"
#include "lcmtypes/marie_pull_reply_t.h"
#include "lcmtypes/marie_pull_request_t.h"
#include "tests/ca/ca_test.h"
#include "tests/proc.h"
#include "tests/fails.h"

static cat_bus_t *bus;
static pid_t mb_pid;

static int setup(void **state)
{
    bus = cat_bus_create();
    assert_non_null(bus);
    const char *args[] = { "mailbox", "--name", "mb", "--param", "type=marie.pose2d_t",
        "--param", "channel=POSE", "--param", "depth=3",
        "--param", "channels=[FULL, EMPTY, {channel: ODOM, type: marie.odometry_t, depth: 2}]", NULL };
    mb_pid = cat_spawn(args);
    assert_true(cat_wait_running(bus, "mb", 5000));
    return 0;
}

static int teardown(void **state)
{
    int st = cat_stop(mb_pid, SIGTERM);
    cat_bus_destroy(bus);
    /* it must have survived everything and quit cleanly */
    return WIFEXITED(st) && WEXITSTATUS(st) == 0 ? 0 : -1;
}

static void publish_pose(const char *channel, double x)
{
    marie_pose2d_t p = { .x = x };
    assert_int_equal(marie_pose2d_t_publish(cat_lcm(bus), channel, &p), 0);
}

typedef struct {
    int64_t id;
    marie_pull_reply_t *reply;
} pending_t;

static void on_reply(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    pending_t *p = user;
    marie_pull_reply_t v;
    assert_int_equal(marie_decode_checked(&marie_type_pull_reply_t, rbuf->data, rbuf->data_size, &v), 0);
    if (v.request_id == p->id && !p->reply) {
        p->reply = malloc(sizeof v);        /* reply_free() it */
        *p->reply = v;
    } else {
        marie_pull_reply_t_decode_cleanup(&v);
    }
}

static void reply_free(marie_pull_reply_t *r)
{
    if (r)
        marie_pull_reply_t_decode_cleanup(r);
    free(r);
}

static bool got_reply(void *user) { return ((pending_t *)user)->reply != NULL; }

/* Send a pull request for `channel` (on `to`.PULL) and wait for its reply (NULL if none). */
static marie_pull_reply_t *pull(const char *to, const char *channel, int timeout_ms)
{
    static int64_t next_id = 100;
    pending_t p = { ++next_id, NULL };
    lcm_subscription_t *sub = lcm_subscribe(cat_lcm(bus), "T\\.REPLY", on_reply, &p);
    char req_ch[128];
    snprintf(req_ch, sizeof req_ch, "%s.PULL", to);
    marie_pull_request_t req = { .utime = marie_wall_us(), .request_id = p.id, .requester = "test",
                                 .channel = (char *)channel, .reply_channel = "T.REPLY", .timeout_ms = timeout_ms };
    assert_int_equal(marie_pull_request_t_publish(cat_lcm(bus), req_ch, &req), 0);
    cat_spin(bus, timeout_ms + 1000, got_reply, &p);
    lcm_unsubscribe(cat_lcm(bus), sub);
    return p.reply;
}

static double pose_x(const marie_pull_reply_t *r)
{
    marie_pose2d_t p;
    assert_true(marie_pose2d_t_decode(r->data, 0, r->size, &p) >= 0);
    return p.x;
}

static void test_pull_returns_newest_in_publish_order(void **state)
{
    for (int i = 1; i <= 20; i++) {
        publish_pose("POSE", i);
        marie_pull_reply_t *r = pull("POSE", "POSE", 500);
        assert_non_null(r);
        assert_int_equal(r->status, MARIE_PULL_REPLY_T_STATUS_OK);
        assert_true(pose_x(r) == (double)i);
        assert_int_equal(r->fingerprint, marie_type_pose2d_t.hash());
        assert_true(r->age_us >= 0);
        reply_free(r);
    }
}

static void test_overflow_drops_oldest_and_counts(void **state)
{
    for (int i = 1; i <= 10; i++)
        publish_pose("FULL", i);
    marie_pull_reply_t *r = pull("FULL", "FULL", 500);
    assert_non_null(r);
    assert_true(pose_x(r) == 10.0);
    reply_free(r);
    int64_t seen;
    assert_true(cat_wait_counter(bus, "mb", "FULL.overflow", 7, 3000, &seen));
    assert_int_equal(seen, 7);
}

static void test_empty_pull_times_out_then_waits_for_data(void **state)
{
    marie_pull_reply_t *r = pull("EMPTY", "EMPTY", 300);
    assert_non_null(r);     /* answered before the requester gives up */
    assert_int_equal(r->status, MARIE_PULL_REPLY_T_STATUS_EMPTY);
    assert_int_equal(r->size, 0);
    reply_free(r);
    r = pull("EMPTY", "EMPTY", 0);
    assert_non_null(r);
    assert_int_equal(r->status, MARIE_PULL_REPLY_T_STATUS_EMPTY);
    reply_free(r);

    /* a request held by the Mailbox is answered when data arrives */
    static int64_t id = 5000;
    pending_t p = { ++id, NULL };
    lcm_subscription_t *sub = lcm_subscribe(cat_lcm(bus), "T\\.REPLY", on_reply, &p);
    marie_pull_request_t req = { .request_id = p.id, .requester = "test", .channel = "EMPTY",
                                 .reply_channel = "T.REPLY", .timeout_ms = 3000 };
    marie_pull_request_t_publish(cat_lcm(bus), "EMPTY.PULL", &req);
    cat_spin(bus, 100, NULL, NULL);
    assert_null(p.reply);
    publish_pose("EMPTY", 42);
    assert_true(cat_spin(bus, 2000, got_reply, &p));
    assert_int_equal(p.reply->status, MARIE_PULL_REPLY_T_STATUS_OK);
    assert_true(pose_x(p.reply) == 42.0);
    reply_free(p.reply);
    lcm_unsubscribe(cat_lcm(bus), sub);
}

static void test_mistyped_payload_counted_not_stored(void **state)
{
    int64_t before;
    cat_wait_counter(bus, "mb", "bad_fingerprint", INT64_MAX, 1, &before);
    publish_pose("POSE", 7);
    marie_gyro_t g = { .utime = 1 };
    marie_gyro_t_publish(cat_lcm(bus), "POSE", &g);
    marie_pull_reply_t *r = pull("POSE", "POSE", 500);
    assert_non_null(r);
    assert_true(pose_x(r) == 7.0);     /* the gyro message was not stored */
    reply_free(r);
    assert_true(cat_wait_counter(bus, "mb", "bad_fingerprint", before + 1, 3000, NULL));
    /* the per-channel type wins over the process-wide one */
    marie_odometry_t o = { .utime = 5 };
    marie_odometry_t_publish(cat_lcm(bus), "ODOM", &o);
    r = pull("ODOM", "ODOM", 500);
    assert_non_null(r);
    assert_int_equal(r->status, MARIE_PULL_REPLY_T_STATUS_OK);
    assert_int_equal(r->fingerprint, marie_type_odometry_t.hash());
    reply_free(r);
}

static void test_malformed_requests_survived_and_counted(void **state)
{
    int64_t before;
    cat_wait_counter(bus, "mb", "bad_request", INT64_MAX, 1, &before);
    uint8_t buf[512];
    marie_pull_request_t req = { .request_id = 1, .requester = "x", .channel = "POSE",
                                 .reply_channel = "T.REPLY", .timeout_ms = 10 };
    int n = marie_pull_request_t_encode(buf, 0, sizeof buf, &req);
    lcm_publish(cat_lcm(bus), "POSE.PULL", buf, (unsigned)n - 4);         /* truncated */
    marie_pose2d_t p = {0};
    marie_pose2d_t_publish(cat_lcm(bus), "POSE.PULL", &p);               /* wrong type */
    memset(buf + 24, 0x7f, 4);                                           /* huge length */
    lcm_publish(cat_lcm(bus), "POSE.PULL", buf, (unsigned)n);
    lcm_publish(cat_lcm(bus), "POSE.PULL", "", 0);                       /* empty */
    assert_true(cat_wait_counter(bus, "mb", "bad_request", before + 4, 3000, NULL));
    /* a request for a channel this Mailbox does not hold is answered */
    marie_pull_reply_t *r = pull("POSE", "NOPE", 500);
    assert_non_null(r);
    assert_int_equal(r->status, MARIE_PULL_REPLY_T_STATUS_UNKNOWN_CHANNEL);
    reply_free(r);
    assert_true(cat_alive(mb_pid));
}

/* ---- the core's client side against this Mailbox ---- */

static const marie_port_spec_t puller_ports[] = {
    { "pose", &marie_type_pose2d_t, MARIE_IN, MARIE_PULL, "POSE" },
    { "empty", &marie_type_pose2d_t, MARIE_IN, MARIE_PULL, "NOTHING_HERE" },
    { 0 },
};
static const marie_component_def_t puller_def = { .kind = "puller", .ports = puller_ports };

static void test_core_pull_client(void **state)
{
    char *argv[] = { "puller", "--name", "puller", "--hold", NULL };
    marie_errors_t errs = {0};
    marie_component_t *c = marie_component_create(&puller_def, 4, argv, NULL, &errs);
    marie_errors_print(&errs, stderr);
    assert_non_null(c);
    publish_pose("POSE", 99);
    cat_spin(bus, 50, NULL, NULL);
    marie_pose2d_t p;
    int64_t age = -1;
    assert_int_equal(marie_port_pull(marie_port(c, "pose"), &p, 1000, &age), 0);
    assert_true(p.x == 99.0);
    assert_true(age >= 0);
    marie_pose2d_t_decode_cleanup(&p);
    /* nobody serves this channel: the requester times out */
    assert_fails(marie_port_pull(marie_port(c, "empty"), &p, 200, &age), ETIMEDOUT);
    marie_component_destroy(c);
}

static void test_core_pull_client_empty_mailbox(void **state)
{
    static const marie_port_spec_t ports[] = {
        { "e", &marie_type_pose2d_t, MARIE_IN, MARIE_PULL, "FULL2" }, { 0 } };
    static const marie_component_def_t def = { .kind = "puller", .ports = ports };
    char *argv[] = { "puller", "--name", "puller2", "--hold", "--port", "e=EMPTY_TOO", NULL };
    marie_errors_t errs = {0};
    marie_component_t *c = marie_component_create(&def, 6, argv, NULL, &errs);
    marie_errors_print(&errs, stderr);
    assert_non_null(c);
    marie_pose2d_t p;
    /* EMPTY_TOO is not served: ETIMEDOUT; the EMPTY mailbox was filled earlier, so use a
     * second Mailbox process that holds nothing */
    const char *args[] = { "mailbox", "--name", "mb2", "--param", "channel=EMPTY_TOO", NULL };
    pid_t pid = cat_spawn(args);
    assert_true(cat_wait_running(bus, "mb2", 5000));
    assert_fails(marie_port_pull(marie_port(c, "e"), &p, 1000, NULL), ENODATA);
    cat_stop(pid, SIGTERM);
    marie_component_destroy(c);
}

/* The system file puts the mailbox's channel on shared memory: marie-ca reads the grids from the
 * ring (a publisher component writes them there; LCM carries only the notices) and a pull gets
 * the newest whole. */
static int whole_on_lcm;
static void on_whole(const lcm_recv_buf_t *rbuf, const char *channel, void *user) { whole_on_lcm++; }

static void test_mailbox_on_a_shared_memory_channel(void **state)
{
    char file[] = "/tmp/marie-test-mbshm-XXXXXX.yaml";
    assert_int_equal(test_write_temp(file, 5, "system: mbshm\n"
                                              "transports:\n  BIG: {kind: shm, max_size: 1000000, slots: 4}\n"
                                              "components:\n"
                                              "  mbs:\n    exec: marie-ca\n    args: [mailbox]\n"
                                              "    params: {channel: BIG, type: marie.occupancy_grid_t}\n"
                                              "  pub: {exec: /bin/true}\n"),
                     0);
    const char *args[] = { "mailbox", "--system", file, "--name", "mbs", NULL };
    pid_t pid = cat_spawn(args);
    assert_true(cat_wait_running(bus, "mbs", 5000));
    static const marie_port_spec_t ports[] = {
        { "map", &marie_type_occupancy_grid_t, MARIE_OUT, MARIE_PUSH, "BIG" }, { 0 } };
    static const marie_component_def_t def = { .kind = "gridpub", .ports = ports };
    char *argv[] = { "gridpub", "--system", file, "--name", "pub", NULL };
    marie_errors_t errs = {0};
    marie_component_t *c = marie_component_create(&def, 5, argv, NULL, &errs);
    marie_errors_print(&errs, stderr);
    assert_non_null(c);
    lcm_subscription_t *spy = lcm_subscribe(cat_lcm(bus), "BIG", on_whole, NULL);
    static int8_t cells[300 * 300];
    for (int k = 1; k <= 3; k++) {
        for (int i = 0; i < 300 * 300; i++)
            cells[i] = (int8_t)((i + k) % 100);
        marie_occupancy_grid_t g = { .utime = k, .resolution = 0.05f, .width = 300, .height = 300,
                                     .ncells = 300 * 300, .cells = cells };
        assert_int_equal(marie_port_publish(marie_port(c, "map"), &g), 0);
        cat_spin(bus, 50, NULL, NULL);
    }
    marie_pull_reply_t *r = pull("BIG", "BIG", 500);
    assert_non_null(r);
    assert_int_equal(r->status, MARIE_PULL_REPLY_T_STATUS_OK);
    marie_occupancy_grid_t got;
    assert_true(marie_occupancy_grid_t_decode(r->data, 0, r->size, &got) == r->size);
    assert_int_equal(got.utime, 3);                 /* the newest */
    assert_int_equal(got.ncells, 300 * 300);
    assert_int_equal(got.cells[299], (int8_t)((299 + 3) % 100));
    marie_occupancy_grid_t_decode_cleanup(&got);
    reply_free(r);
    assert_int_equal(whole_on_lcm, 0);              /* the grids never went on LCM */
    lcm_unsubscribe(cat_lcm(bus), spy);
    marie_component_destroy(c);
    cat_stop(pid, SIGTERM);
    unlink(file);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_pull_returns_newest_in_publish_order),
        cmocka_unit_test(test_overflow_drops_oldest_and_counts),
        cmocka_unit_test(test_empty_pull_times_out_then_waits_for_data),
        cmocka_unit_test(test_mistyped_payload_counted_not_stored),
        cmocka_unit_test(test_malformed_requests_survived_and_counted),
        cmocka_unit_test(test_core_pull_client),
        cmocka_unit_test(test_core_pull_client_empty_mailbox),
        cmocka_unit_test(test_mailbox_on_a_shared_memory_channel),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
