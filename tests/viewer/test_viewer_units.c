/* test_viewer_units: the LCM log reader against logs written by LCM itself (whole, in pieces,
 * corrupt, truncated), the JSON the page receives (any type, from its descriptor), and the
 * page's command parser. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <errno.h>
#include <math.h>
#include <cmocka.h>

#include <lcm/eventlog.h>

#include "core/lcmlog.h"
#include "tools/webcommon/vjson.h"
#include "tests/fails.h"

typedef struct {
    int events, corrupt;
    int64_t last_eventnum, last_utime;
    char channels[64][32];
    char reasons[8][160];
    uint64_t corrupt_off[8];
} seen_t;

static void on_event(void *user, const lcmlog_event_t *ev)
{
    seen_t *s = user;
    if (s->events < 64)
        snprintf(s->channels[s->events], 32, "%.*s", (int)ev->channel_len, ev->channel);
    s->events++;
    s->last_eventnum = ev->eventnum;
    s->last_utime = ev->utime;
}

static void on_corrupt(void *user, uint64_t off, const char *reason)
{
    seen_t *s = user;
    if (s->corrupt < 8) {
        snprintf(s->reasons[s->corrupt], 160, "%s", reason);
        s->corrupt_off[s->corrupt] = off;
    }
    s->corrupt++;
}

/* Ten records written by lcm_eventlog into a memory buffer. */
static uint8_t *lcm_written_log(size_t *len)
{
    char path[] = "/tmp/test_viewer_XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    close(fd);
    lcm_eventlog_t *log = lcm_eventlog_create(path, "w");
    assert_non_null(log);
    for (int i = 0; i < 10; i++) {
        char data[100];
        memset(data, 'a' + i, sizeof data);
        lcm_eventlog_event_t ev = {.eventnum = i, .timestamp = 1000 + i * 100,
                                   .channellen = i % 2 ? 5 : 4, .datalen = 10 * i,
                                   .channel = i % 2 ? "LASER" : "POSE", .data = data};
        assert_int_equal(lcm_eventlog_write_event(log, &ev), 0);
    }
    lcm_eventlog_destroy(log);
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    uint8_t *buf = malloc(1 << 16);
    *len = fread(buf, 1, 1 << 16, f);
    fclose(f);
    unlink(path);
    return buf;
}

static seen_t parse(const uint8_t *b, size_t n, size_t step)
{
    seen_t s = {0};
    lcmlog_parser_t *p = lcmlog_parser_create(on_event, on_corrupt, &s);
    assert_non_null(p);
    for (size_t off = 0; off < n; off += step)
        assert_int_equal(lcmlog_parser_feed(p, b + off, n - off < step ? n - off : step), 0);
    lcmlog_parser_finish(p);
    lcmlog_parser_destroy(p);
    return s;
}

static void reads_every_record_lcm_wrote(void **state)
{
    size_t n;
    uint8_t *b = lcm_written_log(&n);
    seen_t s = parse(b, n, n);
    assert_int_equal(s.events, 10);
    assert_int_equal(s.corrupt, 0);
    assert_string_equal(s.channels[0], "POSE");
    assert_string_equal(s.channels[1], "LASER");
    assert_int_equal(s.last_eventnum, 9);
    assert_int_equal(s.last_utime, 1900);
    free(b);
}

static void pieces_of_any_size_give_the_same_records(void **state)
{
    size_t n;
    uint8_t *b = lcm_written_log(&n);
    for (size_t step = 1; step < 80; step += 7) {
        seen_t s = parse(b, n, step);
        assert_int_equal(s.events, 10);
        assert_int_equal(s.corrupt, 0);
        assert_int_equal(s.last_utime, 1900);
    }
    free(b);
}

static void garbage_in_the_middle_loses_only_the_damaged_record(void **state)
{
    size_t n;
    uint8_t *b = lcm_written_log(&n);
    /* Overwrite the sync word and header of the 5th record (offset: 4 records before it). */
    size_t off = 0;
    for (int i = 0; i < 4; i++)
        off += 28 + (i % 2 ? 5 : 4) + 10 * i;
    memset(b + off, 0x5a, 20);
    for (size_t step = 1; step <= n; step = step * 3 + 1) {
        seen_t s = parse(b, n, step);
        assert_int_equal(s.events, 9);
        assert_int_equal(s.corrupt, 1);
        assert_int_equal(s.corrupt_off[0], off);
        assert_non_null(strstr(s.reasons[0], "no sync word"));
        assert_int_equal(s.last_utime, 1900);
    }
    free(b);
}

