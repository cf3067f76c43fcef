/* test_sharedmap: the SharedMap store and its log without a bus: operations, reload after
 * close, torn tails, compaction, typed values, malformed requests. */
#include <errno.h>
#include <fcntl.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "ca/sharedmap.h"
#include "ca/sharedmap_log.h"
#include "lcmtypes/marie_gyro_t.h"
#include "lcmtypes/marie_pose2d_t.h"
#include "lcmtypes/marie_sharedmap_reply_t.h"
#include "tests/fails.h"

#define MAXR 16
typedef struct {
    marie_sharedmap_reply_t replies[MAXR];
    void *raw[MAXR];
    int nreplies, nsnapshots, bad_input;
} capture_t;

static int cap_publish(void *user, const char *channel, const void *buf, size_t len)
{
    capture_t *c = user;
    if (strcmp(channel, "SNAP") == 0) {
        c->nsnapshots++;
        return 0;
    }
    assert_true(c->nreplies < MAXR);
    c->raw[c->nreplies] = malloc(len);
    memcpy(c->raw[c->nreplies], buf, len);
    assert_int_equal(marie_decode_checked(&marie_type_sharedmap_reply_t, buf, len, &c->replies[c->nreplies]), 0);
    c->nreplies++;
    return 0;
}

static void cap_note(void *user, ca_note_kind_t kind, const char *counter, int64_t n, const char *text)
{
    capture_t *c = user;
    if (kind == CA_NOTE_BAD_INPUT)
        c->bad_input++;
}

static void cap_free(capture_t *c)
{
    for (int i = 0; i < c->nreplies; i++)
    {
        marie_sharedmap_reply_t_decode_cleanup(&c->replies[i]);
        free(c->raw[i]);
    }
    memset(c, 0, sizeof *c);
}

static char dir[256], path[300];

static int setup(void **state)
{
    snprintf(dir, sizeof dir, "/tmp/marie-test-sm-XXXXXX");
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/map.log", dir);
    return 0;
}

static int teardown(void **state)
{
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    return system(cmd);
}

static size_t pose(uint8_t *buf, double x)
{
    marie_pose2d_t p = { .x = x };
    return (size_t)marie_pose2d_t_encode(buf, 0, 256, &p);
}

static double value_x(const sharedmap_t *sm, const char *key)
{
    sharedmap_value_t v;
    assert_int_equal(sharedmap_get(sm, key, &v), 0);
    assert_string_equal(v.type, "marie.pose2d_t");
    marie_pose2d_t p;
    assert_true(marie_pose2d_t_decode(v.data, 0, (int)v.len, &p) >= 0);
    return p.x;
}

static void test_set_get_delete_survive_reopen(void **state)
{
    uint8_t buf[256];
    sharedmap_t *sm = sharedmap_open(path, NULL);
    assert_non_null(sm);
    assert_int_equal(sharedmap_set(sm, "b", "marie.pose2d_t", buf, pose(buf, 2), 10), 0);
    assert_int_equal(sharedmap_set(sm, "a", "marie.pose2d_t", buf, pose(buf, 1), 11), 0);
    assert_int_equal(sharedmap_set(sm, "c", "marie.pose2d_t", buf, pose(buf, 3), 12), 0);
    assert_int_equal(sharedmap_set(sm, "a", "marie.pose2d_t", buf, pose(buf, 4), 13), 0);
    assert_int_equal(sharedmap_delete(sm, "c"), 0);
    assert_fails(sharedmap_delete(sm, "c"), ENOENT);
    assert_int_equal(sharedmap_version(sm), 5);
    sharedmap_close(sm);

    sm = sharedmap_open(path, NULL);
    assert_non_null(sm);
    assert_int_equal(sharedmap_size(sm), 2);
    assert_true(value_x(sm, "a") == 4.0);
    assert_true(value_x(sm, "b") == 2.0);
    assert_fails(sharedmap_get(sm, "c", NULL), ENOENT);
    assert_int_equal(sharedmap_version(sm), 5);
    sharedmap_value_t v;
    assert_int_equal(sharedmap_entry(sm, 0, &v), 0);
    assert_string_equal(v.key, "a");
    assert_int_equal(v.set_utime, 13);
    assert_int_equal(sharedmap_stats(sm)->records_loaded, 5);
    sharedmap_close(sm);
}

static void test_one_sharedmap_per_log(void **state)
{
    sharedmap_t *a = sharedmap_open(path, NULL);
    assert_non_null(a);
    assert_null(sharedmap_open(path, NULL));
    assert_int_equal(errno, EBUSY);
    sharedmap_close(a);
    a = sharedmap_open(path, NULL);
    assert_non_null(a);
    sharedmap_close(a);
}

