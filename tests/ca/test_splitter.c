/* test_splitter: fan-out, renaming, per-output rate limits and mistyped payloads, without a bus. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "ca/splitter.h"
#include "lcmtypes/marie_gyro_t.h"
#include "lcmtypes/marie_pose2d_t.h"
#include "tests/fails.h"

typedef struct { int fast, slow, bad; } capture_t;

static int cap_publish(void *user, const char *channel, const void *buf, size_t len)
{
    capture_t *c = user;
    if (strcmp(channel, "POSE_FAST") == 0)
        c->fast++;
    else if (strcmp(channel, "POSE_SLOW") == 0)
        c->slow++;
    return 0;
}

static void cap_note(void *user, ca_note_kind_t kind, const char *counter, int64_t n, const char *text)
{
    if (kind == CA_NOTE_BAD_INPUT)
        ((capture_t *)user)->bad++;
}

static void test_fans_out_with_rate_limit(void **state)
{
    capture_t c = {0};
    ca_sink_t sink = { .note = cap_note, .publish = cap_publish, .user = &c };
    splitter_t *sp = splitter_create("POSE", &marie_type_pose2d_t, &sink);
    assert_int_equal(splitter_add_output(sp, "POSE_FAST", 0), 0);
    assert_int_equal(splitter_add_output(sp, "POSE_SLOW", 10), 1);
    assert_fails(splitter_add_output(sp, "POSE", 0), EINVAL);
    uint8_t buf[128];
    marie_pose2d_t p = {0};
    int n = marie_pose2d_t_encode(buf, 0, sizeof buf, &p);
    /* 100 Hz for 2 s with +-3 ms jitter: the slow output carries 10 Hz */
    for (int i = 0; i < 200; i++)
        splitter_push(sp, buf, (size_t)n, i * 10000 + ((i * 37) % 7 - 3) * 1000);
    assert_int_equal(c.fast, 200);
    assert_in_range(c.slow, 19, 21);
    assert_int_equal(splitter_output_forwarded(sp, 1), c.slow);
    assert_int_equal(splitter_output_limited(sp, 1), 200 - c.slow);
    /* after a pause the first message goes at once, without a burst */
    c.slow = 0;
    for (int i = 0; i < 5; i++)
        splitter_push(sp, buf, (size_t)n, 10000000 + i * 1000);
    assert_int_equal(c.slow, 1);
    splitter_destroy(sp);
}

static void test_mistyped_payload_not_forwarded(void **state)
{
    capture_t c = {0};
    ca_sink_t sink = { .note = cap_note, .publish = cap_publish, .user = &c };
    splitter_t *sp = splitter_create("POSE", &marie_type_pose2d_t, &sink);
    splitter_add_output(sp, "POSE_FAST", 0);
    uint8_t buf[128];
    marie_gyro_t g = {0};
    int n = marie_gyro_t_encode(buf, 0, sizeof buf, &g);
    assert_fails(splitter_push(sp, buf, (size_t)n, 0), EBADMSG);
    assert_fails(splitter_push(sp, buf, 2, 0), EBADMSG);
    assert_int_equal(c.fast, 0);
    assert_int_equal(c.bad, 2);
    assert_int_equal(splitter_stats(sp)->bad_input, 2);
    splitter_destroy(sp);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fans_out_with_rate_limit),
        cmocka_unit_test(test_mistyped_payload_not_forwarded),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