static void truncated_tail_is_reported_and_the_rest_kept(void **state)
{
    size_t n;
    uint8_t *b = lcm_written_log(&n);
    seen_t s = parse(b, n - 30, 64);
    assert_int_equal(s.events, 9);
    assert_int_equal(s.corrupt, 1);
    assert_non_null(strstr(s.reasons[0], "cut short"));
    /* even a cut inside the header */
    s = parse(b, n - (28 + 5 + 90) + 10, 5);
    assert_int_equal(s.events, 9);
    assert_int_equal(s.corrupt, 1);
    free(b);
}

static void impossible_lengths_resync_on_the_next_record(void **state)
{
    size_t n;
    uint8_t *b = lcm_written_log(&n);
    uint8_t *c = malloc(n + 28);
    /* a header claiming a 4 GB payload in front of a good log */
    long h = lcmlog_encode(c, 28 + 8, 0, 0, "BAD", NULL, 0);
    assert_true(h > 0);
    c[24] = c[25] = c[26] = c[27] = 0xff;
    memcpy(c + 28, b, n);
    seen_t s = parse(c, n + 28, n + 28);
    assert_int_equal(s.events, 10);
    assert_int_equal(s.corrupt, 1);
    assert_non_null(strstr(s.reasons[0], "bad record header"));
    free(b);
    free(c);
}

static void a_plausible_but_wrong_length_loses_one_record(void **state)
{
    size_t n;
    uint8_t *b = lcm_written_log(&n);
    /* the 3rd record (offset after two) claims 1 MB: the reader waits for it, and at the end
     * of the stream skips it and finds every record after it */
    size_t off = (28 + 4 + 0) + (28 + 5 + 10);
    b[off + 24] = 0; b[off + 25] = 0x10; b[off + 26] = 0; b[off + 27] = 0;
    for (size_t step = 7; step <= n; step = step * 5) {
        seen_t s = parse(b, n, step);
        assert_int_equal(s.events, 9);
        assert_int_equal(s.corrupt, 1);
        assert_int_equal(s.corrupt_off[0], off);
        assert_int_equal(s.last_utime, 1900);
    }
    free(b);
}

static void empty_and_tiny_inputs_are_harmless(void **state)
{
    seen_t s = parse((const uint8_t *)"", 0, 1);
    assert_int_equal(s.events, 0);
    assert_int_equal(s.corrupt, 0);
    s = parse((const uint8_t *)"\xed\xa1", 2, 1);
    assert_int_equal(s.events, 0);
    assert_int_equal(s.corrupt, 1);
}

/* The frame members vj_message writes for a message, as a string (static, overwritten). */
static const char *frame_of(const marie_type_t *t, const void *msg, vj_role_t role)
{
    static marie_buf_t b;
    static uint8_t buf[1 << 16];
    int n = t->encode(buf, 0, sizeof buf, msg);
    assert_true(n > 0);
    marie_buf_free(&b);
    assert_int_equal(vj_message(&b, buf, (size_t)n, role), 0);
    return b.data;
}

static void laser_json_is_the_scan_with_its_lcm_field_names(void **state)
{
    float r[3] = {1.0f, NAN, 2.25f};
    marie_laser_scan_t scan = {.utime = 5, .angle_min = -1.5f, .angle_increment = 0.5f, .range_max = 8,
                               .nranges = 3, .ranges = r};
    uint8_t buf[256];
    int n = marie_type_laser_scan_t.encode(buf, 0, sizeof buf, &scan);
    assert_true(n > 0);
    assert_ptr_equal(vj_type_of(buf, (size_t)n), &marie_type_laser_scan_t);
    assert_null(vj_type_of(buf, 4));
    assert_string_equal(frame_of(&marie_type_laser_scan_t, &scan, VJ_ROLE_OTHER),
                        ",\"k\":\"laser\",\"msg\":{\"utime\":5,\"angle_min\":-1.5,\"angle_increment\":0.5,"
                        "\"range_min\":0,\"range_max\":8,\"nranges\":3,\"ranges\":[1,null,2.25],"
                        "\"nintensities\":0,\"intensities\":[]}");
}

