/* test_mailbox: the Mailbox's buffer and pull protocol without a bus (ordering, overflow,
 * waiting and timing out, mistyped and malformed payloads, malformed requests). */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ca/mailbox.h"
#include "core/bus/shm_bus.h"
#include "lcmtypes/marie_occupancy_grid_t.h"
#include "lcmtypes/marie_pose2d_t.h"
#include "lcmtypes/marie_gyro_t.h"
#include "lcmtypes/marie_laser_scan_t.h"
#include "lcmtypes/marie_pull_reply_t.h"
#include "tests/fails.h"

#define MAXR 64
typedef struct {
    marie_pull_reply_t replies[MAXR];
    void *raw[MAXR];
    char channels[MAXR][64];
    int nreplies;
    int bad_input, drops;
} capture_t;

static int cap_publish(void *user, const char *channel, const void *buf, size_t len)
{
    capture_t *c = user;
    assert_true(c->nreplies < MAXR);
    c->raw[c->nreplies] = malloc(len);
    memcpy(c->raw[c->nreplies], buf, len);
    assert_int_equal(marie_decode_checked(&marie_type_pull_reply_t, buf, len, &c->replies[c->nreplies]), 0);
    snprintf(c->channels[c->nreplies], 64, "%s", channel);
    c->nreplies++;
    return 0;
}

static void cap_note(void *user, ca_note_kind_t kind, const char *counter, int64_t n, const char *text)
{
    capture_t *c = user;
    if (kind == CA_NOTE_BAD_INPUT)
        c->bad_input += (int)n;
    if (kind == CA_NOTE_DROP)
        c->drops += (int)n;
}

static void cap_free(capture_t *c)
{
    for (int i = 0; i < c->nreplies; i++) {
        marie_pull_reply_t_decode_cleanup(&c->replies[i]);
        free(c->raw[i]);
    }
    memset(c, 0, sizeof *c);
}

static size_t pose(uint8_t *buf, size_t cap, double x)
{
    marie_pose2d_t p = { .x = x, .y = 1 };
    int n = marie_pose2d_t_encode(buf, 0, (int)cap, &p);
    assert_true(n > 0);
    return (size_t)n;
}

static double reply_x(const marie_pull_reply_t *r)
{
    marie_pose2d_t p;
    assert_true(marie_pose2d_t_decode(r->data, 0, r->size, &p) >= 0);
    return p.x;
}

static mailbox_t *make(capture_t *c, int depth)
{
    ca_sink_t sink = { .note = cap_note, .publish = cap_publish, .user = c };
    mailbox_t *mb = mailbox_create("POSE", &marie_type_pose2d_t, depth, &sink);
    assert_non_null(mb);
    return mb;
}

static marie_pull_request_t req(int64_t id, int timeout_ms)
{
    marie_pull_request_t r = { .utime = 0, .request_id = id, .requester = "t", .channel = "POSE",
                               .reply_channel = "REPLY", .timeout_ms = timeout_ms };
    return r;
}

static void test_keeps_newest_in_order(void **state)
{
    capture_t c = {0};
    mailbox_t *mb = make(&c, 3);
    uint8_t buf[256];
    for (int i = 1; i <= 5; i++)
        assert_int_equal(mailbox_push(mb, buf, pose(buf, sizeof buf, i), 1000 * i), 0);
    assert_int_equal(mailbox_count(mb), 3);
    /* newest first: 5, 4, 3; 1 and 2 were dropped as overflow */
    for (size_t i = 0; i < 3; i++) {
        const void *raw; size_t len; int64_t t;
        assert_int_equal(mailbox_peek(mb, i, &raw, &len, &t), 0);
        marie_pose2d_t p;
        assert_true(marie_pose2d_t_decode(raw, 0, (int)len, &p) >= 0);
        assert_true(p.x == 5.0 - (double)i);
        assert_int_equal(t, 1000 * (5 - (int)i));
    }
    assert_fails(mailbox_peek(mb, 3, NULL, NULL, NULL), ENODATA);
    assert_int_equal(mailbox_stats(mb)->overflow, 2);
    assert_int_equal(c.drops, 2);
    marie_pose2d_t p;
    int64_t age;
    assert_int_equal(mailbox_latest(mb, &p, 9000, &age), 0);
    assert_true(p.x == 5.0);
    assert_int_equal(age, 4000);
    mailbox_destroy(mb);
    cap_free(&c);
}

