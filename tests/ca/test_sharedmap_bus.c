/* test_sharedmap_bus: a marie-ca sharedmap process over real LCM through the client library:
 * set/get/delete/list, typed values, snapshots on change, malformed requests, restart. */
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

#include "ca/sharedmap_client.h"
#include "lcmtypes/marie_goal_t.h"
#include "lcmtypes/marie_pose2d_t.h"
#include "lcmtypes/marie_sharedmap_request_t.h"
#include "lcmtypes/marie_sharedmap_snapshot_t.h"
#include "tests/ca/ca_test.h"
#include "tests/fails.h"

static cat_bus_t *bus;
static pid_t pid;
static char dir[256], state_arg[400];
static sharedmap_client_t *cl;

static void start(void)
{
    const char *args[] = { "sharedmap", "--name", "sm", "--param", state_arg, NULL };
    pid = cat_spawn(args);
    assert_true(cat_wait_running(bus, "sm", 5000));
}

static int setup(void **state)
{
    bus = cat_bus_create();
    cat_tmpdir(dir, sizeof dir);
    snprintf(state_arg, sizeof state_arg, "state_file=%s/map.log", dir);
    start();
    cl = sharedmap_client_create(cat_lcm(bus), NULL, "tester");
    assert_non_null(cl);
    return 0;
}

static int teardown(void **state)
{
    int st = cat_stop(pid, SIGTERM);
    sharedmap_client_destroy(cl);
    cat_bus_destroy(bus);
    cat_rmdir(dir);
    return WIFEXITED(st) && WEXITSTATUS(st) == 0 ? 0 : -1;
}

static void test_set_get_delete_list(void **state)
{
    marie_pose2d_t p = { .x = 1.5, .y = -2, .theta = 0.25 };
    assert_int_equal(sharedmap_client_set(cl, "robot/pose", &marie_type_pose2d_t, &p, 1000), 0);
    p.x = 3;
    assert_int_equal(sharedmap_client_set(cl, "robot/home", &marie_type_pose2d_t, &p, 1000), 0);
    assert_int_equal(sharedmap_client_set(cl, "other", &marie_type_pose2d_t, &p, 1000), 0);
    marie_pose2d_t q;
    int64_t age = -1;
    assert_int_equal(sharedmap_client_get(cl, "robot/pose", &marie_type_pose2d_t, &q, 1000, &age), 0);
    assert_true(q.x == 1.5 && q.y == -2 && q.theta == 0.25);
    assert_true(age >= 0);
    /* asking for it as another type is refused */
    marie_goal_t g;
    assert_fails(sharedmap_client_get(cl, "robot/pose", &marie_type_goal_t, &g, 1000, NULL), EBADMSG);
    char **keys;
    size_t n;
    assert_int_equal(sharedmap_client_list(cl, "robot/", &keys, &n, 1000), 0);
    assert_int_equal(n, 2);
    assert_string_equal(keys[0], "robot/home");
    assert_string_equal(keys[1], "robot/pose");
    sharedmap_client_free_keys(keys, n);
    assert_int_equal(sharedmap_client_delete(cl, "robot/home", 1000), 0);
    assert_fails(sharedmap_client_delete(cl, "robot/home", 1000), ENOENT);
    assert_fails(sharedmap_client_get(cl, "robot/home", &marie_type_pose2d_t, &q, 1000, NULL), ENOENT);
    /* a payload that is not the type it claims */
    assert_fails(sharedmap_client_set_raw(cl, "bad", "marie.pose2d_t", "0123456789", 10, 1000, NULL), EBADMSG);
    assert_fails(sharedmap_client_set_raw(cl, "", "marie.pose2d_t", "01234567", 8, 1000, NULL), EINVAL);
}

typedef struct {
    int64_t version;
    int found;
} snap_t;

static void on_snap(const lcm_recv_buf_t *rbuf, const char *channel, const marie_sharedmap_snapshot_t *msg, void *user)
{
    snap_t *s = user;
    s->version = msg->version;
    s->found = 0;
    for (int i = 0; i < msg->nentries; i++)
        if (strcmp(msg->entries[i].key, "snap/key") == 0)
            s->found = 1;
}

static bool snap_has_key(void *user) { return ((snap_t *)user)->found; }

static void test_snapshot_published_on_change(void **state)
{
    snap_t s = {0};
    marie_sharedmap_snapshot_t_subscription_t *sub =
        marie_sharedmap_snapshot_t_subscribe(cat_lcm(bus), "SHAREDMAP\\.SNAPSHOT", on_snap, &s);
    marie_pose2d_t p = { .x = 9 };
    assert_int_equal(sharedmap_client_set(cl, "snap/key", &marie_type_pose2d_t, &p, 1000), 0);
    assert_true(cat_spin(bus, 2000, snap_has_key, &s));
    assert_true(s.version > 0);
    marie_sharedmap_snapshot_t_unsubscribe(cat_lcm(bus), sub);
}

