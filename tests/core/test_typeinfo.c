/* test_typeinfo: the payload checker accepts what lcm-gen encodes and refuses what would make
 * lcm-gen's decoder read or free out of bounds. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#include "core/typeinfo.h"
#include "lcmtypes/marie_types.h"
#include "tests/fails.h"

static void every_type_has_a_descriptor_with_the_same_fingerprint(void **state)
{
    for (size_t i = 0; marie_types[i]; i++) {
        const marie_typeinfo_t *ti = marie_typeinfo_find(marie_types[i]->name);
        assert_non_null(ti);
        assert_true(ti->fingerprint == marie_types[i]->hash());
    }
    assert_int_equal(marie_typeinfos_count, marie_types_count);
}

static int encode(const marie_type_t *t, const void *msg, uint8_t *buf, int cap)
{
    return t->encode(buf, 0, cap, msg);
}

static void accepts_encoded_messages_and_refuses_truncations(void **state)
{
    marie_behaviour_vote_t votes[2] = {{"follow", 40, 1, 0.3, 0.1, "path"}, {"avoid", 80, 0, 0, 0, ""}};
    marie_input_age_t ages[1] = {{"pose", 0.05}};
    marie_arbitration_t a = {.utime = 1, .cycle = 2, .nvotes = 2, .votes = votes, .winner = "follow",
                             .v = 0.3, .omega = 0.1, .ninputs = 1, .inputs = ages};
    uint8_t buf[1024];
    int n = encode(&marie_type_arbitration_t, &a, buf, sizeof buf);
    assert_true(n > 0);
    const marie_typeinfo_t *ti = marie_typeinfo_find("marie.arbitration_t");
    assert_int_equal(marie_typeinfo_check(ti, buf, (size_t)n), 0);
    for (int cut = 0; cut < n; cut++)
        assert_fails(marie_typeinfo_check(ti, buf, (size_t)cut), EBADMSG);
    /* Another type's checker refuses it by fingerprint. */
    assert_fails(marie_typeinfo_check(marie_typeinfo_find("pose_cov_t"), buf, (size_t)n), EBADMSG);
}

static void refuses_strings_without_nul_and_lying_counts(void **state)
{
    marie_event_t e = {.utime = 1, .source = "src", .seq = 1, .severity = 1, .kind = "k", .text = "hello"};
    uint8_t buf[256];
    int n = encode(&marie_type_event_t, &e, buf, sizeof buf);
    const marie_typeinfo_t *ti = marie_typeinfo_find("event_t");
    assert_int_equal(marie_typeinfo_check(ti, buf, (size_t)n), 0);
    /* source is the first string: length at 16, text at 20..23 ("src\0"). */
    uint8_t bad[256];
    memcpy(bad, buf, (size_t)n);
    bad[23] = 'x';
    assert_fails(marie_typeinfo_check(ti, bad, (size_t)n), EBADMSG);
    memcpy(bad, buf, (size_t)n);
    bad[16] = 0x80;  /* negative length */
    assert_fails(marie_typeinfo_check(ti, bad, (size_t)n), EBADMSG);
    memcpy(bad, buf, (size_t)n);
    bad[19] = 0;     /* zero length: lcm-gen would hand out an unterminated string */
    assert_fails(marie_typeinfo_check(ti, bad, (size_t)n), EBADMSG);

    marie_behaviour_vote_t votes[1] = {{"follow", 40, 1, 0.3, 0.1, "path"}};
    marie_arbitration_t a = {.nvotes = 1, .votes = votes, .winner = "w", .ninputs = 0};
    n = encode(&marie_type_arbitration_t, &a, buf, sizeof buf);
    ti = marie_typeinfo_find("arbitration_t");
    /* nvotes sits after fingerprint, utime and cycle: offset 24. A huge count would make
     * lcm-gen allocate that many votes and free their unset strings on cleanup. */
    memcpy(bad, buf, (size_t)n);
    bad[24] = 0x7f;
    assert_fails(marie_typeinfo_check(ti, bad, (size_t)n), EBADMSG);
    memcpy(bad, buf, (size_t)n);
    bad[24] = 0xff;
    assert_fails(marie_typeinfo_check(ti, bad, (size_t)n), EBADMSG);
}

static void large_primitive_arrays_are_checked_by_extent(void **state)
{
    float ranges[361];
    for (int i = 0; i < 361; i++)
        ranges[i] = (float)i;
    marie_laser_scan_t s = {.nranges = 361, .ranges = ranges};
    uint8_t buf[4096];
    int n = encode(&marie_type_laser_scan_t, &s, buf, sizeof buf);
    const marie_typeinfo_t *ti = marie_typeinfo_find("laser_scan_t");
    assert_int_equal(marie_typeinfo_check(ti, buf, (size_t)n), 0);
    assert_fails(marie_typeinfo_check(ti, buf, (size_t)n - 1), EBADMSG);
}

/* marie_decode_input: a NaN or an infinity in a scalar, a primitive array or a nested struct
 * array is refused with its own counter, before anything is decoded (but in a field that gives
 * them a meaning, below); finite values pass. */