static void a_long_scan_reaches_the_page_thinned_with_its_stride(void **state)
{
    static float r[1441];
    for (int i = 0; i < 1441; i++)
        r[i] = (float)i;
    marie_laser_scan_t scan = {.angle_increment = 0.25f, .range_max = 2000, .nranges = 1441, .ranges = r};
    const char *s = frame_of(&marie_type_laser_scan_t, &scan, VJ_ROLE_OTHER);
    /* 1441 beams over a 720 cap: every 3rd, 481 of them, the last being beam 1440 */
    assert_non_null(strstr(s, "\"nranges\":1441,\"ranges\":[0,3,6,"));
    assert_non_null(strstr(s, ",1437,1440],\"nintensities\":0"));
    assert_non_null(strstr(s, "},\"stride\":{\"ranges\":3}"));
    int commas = 0;
    for (const char *p = strstr(s, "\"ranges\":["); *p != ']'; p++)
        commas += *p == ',';
    assert_int_equal(commas + 1, 481);
    /* the cap is the page's, for lasers: a path of as many poses is sent whole */
    static marie_pose2d_t poses[1441];
    marie_path_t path = {.nposes = 1441, .poses = poses};
    assert_null(strstr(frame_of(&marie_type_path_t, &path, VJ_ROLE_OTHER), "stride"));
}

static void pose_frame_nests_the_pose_and_says_its_role(void **state)
{
    marie_pose_cov_t p = {.utime = 7, .frame = "map", .pose = {1.25, -2.5, 0.125},
                          .cov = {0.01, 0, 0, 0, 0.04, 0, 0, 0, INFINITY}};
    assert_string_equal(frame_of(&marie_type_pose_cov_t, &p, VJ_ROLE_TRUTH),
                        ",\"k\":\"pose\",\"role\":\"truth\",\"msg\":{\"utime\":7,\"frame\":\"map\","
                        "\"pose\":{\"x\":1.25,\"y\":-2.5,\"theta\":0.125},"
                        "\"cov\":[0.01,0,0,0,0.04,0,0,0,null]}");
}

static void map_cells_go_as_base64(void **state)
{
    int8_t cells[6] = {0, 100, -1, -100, 0, 50};
    marie_occupancy_grid_t g = {.resolution = 0.05f, .width = 3, .height = 2, .origin = {-1, 2, 0},
                                .ncells = 6, .cells = cells};
    assert_string_equal(frame_of(&marie_type_occupancy_grid_t, &g, VJ_ROLE_OTHER),
                        ",\"k\":\"map\",\"msg\":{\"utime\":0,\"resolution\":0.05,\"width\":3,\"height\":2,"
                        "\"origin\":{\"x\":-1,\"y\":2,\"theta\":0},\"ncells\":6,\"cells\":\"AGT/nAAy\"}");
}

/* A type the page has no kind for is written from its descriptor all the same: nothing of the
 * viewer names its fields. */
static void a_type_the_page_never_heard_of_is_encoded_from_its_descriptor(void **state)
{
    uint8_t px[5] = {1, 2, 3, 250, 0};
    marie_image_t im = {.utime = 1700000000123456789LL, .width = 5, .height = 1, .row_stride = 5,
                        .format = MARIE_IMAGE_T_FORMAT_GRAY8, .size = 5, .data = px};
    assert_null(vj_kind(marie_typeinfo_find("marie.image_t")));
    assert_string_equal(frame_of(&marie_type_image_t, &im, VJ_ROLE_OTHER),
                        ",\"k\":\"marie.image_t\",\"msg\":{\"utime\":1700000000123456789,\"width\":5,"
                        "\"height\":1,\"row_stride\":5,\"format\":0,\"size\":5,\"data\":\"AQID+gA=\"}");
    /* nested arrays of structs, fixed 2-D arrays, booleans, escaped strings */
    marie_tag_detection_t t = {.family = "tag\"36", .id = 4, .pose_valid = 1,
                               .corners = {{1, 2}, {3, 4}, {5, 6}, {7, 8}}, .position = {0.5, 0, 2}};
    marie_tag_detections_t d = {.camera = "front", .count = 1, .tags = &t};
    const char *s = frame_of(&marie_type_tag_detections_t, &d, VJ_ROLE_OTHER);
    assert_non_null(strstr(s, "\"tags\":[{\"family\":\"tag\\\"36\",\"id\":4,"));
    assert_non_null(strstr(s, "\"corners\":[[1,2],[3,4],[5,6],[7,8]],\"center\":[0,0],\"pose_valid\":true,"
                              "\"position\":[0.5,0,2],"));
}

static void numbers_keep_the_digits_their_type_holds(void **state)
{
    /* doubles: 10 significant digits; floats: 7; "%g" forms for the tiny and the huge */
    marie_gyro_t g = {.utime = -42, .yaw_rate = -123456.789012345, .bias = 1e-5, .bias_valid = 0, .status = -3};
    assert_string_equal(frame_of(&marie_type_gyro_t, &g, VJ_ROLE_OTHER),
                        ",\"k\":\"marie.gyro_t\",\"msg\":{\"utime\":-42,\"yaw_rate\":-123456.789,\"bias\":1e-05,"
                        "\"bias_valid\":false,\"status\":-3}");
    float r[6] = {0.1f, 9.99999999f, -0.0f, 1234567.8f, 3e20f, 0.000123456789f};
    marie_laser_scan_t scan = {.nranges = 6, .ranges = r};
    assert_non_null(strstr(frame_of(&marie_type_laser_scan_t, &scan, VJ_ROLE_OTHER),
                           "\"ranges\":[0.1,10,0,1234568,3e+20,0.0001234568]"));
}