static void test_pull_answers_newest_with_age(void **state)
{
    capture_t c = {0};
    mailbox_t *mb = make(&c, 4);
    uint8_t buf[256];
    mailbox_push(mb, buf, pose(buf, sizeof buf, 1), 100);
    mailbox_push(mb, buf, pose(buf, sizeof buf, 2), 200);
    marie_pull_request_t r = req(42, 100);
    assert_int_equal(mailbox_handle_request(mb, &r, 1200), 0);
    assert_int_equal(c.nreplies, 1);
    assert_string_equal(c.channels[0], "REPLY");
    assert_int_equal(c.replies[0].status, MARIE_PULL_REPLY_T_STATUS_OK);
    assert_int_equal(c.replies[0].request_id, 42);
    assert_int_equal(c.replies[0].age_us, 1000);
    assert_int_equal(c.replies[0].fingerprint, marie_type_pose2d_t.hash());
    assert_string_equal(c.replies[0].channel, "POSE");
    assert_true(reply_x(&c.replies[0]) == 2.0);
    mailbox_destroy(mb);
    cap_free(&c);
}

static void test_empty_pull_waits_for_data(void **state)
{
    capture_t c = {0};
    mailbox_t *mb = make(&c, 2);
    marie_pull_request_t r = req(7, 500);
    assert_int_equal(mailbox_handle_request(mb, &r, 0), 1);
    assert_int_equal(c.nreplies, 0);
    assert_int_equal(mailbox_tick(mb, 100000), 0);     /* 100 ms: still waiting */
    uint8_t buf[256];
    mailbox_push(mb, buf, pose(buf, sizeof buf, 3), 150000);
    assert_int_equal(c.nreplies, 1);
    assert_int_equal(c.replies[0].status, MARIE_PULL_REPLY_T_STATUS_OK);
    assert_int_equal(c.replies[0].request_id, 7);
    assert_true(reply_x(&c.replies[0]) == 3.0);
    assert_int_equal(mailbox_next_deadline(mb), INT64_MAX);
    mailbox_destroy(mb);
    cap_free(&c);
}

static void test_empty_pull_times_out_before_requester(void **state)
{
    capture_t c = {0};
    mailbox_t *mb = make(&c, 2);
    marie_pull_request_t r = req(8, 500);
    assert_int_equal(mailbox_handle_request(mb, &r, 0), 1);
    int64_t d = mailbox_next_deadline(mb);
    assert_int_equal(d, 400000);
    assert_int_equal(mailbox_tick(mb, d - 1), 0);
    assert_int_equal(mailbox_tick(mb, d), 1);
    assert_int_equal(c.nreplies, 1);
    assert_int_equal(c.replies[0].status, MARIE_PULL_REPLY_T_STATUS_EMPTY);
    assert_int_equal(c.replies[0].size, 0);
    /* zero timeout: answered EMPTY at once */
    r = req(9, 0);
    assert_int_equal(mailbox_handle_request(mb, &r, d), 0);
    assert_int_equal(c.replies[1].status, MARIE_PULL_REPLY_T_STATUS_EMPTY);
    assert_int_equal(c.replies[1].request_id, 9);
    mailbox_destroy(mb);
    cap_free(&c);
}

static void test_mistyped_payload_is_counted_not_stored(void **state)
{
    capture_t c = {0};
    mailbox_t *mb = make(&c, 2);
    uint8_t buf[256];
    marie_gyro_t g = {0};
    int n = marie_gyro_t_encode(buf, 0, sizeof buf, &g);
    assert_fails(mailbox_push(mb, buf, (size_t)n, 1), EBADMSG);
    assert_fails(mailbox_push(mb, buf, 5, 1), EBADMSG);    /* shorter than a fingerprint */
    assert_int_equal(mailbox_count(mb), 0);
    assert_int_equal(c.bad_input, 2);
    assert_int_equal(mailbox_stats(mb)->bad_input, 2);
    mailbox_destroy(mb);
    cap_free(&c);
}

/* A payload with the right fingerprint but a body no component accepts (cut short, trailing
 * bytes, a NaN or an infinity) is refused and counted once, and pulls keep getting the last
 * good one: stored, it would be served to every pull and counted again by every puller. */