static void component_inputs_refuse_nan_and_inf_anywhere(void **state)
{
    uint8_t buf[512];
    const char *why = NULL;
    marie_pose_cov_t pc = {.utime = 1, .frame = "map", .pose = {1, 2, 3}};
    marie_pose_cov_t out;
    int n = encode(&marie_type_pose_cov_t, &pc, buf, sizeof buf);
    assert_int_equal(marie_decode_input(&marie_type_pose_cov_t, buf, (size_t)n, &out, &why), 0);
    marie_pose_cov_t_decode_cleanup(&out);
    pc.pose.theta = NAN;
    n = encode(&marie_type_pose_cov_t, &pc, buf, sizeof buf);
    assert_fails(marie_decode_input(&marie_type_pose_cov_t, buf, (size_t)n, &out, &why), EDOM);
    assert_string_equal(why, "bad_nonfinite");
    /* the plain checked decode leaves meaning to the caller (managers, tools) */
    assert_int_equal(marie_decode_checked(&marie_type_pose_cov_t, buf, (size_t)n, &out), 0);
    marie_pose_cov_t_decode_cleanup(&out);
    pc.pose.theta = 0;
    pc.cov[8] = -INFINITY;
    n = encode(&marie_type_pose_cov_t, &pc, buf, sizeof buf);
    assert_fails(marie_decode_input(&marie_type_pose_cov_t, buf, (size_t)n, &out, &why), EDOM);

    float r[3] = {1, INFINITY, 2};
    marie_laser_scan_t ls = {.range_max = 8, .nranges = 3, .ranges = r, .nintensities = 3, .intensities = r};
    marie_laser_scan_t ols;
    n = encode(&marie_type_laser_scan_t, &ls, buf, sizeof buf);
    assert_fails(marie_decode_input(&marie_type_laser_scan_t, buf, (size_t)n, &ols, &why), EDOM);
    r[1] = 3;
    n = encode(&marie_type_laser_scan_t, &ls, buf, sizeof buf);
    assert_int_equal(marie_decode_input(&marie_type_laser_scan_t, buf, (size_t)n, &ols, &why), 0);
    marie_laser_scan_t_decode_cleanup(&ols);
}

/* A laser's ranges give NaN and the infinities a meaning (REP 117: no reading, no return, nearer
 * than range_min; the field is @nonfinite in laser_scan_t.lcm): a scan with them is a scan, while
 * a NaN anywhere else in it is still refused. */
static void laser_ranges_may_be_nan_or_infinite(void **state)
{
    uint8_t buf[512];
    const char *why = NULL;
    float r[4] = {1, INFINITY, NAN, -INFINITY}, in[4] = {1, 2, 3, 4};
    marie_laser_scan_t ls = {.range_max = 8, .nranges = 4, .ranges = r, .nintensities = 4, .intensities = in};
    marie_laser_scan_t ols;
    int n = encode(&marie_type_laser_scan_t, &ls, buf, sizeof buf);
    assert_int_equal(marie_decode_input(&marie_type_laser_scan_t, buf, (size_t)n, &ols, &why), 0);
    assert_true(isinf(ols.ranges[1]) && isnan(ols.ranges[2]) && isinf(ols.ranges[3]) && ols.ranges[3] < 0);
    marie_laser_scan_t_decode_cleanup(&ols);
    in[2] = NAN;
    n = encode(&marie_type_laser_scan_t, &ls, buf, sizeof buf);
    assert_fails(marie_decode_input(&marie_type_laser_scan_t, buf, (size_t)n, &ols, &why), EDOM);
    in[2] = 3;
    ls.angle_min = NAN;
    n = encode(&marie_type_laser_scan_t, &ls, buf, sizeof buf);
    assert_fails(marie_decode_input(&marie_type_laser_scan_t, buf, (size_t)n, &ols, &why), EDOM);
    assert_string_equal(why, "bad_nonfinite");
    const marie_typeinfo_t *ti = marie_typeinfo_find("laser_scan_t");
    for (int i = 0; i < ti->nfields; i++)
        assert_int_equal(ti->fields[i].flags, strcmp(ti->fields[i].name, "ranges") ? 0 : MARIE_TFIELD_NONFINITE);
}

static void other_inputs_refuse_nan(void **state)
{
    uint8_t buf[512];
    const char *why = NULL;
    int n;
    marie_pose_cov_t out;

    marie_pose2d_t poses[2] = {{0, 0, 0}, {1, NAN, 0}};
    marie_path_t path = {.nposes = 2, .poses = poses};
    marie_path_t op;
    n = encode(&marie_type_path_t, &path, buf, sizeof buf);
    assert_fails(marie_decode_input(&marie_type_path_t, buf, (size_t)n, &op, &why), EDOM);
    /* a wrong fingerprint and a lying count keep their own counters */
    assert_fails(marie_decode_input(&marie_type_pose_cov_t, buf, (size_t)n, &out, &why), EBADMSG);
    assert_string_equal(why, "bad_fingerprint");
    assert_fails(marie_decode_input(&marie_type_path_t, buf, (size_t)n - 1, &op, &why), EBADMSG);
    assert_string_equal(why, "bad_payload");
}