static void test_torn_tail_is_cut_off(void **state)
{
    uint8_t buf[256];
    sharedmap_t *sm = sharedmap_open(path, NULL);
    assert_int_equal(sharedmap_set(sm, "k1", "marie.pose2d_t", buf, pose(buf, 1), 1), 0);
    assert_int_equal(sharedmap_set(sm, "k2", "marie.pose2d_t", buf, pose(buf, 2), 1), 0);
    sharedmap_close(sm);
    /* a write cut short by a crash: the third record, never acknowledged, lost its end */
    uint8_t rec[512];
    sharedmap_log_rec_t r3 = { SHAREDMAP_LOG_SET, 3, 3, 1, "k2", "marie.pose2d_t", buf, (size_t)pose(buf, 9) };
    size_t n3 = sharedmap_log_encode(rec, &r3);
    int fd = open(path, O_WRONLY | O_APPEND);
    assert_true(write(fd, rec, n3 - 5) == (ssize_t)(n3 - 5));
    close(fd);
    sm = sharedmap_open(path, NULL);
    assert_non_null(sm);
    assert_int_equal(sharedmap_size(sm), 2);
    assert_true(value_x(sm, "k2") == 2.0);
    assert_int_equal(sharedmap_stats(sm)->tail_bytes_dropped, (int64_t)(n3 - 5));
    /* new writes go after the last good record */
    assert_int_equal(sharedmap_set(sm, "k3", "marie.pose2d_t", buf, pose(buf, 3), 1), 0);
    sharedmap_close(sm);
    /* a header cut short (the record marker and a few bytes) is dropped too */
    fd = open(path, O_WRONLY | O_APPEND);
    assert_true(write(fd, "\xa7SMR\x00\x00", 6) == 6);
    close(fd);
    sm = sharedmap_open(path, NULL);
    assert_int_equal(sharedmap_size(sm), 3);
    assert_true(value_x(sm, "k3") == 3.0);
    assert_int_equal(sharedmap_stats(sm)->tail_bytes_dropped, 6);
    /* a torn tail is no damage: nothing skipped, nothing kept aside */
    assert_int_equal(sharedmap_load_report(sm)->nranges, 0);
    assert_null(sharedmap_kept_aside(sm));
    sharedmap_close(sm);
}

static void test_refuses_foreign_file(void **state)
{
    FILE *f = fopen(path, "w");
    fputs("not a sharedmap log\n", f);
    fclose(f);
    assert_null(sharedmap_open(path, NULL));
    assert_int_equal(errno, EINVAL);
}

static void test_compaction_keeps_live_values(void **state)
{
    uint8_t buf[256];
    sharedmap_t *sm = sharedmap_open(path, NULL);
    sharedmap_set_compaction(sm, 64);
    for (int i = 0; i < 600; i++) {
        char key[32];
        snprintf(key, sizeof key, "k%d", i % 10);
        assert_int_equal(sharedmap_set(sm, key, "marie.pose2d_t", buf, pose(buf, i), i), 0);
    }
    assert_true(sharedmap_stats(sm)->compactions >= 1);
    sharedmap_close(sm);
    struct stat st;
    assert_int_equal(stat(path, &st), 0);
    assert_true(st.st_size < 100 * 80);        /* not 600 records */
    sm = sharedmap_open(path, NULL);
    assert_int_equal(sharedmap_size(sm), 10);
    assert_true(value_x(sm, "k9") == 599.0);
    assert_true(value_x(sm, "k0") == 590.0);
    assert_int_equal(sharedmap_version(sm), 600);
    sharedmap_close(sm);
}

static void test_values_are_checked_against_their_type(void **state)
{
    uint8_t buf[256];
    sharedmap_t *sm = sharedmap_open(NULL, NULL);
    marie_gyro_t g = {0};
    int n = marie_gyro_t_encode(buf, 0, sizeof buf, &g);
    assert_fails(sharedmap_set(sm, "k", "marie.pose2d_t", buf, (size_t)n, 1), EBADMSG);
    assert_int_equal(sharedmap_set(sm, "k", "marie.gyro_t", buf, (size_t)n, 1), 0);
    assert_int_equal(sharedmap_set(sm, "k", "other.type_t", buf, (size_t)n, 1), 0);
    assert_fails(sharedmap_set(sm, "k", "marie.gyro_t", buf, 4, 1), EINVAL);
    assert_fails(sharedmap_set(sm, "", "marie.gyro_t", buf, (size_t)n, 1), EINVAL);
    sharedmap_close(sm);
}