static void test_malformed_payload_is_counted_not_stored(void **state)
{
    capture_t c = {0};
    mailbox_t *mb = make(&c, 4);
    uint8_t buf[256], bad[260];
    size_t n = pose(buf, sizeof buf, 1.0);
    assert_int_equal(mailbox_push(mb, buf, n, 1), 0);
    assert_fails(mailbox_push(mb, buf, n - 1, 2), EBADMSG);     /* truncated */
    memcpy(bad, buf, n);
    bad[n] = 0;
    assert_fails(mailbox_push(mb, bad, n + 1, 3), EBADMSG);     /* trailing byte */
    size_t nan = pose(bad, sizeof bad, NAN), inf = pose(bad + 128, 128, INFINITY);
    assert_fails(mailbox_push(mb, bad, nan, 4), EBADMSG);
    assert_fails(mailbox_push(mb, bad + 128, inf, 5), EBADMSG);
    assert_int_equal(mailbox_count(mb), 1);
    assert_int_equal(c.bad_input, 4);
    assert_int_equal(mailbox_stats(mb)->bad_input, 4);
    marie_pull_request_t r = req(7, 0);
    for (int i = 0; i < 3; i++)
        assert_int_equal(mailbox_handle_request(mb, &r, 10), 0);
    assert_int_equal(c.nreplies, 3);
    for (int i = 0; i < 3; i++) {
        assert_int_equal(c.replies[i].status, MARIE_PULL_REPLY_T_STATUS_OK);
        assert_true(reply_x(&c.replies[i]) == 1.0);
    }
    assert_int_equal(c.bad_input, 4);
    mailbox_destroy(mb);
    cap_free(&c);
}

/* An untyped Mailbox checks the body of every marie type it recognises by fingerprint. */
static void test_untyped_mailbox_checks_known_types(void **state)
{
    capture_t c = {0};
    ca_sink_t sink = { .note = cap_note, .publish = cap_publish, .user = &c };
    mailbox_t *mb = mailbox_create("ANY", NULL, 2, &sink);
    uint8_t buf[256];
    float ranges[2] = {1, 2};
    marie_laser_scan_t s = { .nranges = 2, .ranges = ranges, .intensities = ranges };
    int n = marie_laser_scan_t_encode(buf, 0, sizeof buf, &s);
    assert_true(n > 0);
    /* nranges (after utime and four floats) claims INT32_MAX beams */
    buf[8 + 8 + 16] = 0x7f;
    assert_fails(mailbox_push(mb, buf, (size_t)n, 1), EBADMSG);
    memset(buf, 0xa5, 16);       /* no marie type: only its length is checked */
    assert_int_equal(mailbox_push(mb, buf, 16, 2), 0);
    assert_int_equal(mailbox_count(mb), 1);
    assert_int_equal(c.bad_input, 1);
    mailbox_destroy(mb);
    cap_free(&c);
}

static void test_untyped_mailbox_takes_any_payload(void **state)
{
    capture_t c = {0};
    ca_sink_t sink = { .note = cap_note, .publish = cap_publish, .user = &c };
    mailbox_t *mb = mailbox_create("ANY", NULL, 1, &sink);
    uint8_t buf[256];
    marie_gyro_t g = {0};
    int n = marie_gyro_t_encode(buf, 0, sizeof buf, &g);
    assert_int_equal(mailbox_push(mb, buf, (size_t)n, 1), 0);
    assert_fails(mailbox_push(mb, buf, 3, 1), EBADMSG);
    mailbox_destroy(mb);
    cap_free(&c);
}

static void test_bad_requests_counted(void **state)
{
    capture_t c = {0};
    mailbox_t *mb = make(&c, 2);
    uint8_t buf[512];
    /* truncated and wrong-type requests are dropped */
    marie_pull_request_t r = req(1, 10);
    int n = marie_pull_request_t_encode(buf, 0, sizeof buf, &r);
    assert_fails(mailbox_handle_request_raw(mb, buf, (size_t)n - 3, 0), EBADMSG);
    size_t pl = pose(buf, sizeof buf, 1);
    assert_fails(mailbox_handle_request_raw(mb, buf, pl, 0), EBADMSG);
    /* a huge string length */
    n = marie_pull_request_t_encode(buf, 0, sizeof buf, &r);
    buf[24] = 0x7f;
    assert_fails(mailbox_handle_request_raw(mb, buf, (size_t)n, 0), EBADMSG);
    /* a negative string length, and a string without its NUL */
    n = marie_pull_request_t_encode(buf, 0, sizeof buf, &r);
    buf[24] = 0xff;
    assert_fails(mailbox_handle_request_raw(mb, buf, (size_t)n, 0), EBADMSG);
    n = marie_pull_request_t_encode(buf, 0, sizeof buf, &r);
    buf[28 + 1] = 'x';      /* requester "t" loses its terminator */
    assert_fails(mailbox_handle_request_raw(mb, buf, (size_t)n, 0), EBADMSG);
    /* no reply channel */
    r.reply_channel = "";
    assert_fails(mailbox_handle_request(mb, &r, 0), EINVAL);
    assert_int_equal(mailbox_stats(mb)->bad_requests, 6);
    assert_int_equal(c.bad_input, 6);
    assert_int_equal(c.nreplies, 0);
    /* another channel: answered UNKNOWN_CHANNEL */
    r = req(2, 10);
    r.channel = "OTHER";
    assert_int_equal(mailbox_handle_request(mb, &r, 0), 0);
    assert_int_equal(c.replies[0].status, MARIE_PULL_REPLY_T_STATUS_UNKNOWN_CHANNEL);
    mailbox_destroy(mb);
    cap_free(&c);
}