static void a_malformed_payload_appends_nothing(void **state)
{
    marie_event_t e = {.source = "a", .kind = "k", .text = "t"};
    uint8_t buf[256];
    int n = marie_type_event_t.encode(buf, 0, sizeof buf, &e);
    assert_true(n > 0);
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_puts(&b, "{");
    assert_fails(vj_message(&b, buf, (size_t)n - 1, VJ_ROLE_OTHER), EBADMSG);   /* cut short */
    buf[n - 1] = 'x';                                                               /* unterminated string */
    assert_fails(vj_message(&b, buf, (size_t)n, VJ_ROLE_OTHER), EBADMSG);
    assert_fails(vj_message(&b, "\x01\x02\x03\x04\x05\x06\x07\x08", 8, VJ_ROLE_OTHER), EBADMSG);
    assert_string_equal(b.data, "{");
    marie_buf_free(&b);
}

static void strings_are_escaped_and_binary_is_base64(void **state)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    vj_str(&b, "a\"b\\c\n\x01\xc3\xa9\xc3");     /* a stray byte: U+FFFD, the page's text stays valid */
    assert_string_equal(b.data, "\"a\\\"b\\\\c\\u000a\\u0001\xc3\xa9\\ufffd\"");
    marie_buf_reset(&b);
    vj_base64(&b, "\x00\x64\xff\x9c", 4);
    assert_string_equal(b.data, "\"AGT/nA==\"");
    marie_buf_reset(&b);
    vj_num(&b, -0.0001, 3);
    marie_buf_puts(&b, " ");
    vj_num(&b, INFINITY, 3);
    assert_string_equal(b.data, "0 null");
    marie_buf_free(&b);
}

static void page_commands_parse_or_are_refused(void **state)
{
    vj_cmd_t c;
    const char *ok = " {\"op\":\"goal\", \"x\": 1.5, \"y\":-2e1, \"th\":0, \"flag\":true} ";
    assert_int_equal(vj_cmd_parse(&c, ok, strlen(ok)), 0);
    assert_string_equal(vj_cmd_str(&c, "op"), "goal");
    double v;
    assert_true(vj_cmd_num(&c, "y", &v));
    assert_true(v == -20);
    assert_true(vj_cmd_num(&c, "flag", &v) && v == 1);
    assert_null(vj_cmd_str(&c, "x"));
    const char *bad[] = {"", "[]", "{\"op\":}", "{\"op\":\"a\"", "{\"op\":\"a\"} x", "{\"a\":{}}",
                         "{\"op\":nan}", "{\"op\":\"\\u0041\"}", "{\"a\":1,\"b\":2,\"c\":3,\"d\":4,\"e\":5,\"f\":6,\"g\":7,\"h\":8,\"i\":9}"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
        assert_fails(vj_cmd_parse(&c, bad[i], strlen(bad[i])), EBADMSG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(reads_every_record_lcm_wrote),
        cmocka_unit_test(pieces_of_any_size_give_the_same_records),
        cmocka_unit_test(garbage_in_the_middle_loses_only_the_damaged_record),
        cmocka_unit_test(truncated_tail_is_reported_and_the_rest_kept),
        cmocka_unit_test(impossible_lengths_resync_on_the_next_record),
        cmocka_unit_test(a_plausible_but_wrong_length_loses_one_record),
        cmocka_unit_test(empty_and_tiny_inputs_are_harmless),
        cmocka_unit_test(laser_json_is_the_scan_with_its_lcm_field_names),
        cmocka_unit_test(a_long_scan_reaches_the_page_thinned_with_its_stride),
        cmocka_unit_test(pose_frame_nests_the_pose_and_says_its_role),
        cmocka_unit_test(map_cells_go_as_base64),
        cmocka_unit_test(a_type_the_page_never_heard_of_is_encoded_from_its_descriptor),
        cmocka_unit_test(numbers_keep_the_digits_their_type_holds),
        cmocka_unit_test(a_malformed_payload_appends_nothing),
        cmocka_unit_test(strings_are_escaped_and_binary_is_base64),
        cmocka_unit_test(page_commands_parse_or_are_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