/* A type's tail (the byte array a loaned publish writes apart) lies where lcm-gen's own encoder
 * puts it, for every type that has one; types with a string, a second array or an array of
 * anything but bytes have none. */
static void tails_lie_where_lcm_gen_encodes_them(void **state)
{
    int with_tail = 0;
    for (size_t i = 0; marie_types[i]; i++) {
        const marie_type_t *t = marie_types[i];
        marie_tail_t tl;
        if (marie_typeinfo_tail(marie_typeinfo_find(t->name), &tl) < 0)
            continue;
        with_tail++;
        uint8_t *msg = calloc(1, t->size), bytes[5] = {'m', 'a', 'r', 'i', 'e'}, *p = bytes, buf[4096];
        int32_t n = 5;
        memcpy(msg + tl.len_off, &n, sizeof n);
        memcpy(msg + tl.ptr_off, &p, sizeof p);
        assert_int_equal(encode(t, msg, buf, sizeof buf), (int)tl.wire_off + 5);
        assert_memory_equal(buf + tl.wire_off, bytes, 5);
        assert_int_equal(marie_wire_int(buf + tl.len_wire_off, 4), 5);
        free(msg);
    }
    marie_tail_t tl;
    assert_int_equal(marie_typeinfo_tail(marie_typeinfo_find("image_t"), &tl), 0);
    assert_int_equal(tl.wire_off, 8 + 8 + 4 + 4 + 4 + 1 + 4);
    assert_int_equal(marie_typeinfo_tail(marie_typeinfo_find("occupancy_grid_t"), &tl), 0);   /* a nested pose */
    assert_fails(marie_typeinfo_tail(marie_typeinfo_find("audio_frame_t"), &tl), ENOTSUP);     /* a string */
    assert_fails(marie_typeinfo_tail(marie_typeinfo_find("laser_scan_t"), &tl), ENOTSUP);      /* floats */
    assert_fails(marie_typeinfo_tail(marie_typeinfo_find("pose2d_t"), &tl), ENOTSUP);
    assert_true(with_tail >= 2);
}

/* A view decodes a message with a tail as a copy does, the tail's bytes where they lie in the
 * payload (not copied); a type of another shape is decoded whole; bad input is refused alike. */
static void views_point_into_the_payload(void **state)
{
    uint8_t px[300];
    for (int i = 0; i < 300; i++)
        px[i] = (uint8_t)(i * 7);
    marie_image_t img = {.utime = 5, .width = 10, .height = 10, .row_stride = 30, .format = 1, .size = 300, .data = px};
    uint8_t buf[1024];
    int n = encode(&marie_type_image_t, &img, buf, sizeof buf);
    marie_image_t v, c;
    assert_int_equal(marie_decode_view(&marie_type_image_t, buf, (size_t)n, &v, NULL), 1);
    assert_int_equal(marie_decode_input(&marie_type_image_t, buf, (size_t)n, &c, NULL), 0);
    assert_true(v.data >= buf && v.data + v.size <= buf + n);
    assert_int_equal(v.size, 300);
    assert_memory_equal(v.data, px, 300);
    assert_int_equal(v.utime, 5);
    assert_int_equal(v.row_stride, 30);
    assert_int_equal(v.format, 1);
    assert_true(c.data < buf || c.data >= buf + n);     /* the copy's are its own */
    marie_decode_cleanup_view(&marie_type_image_t, &v, 1);
    marie_decode_cleanup_view(&marie_type_image_t, &c, 0);
    assert_fails(marie_decode_view(&marie_type_image_t, buf, (size_t)n - 1, &v, NULL), EBADMSG);
    marie_pose2d_t pose = {.x = 2, .y = 3, .theta = 0.5}, pv;
    n = encode(&marie_type_pose2d_t, &pose, buf, sizeof buf);
    assert_int_equal(marie_decode_view(&marie_type_pose2d_t, buf, (size_t)n, &pv, NULL), 0);
    assert_true(pv.x == 2 && pv.theta == 0.5);
    marie_decode_cleanup_view(&marie_type_pose2d_t, &pv, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(every_type_has_a_descriptor_with_the_same_fingerprint),
        cmocka_unit_test(accepts_encoded_messages_and_refuses_truncations),
        cmocka_unit_test(refuses_strings_without_nul_and_lying_counts),
        cmocka_unit_test(large_primitive_arrays_are_checked_by_extent),
        cmocka_unit_test(component_inputs_refuse_nan_and_inf_anywhere),
        cmocka_unit_test(laser_ranges_may_be_nan_or_infinite),
        cmocka_unit_test(other_inputs_refuse_nan),
        cmocka_unit_test(tails_lie_where_lcm_gen_encodes_them),
        cmocka_unit_test(views_point_into_the_payload),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