static void test_waiting_requests_are_bounded(void **state)
{
    capture_t c = {0};
    mailbox_t *mb = make(&c, 2);
    for (int i = 0; i < MAILBOX_MAX_WAITING + 3; i++) {
        marie_pull_request_t r = req(i, 1000);
        mailbox_handle_request(mb, &r, 0);
    }
    assert_int_equal(c.nreplies, 3);
    assert_int_equal(c.replies[0].request_id, 0);
    assert_int_equal(c.replies[0].status, MARIE_PULL_REPLY_T_STATUS_EMPTY);
    cap_free(&c);
    mailbox_destroy(mb);    /* frees the waiting requests */
}

/* Waits (2 s at most) for mb to hold a message, then pulls it on CHANNEL.PULL with request id
 * `id`, replies on CHANNEL_REPLY, and waits for *replies to turn non-zero. */
static void pull_when_held(lcm_t *lcm, mailbox_t *mb, const char *channel, int64_t id, const int *replies)
{
    for (int i = 0; i < 100 && mailbox_count(mb) == 0; i++)
        lcm_handle_timeout(lcm, 20);
    assert_int_equal(mailbox_count(mb), 1);
    char reply_ch[64], pull_ch[64];
    snprintf(reply_ch, sizeof reply_ch, "%s_REPLY", channel);
    snprintf(pull_ch, sizeof pull_ch, "%s.PULL", channel);
    marie_pull_request_t r = req(id, 100);
    r.channel = (char *)channel;
    r.reply_channel = reply_ch;
    marie_pull_request_t_publish(lcm, pull_ch, &r);
    for (int i = 0; i < 100 && !*replies; i++)
        lcm_handle_timeout(lcm, 20);
}

/* In-process use over a real bus: attach to an lcm_t the component already has. */
static int replies_seen;
static void on_reply(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_pull_reply_t r;
    if (marie_decode_checked(&marie_type_pull_reply_t, rbuf->data, rbuf->data_size, &r) < 0)
        return;
    if (r.status == MARIE_PULL_REPLY_T_STATUS_OK && r.request_id == 77)
        replies_seen++;
    marie_pull_reply_t_decode_cleanup(&r);
}

static void test_attached_mailbox_serves_the_bus(void **state)
{
    lcm_t *lcm = lcm_create(NULL);
    assert_non_null(lcm);
    mailbox_t *mb = mailbox_create("INPROC", &marie_type_pose2d_t, 2, NULL);
    assert_int_equal(mailbox_attach(mb, lcm), 0);
    assert_string_equal(mailbox_pull_channel(mb), "INPROC.PULL");
    lcm_subscription_t *sub = lcm_subscribe(lcm, "INPROC_REPLY", on_reply, NULL);
    marie_pose2d_t p = { .x = 5 };
    marie_pose2d_t_publish(lcm, "INPROC", &p);
    pull_when_held(lcm, mb, "INPROC", 77, &replies_seen);
    assert_int_equal(replies_seen, 1);
    mailbox_detach(mb);
    marie_pose2d_t_publish(lcm, "INPROC", &p);
    for (int i = 0; i < 5; i++)
        lcm_handle_timeout(lcm, 20);
    assert_int_equal(mailbox_stats(mb)->received, 1);
    lcm_unsubscribe(lcm, sub);
    mailbox_destroy(mb);
    lcm_destroy(lcm);
}

