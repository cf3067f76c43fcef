/* test_splitter_bus: a marie-ca splitter process over real LCM: every output gets every
 * message in order, a renamed output is rate limited, mistyped payloads are not forwarded, a
 * burst that arrives while the splitter cannot run is forwarded whole. */
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

#include "core/loop.h"
#include "core/time.h"
#include "lcmtypes/marie_gyro_t.h"
#include "lcmtypes/marie_pose2d_t.h"
#include "tests/ca/ca_test.h"

static cat_bus_t *bus;
static pid_t pid;

typedef struct {
    int n, out_of_order, bad;
    double last;
} out_t;
static out_t full, slow;

static void on_pose(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    out_t *o = user;
    marie_pose2d_t p;
    if (marie_pose2d_t_decode(rbuf->data, 0, (int)rbuf->data_size, &p) < 0) {
        o->bad++;
        return;
    }
    if (o->n > 0 && p.x <= o->last)
        o->out_of_order++;
    o->last = p.x;
    o->n++;
}

static int setup(void **state)
{
    bus = cat_bus_create();
    marie_bus_subscribe(cat_lcm(bus), "POSE_ALL", on_pose, &full);
    marie_bus_subscribe(cat_lcm(bus), "POSE_SLOW", on_pose, &slow);
    const char *args[] = { "splitter", "--name", "sp", "--param", "type=marie.pose2d_t",
        "--param", "input=POSE", "--param", "outputs=[POSE_ALL, {channel: POSE_SLOW, max_hz: 10}]", NULL };
    pid = cat_spawn(args);
    assert_true(cat_wait_running(bus, "sp", 5000));
    return 0;
}

static int teardown(void **state)
{
    int st = cat_stop(pid, SIGTERM);
    cat_bus_destroy(bus);
    return WIFEXITED(st) && WEXITSTATUS(st) == 0 ? 0 : -1;
}

static bool all_200(void *user) { return full.n >= 200; }

static void test_fan_out_in_order_with_rate_limit(void **state)
{
    /* 100 Hz for 2 s */
    int64_t t0 = marie_mono_us();
    for (int i = 1; i <= 200; i++) {
        marie_pose2d_t p = { .x = i };
        marie_pose2d_t_publish(cat_lcm(bus), "POSE", &p);
        int64_t due = t0 + i * 10000;
        while (marie_mono_us() < due)
            cat_spin(bus, (int)((due - marie_mono_us()) / 1000) + 1, NULL, NULL);
    }
    cat_spin(bus, 5000, all_200, NULL);
    int64_t secs = (marie_mono_us() - t0);
    assert_int_equal(full.n, 200);
    assert_int_equal(full.out_of_order, 0);
    assert_true(full.last == 200);
    /* the limited output never beats its rate: at most one per 100 ms of the run */
    assert_true(slow.n >= 5);
    assert_true(slow.n <= secs / 100000 + 1);
    assert_int_equal(slow.out_of_order, 0);
}

static void test_mistyped_payload_not_forwarded(void **state)
{
    int before = full.n;
    marie_gyro_t g = {0};
    marie_gyro_t_publish(cat_lcm(bus), "POSE", &g);
    lcm_publish(cat_lcm(bus), "POSE", "abc", 3);
    assert_true(cat_wait_counter(bus, "sp", "bad_fingerprint", 2, 3000, NULL));
    assert_int_equal(full.n, before);
    assert_int_equal(full.bad, 0);
}

static bool all_burst(void *user) { return full.n >= *(int *)user; }

/* 500 messages while the splitter is stopped (SIGSTOP: the kernel holds them), then it runs
 * again: every one comes out, in order. LCM keeps 30 per subscription unless told otherwise. */
static void test_burst_while_stopped_forwarded_whole(void **state)
{
    int before = full.n, out_of_order = full.out_of_order;
    kill(pid, SIGSTOP);
    for (int i = 1; i <= 500; i++) {
        marie_pose2d_t p = { .x = 1000 + i };
        marie_pose2d_t_publish(cat_lcm(bus), "POSE", &p);
    }
    kill(pid, SIGCONT);
    int want = before + 500;
    cat_spin(bus, 5000, all_burst, &want);
    assert_int_equal(full.n, want);
    assert_int_equal(full.out_of_order, out_of_order);
    assert_true(full.last == 1500);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fan_out_in_order_with_rate_limit),
        cmocka_unit_test(test_mistyped_payload_not_forwarded),
        cmocka_unit_test(test_burst_while_stopped_forwarded_whole),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