static void test_malformed_requests_counted(void **state)
{
    int64_t before;
    cat_wait_counter(bus, "sm", "bad_request", INT64_MAX, 1, &before);
    uint8_t buf[512];
    marie_sharedmap_request_t req = { .request_id = 1, .client = "x", .reply_channel = "R", .op = 2,
                                      .key = "k", .type = "", .size = 0,
                                      .data = (uint8_t *)"" };
    int n = marie_sharedmap_request_t_encode(buf, 0, sizeof buf, &req);
    lcm_publish(cat_lcm(bus), "SHAREDMAP", buf, (unsigned)n - 2);        /* truncated */
    marie_pose2d_t p = {0};
    marie_pose2d_t_publish(cat_lcm(bus), "SHAREDMAP", &p);             /* wrong type */
    memset(buf + n - 4, 0x7f, 4);                                      /* huge data size */
    lcm_publish(cat_lcm(bus), "SHAREDMAP", buf, (unsigned)n);
    req.op = 77;                                                       /* unknown op: answered */
    marie_sharedmap_request_t_publish(cat_lcm(bus), "SHAREDMAP", &req);
    assert_true(cat_wait_counter(bus, "sm", "bad_request", before + 4, 3000, NULL));
    assert_true(cat_alive(pid));
    marie_pose2d_t q;
    assert_int_equal(sharedmap_client_get(cl, "robot/pose", &marie_type_pose2d_t, &q, 1000, NULL), 0);
}

typedef struct {
    int calls, status;
    double x;
} async_t;

static void on_done(sharedmap_client_t *c, const sharedmap_result_t *r, void *user)
{
    async_t *a = user;
    a->calls++;
    a->status = r->status;
    marie_pose2d_t p;
    if (r->status == 0 && r->len && marie_pose2d_t_decode(r->data, 0, (int)r->len, &p) >= 0)
        a->x = p.x;
}

static bool both_done(void *user) { async_t *a = user; return a[0].calls && a[1].calls; }
typedef struct {
    async_t a;
    sharedmap_client_t *c;
} ticking_t;

static bool timed_out(void *user)
{
    ticking_t *t = user;
    sharedmap_client_tick(t->c);
    return t->a.calls > 0;
}

static void test_async_calls(void **state)
{
    async_t a[2] = {{0}};
    marie_pose2d_t p = { .x = 31 };
    assert_int_equal(sharedmap_client_set_async(cl, "async", &marie_type_pose2d_t, &p, 1000, on_done, &a[0]), 0);
    assert_int_equal(sharedmap_client_get_async(cl, "async", 1000, on_done, &a[1]), 0);
    assert_true(cat_spin(bus, 3000, both_done, a));
    assert_int_equal(a[0].status, 0);
    assert_int_equal(a[1].status, 0);       /* requests are served in order */
    assert_true(a[1].x == 31);
    assert_int_equal(sharedmap_client_tick(cl), 0);
    /* nobody listens on this channel: the callback reports the timeout, once */
    ticking_t t = { {0}, sharedmap_client_create(cat_lcm(bus), "NOBODY", "t2") };
    assert_int_equal(sharedmap_client_get_async(t.c, "x", 100, on_done, &t.a), 0);
    assert_true(cat_spin(bus, 3000, timed_out, &t));
    assert_int_equal(t.a.status, ETIMEDOUT);
    cat_spin(bus, 200, timed_out, &t);
    assert_int_equal(t.a.calls, 1);
    sharedmap_client_destroy(t.c);
}

static void test_values_survive_restart(void **state)
{
    marie_pose2d_t p = { .x = 77 };
    assert_int_equal(sharedmap_client_set(cl, "keep", &marie_type_pose2d_t, &p, 1000), 0);
    assert_true(WIFEXITED(cat_stop(pid, SIGTERM)));
    /* nobody answers meanwhile */
    assert_fails(sharedmap_client_get(cl, "keep", &marie_type_pose2d_t, &p, 200, NULL), ETIMEDOUT);
    start();
    marie_pose2d_t q;
    assert_int_equal(sharedmap_client_get(cl, "keep", &marie_type_pose2d_t, &q, 1000, NULL), 0);
    assert_true(q.x == 77);
    assert_int_equal(sharedmap_client_get(cl, "robot/pose", &marie_type_pose2d_t, &q, 1000, NULL), 0);
    assert_true(q.x == 1.5);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_set_get_delete_list),
        cmocka_unit_test(test_snapshot_published_on_change),
        cmocka_unit_test(test_malformed_requests_counted),
        cmocka_unit_test(test_async_calls),
        cmocka_unit_test(test_values_survive_restart),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