/* A channel the system file puts on shared memory: the mailbox reads the ring (LCM carries only
 * the notices) and answers a pull with the whole message. */
typedef struct {
    int whole, replies, payload_ok;
    int64_t want_size;
} shm_seen_t;

static void on_whole(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    ((shm_seen_t *)user)->whole++;
}

static void on_grid_reply(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    shm_seen_t *s = user;
    marie_pull_reply_t r;
    if (marie_decode_checked(&marie_type_pull_reply_t, rbuf->data, rbuf->data_size, &r) < 0)
        return;
    if (r.request_id == 78 && r.status == MARIE_PULL_REPLY_T_STATUS_OK) {
        s->replies++;
        marie_occupancy_grid_t g;
        if (r.size == s->want_size && marie_occupancy_grid_t_decode(r.data, 0, r.size, &g) == r.size) {
            s->payload_ok = g.ncells == 200 * 200 && g.cells[199] == 99;
            marie_occupancy_grid_t_decode_cleanup(&g);
        }
    }
    marie_pull_reply_t_decode_cleanup(&r);
}

static void test_attached_mailbox_reads_shared_memory(void **state)
{
    /* A bus liblcm reads, since the test waits with lcm_handle_timeout, with the channel on
     * shared memory as a system file's transports would put it. */
    setenv("MARIE_LCM_RECEIVE", "liblcm", 1);
    lcm_t *lcm = marie_bus_create(NULL);
    unsetenv("MARIE_LCM_RECEIVE");
    assert_non_null(lcm);
    assert_int_equal(marie_bus_set_transport(lcm, &(marie_bus_transport_t){"INSHM", "shm", 1000000, 8}), 0);
    shm_seen_t seen = {0};
    mailbox_t *mb = mailbox_create("INSHM", &marie_type_occupancy_grid_t, 2, NULL);
    assert_int_equal(mailbox_attach(mb, lcm), 0);
    lcm_subscription_t *spy = lcm_subscribe(lcm, "INSHM", on_whole, &seen);
    lcm_subscription_t *rsub = lcm_subscribe(lcm, "INSHM_REPLY", on_grid_reply, &seen);
    marie_shm_pub_t *pub = marie_shm_pub_create(lcm, "INSHM", 1000000, 4);
    assert_non_null(pub);
    static int8_t cells[200 * 200];
    for (int i = 0; i < 200 * 200; i++)
        cells[i] = (int8_t)(i % 100);
    marie_occupancy_grid_t g = { .resolution = 0.05f, .width = 200, .height = 200, .ncells = 200 * 200,
                                 .cells = cells };
    int size = marie_occupancy_grid_t_encoded_size(&g);
    uint8_t *buf = malloc((size_t)size);
    assert_int_equal(marie_occupancy_grid_t_encode(buf, 0, size, &g), size);
    seen.want_size = size;
    assert_int_equal(marie_shm_pub_publish(pub, buf, (size_t)size), 0);
    pull_when_held(lcm, mb, "INSHM", 78, &seen.replies);
    assert_int_equal(seen.replies, 1);
    assert_true(seen.payload_ok);
    assert_int_equal(seen.whole, 0);        /* the grid itself never went on LCM */
    assert_int_equal(mailbox_input_stats(mb).received, 1);
    assert_int_equal(mailbox_input_stats(mb).lost, 0);
    mailbox_detach(mb);
    marie_shm_pub_destroy(pub);
    lcm_unsubscribe(lcm, spy);
    lcm_unsubscribe(lcm, rsub);
    free(buf);
    mailbox_destroy(mb);
    marie_bus_destroy(lcm);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_keeps_newest_in_order),
        cmocka_unit_test(test_pull_answers_newest_with_age),
        cmocka_unit_test(test_empty_pull_waits_for_data),
        cmocka_unit_test(test_empty_pull_times_out_before_requester),
        cmocka_unit_test(test_mistyped_payload_is_counted_not_stored),
        cmocka_unit_test(test_untyped_mailbox_takes_any_payload),
        cmocka_unit_test(test_malformed_payload_is_counted_not_stored),
        cmocka_unit_test(test_untyped_mailbox_checks_known_types),
        cmocka_unit_test(test_bad_requests_counted),
        cmocka_unit_test(test_waiting_requests_are_bounded),
        cmocka_unit_test(test_attached_mailbox_serves_the_bus),
        cmocka_unit_test(test_attached_mailbox_reads_shared_memory),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