static void test_requests_are_answered(void **state)
{
    capture_t c = {0};
    ca_sink_t sink = { .note = cap_note, .publish = cap_publish, .user = &c };
    sharedmap_t *sm = sharedmap_open(path, &sink);
    sharedmap_set_snapshot(sm, "SNAP", "sm", 0);
    uint8_t buf[256];
    size_t n = pose(buf, 7);
    marie_sharedmap_request_t req = { .request_id = 1, .client = "t", .reply_channel = "R",
        .op = MARIE_SHAREDMAP_REQUEST_T_OP_SET, .key = "mission/goal", .type = "marie.pose2d_t",
        .size = (int32_t)n, .data = buf };
    assert_int_equal(sharedmap_handle_request(sm, &req, 100), 0);
    req = (marie_sharedmap_request_t){ .request_id = 2, .client = "t", .reply_channel = "R",
        .op = MARIE_SHAREDMAP_REQUEST_T_OP_GET, .key = "mission/goal", .type = "" };
    assert_int_equal(sharedmap_handle_request(sm, &req, 600), 0);
    req.request_id = 3;
    req.op = MARIE_SHAREDMAP_REQUEST_T_OP_LIST;
    req.key = "mission/";
    assert_int_equal(sharedmap_handle_request(sm, &req, 600), 0);
    req.request_id = 4;
    req.op = MARIE_SHAREDMAP_REQUEST_T_OP_GET;
    req.key = "nope";
    assert_fails(sharedmap_handle_request(sm, &req, 600), ENOENT);
    req.request_id = 5;
    req.op = 99;
    assert_fails(sharedmap_handle_request(sm, &req, 600), EINVAL);

    assert_int_equal(c.nreplies, 5);
    assert_int_equal(c.replies[0].status, MARIE_SHAREDMAP_REPLY_T_STATUS_OK);
    assert_int_equal(c.replies[0].version, 1);
    assert_int_equal(c.replies[1].status, MARIE_SHAREDMAP_REPLY_T_STATUS_OK);
    assert_int_equal(c.replies[1].age_us, 500);
    assert_string_equal(c.replies[1].type, "marie.pose2d_t");
    assert_int_equal(c.replies[1].size, (int)n);
    assert_memory_equal(c.replies[1].data, buf, n);
    assert_int_equal(c.replies[2].nkeys, 1);
    assert_string_equal(c.replies[2].keys[0], "mission/goal");
    assert_int_equal(c.replies[3].status, MARIE_SHAREDMAP_REPLY_T_STATUS_NOT_FOUND);
    assert_int_equal(c.replies[4].status, MARIE_SHAREDMAP_REPLY_T_STATUS_BAD_REQUEST);
    assert_int_equal(c.replies[4].request_id, 5);
    assert_int_equal(c.nsnapshots, 1);      /* one change */

    /* undecodable: dropped and counted */
    assert_fails(sharedmap_handle_request_raw(sm, buf, n, 0), EBADMSG);
    assert_fails(sharedmap_handle_request_raw(sm, "", 0, 0), EBADMSG);
    assert_int_equal(c.nreplies, 5);
    assert_int_equal(c.bad_input, 3);
    assert_int_equal(sharedmap_stats(sm)->bad_requests, 3);
    sharedmap_close(sm);
    cap_free(&c);
}

static void test_snapshots_are_rate_limited(void **state)
{
    capture_t c = {0};
    ca_sink_t sink = { .note = cap_note, .publish = cap_publish, .user = &c };
    sharedmap_t *sm = sharedmap_open(NULL, &sink);
    sharedmap_set_snapshot(sm, "SNAP", "sm", 50000);
    uint8_t buf[256];
    size_t n = pose(buf, 7);
    marie_sharedmap_request_t req = { .request_id = 1, .client = "t", .reply_channel = "R",
        .op = MARIE_SHAREDMAP_REQUEST_T_OP_SET, .key = "k", .type = "marie.pose2d_t",
        .size = (int32_t)n, .data = buf };
    for (int i = 0; i < 10; i++)
        sharedmap_handle_request(sm, &req, 100000 + i * 1000);
    assert_int_equal(c.nsnapshots, 1);
    sharedmap_tick(sm, 120000);
    assert_int_equal(c.nsnapshots, 1);
    sharedmap_tick(sm, 150000);
    assert_int_equal(c.nsnapshots, 2);
    sharedmap_tick(sm, 250000);             /* nothing changed since */
    assert_int_equal(c.nsnapshots, 2);
    sharedmap_close(sm);
    cap_free(&c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_set_get_delete_survive_reopen, setup, teardown),
        cmocka_unit_test_setup_teardown(test_torn_tail_is_cut_off, setup, teardown),
        cmocka_unit_test_setup_teardown(test_one_sharedmap_per_log, setup, teardown),
        cmocka_unit_test_setup_teardown(test_refuses_foreign_file, setup, teardown),
        cmocka_unit_test_setup_teardown(test_compaction_keeps_live_values, setup, teardown),
        cmocka_unit_test(test_values_are_checked_against_their_type),
        cmocka_unit_test_setup_teardown(test_requests_are_answered, setup, teardown),
        cmocka_unit_test(test_snapshots_are_rate_limited),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
