/* test_xb_codec: the XML bridge's type-driven codec and document parser against lcm-gen's code. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "adapters/xml_bridge/xb_codec.h"
#include "adapters/xml_bridge/xb_doc.h"
#include "lcmtypes/marie_types.h"
#include "tests/xml_bridge/xb_canon.h"

/* Parses exactly one document and keeps a deep copy-free handle: the callback encodes. */
typedef struct {
    const marie_typeinfo_t *type;
    marie_buf_t out;
    xb_error_t err;
    int docs, rc;
    char root[64];
} enc_ctx_t;

static void encode_cb(void *user, xb_node_t *root)
{
    enc_ctx_t *c = user;
    c->docs++;
    snprintf(c->root, sizeof c->root, "%s", root->name);
    c->rc = xb_encode(c->type, root, &c->out, &c->err);
}

/* XML fields text -> LCM payload through the document parser and the encoder. */
static int xml_to_lcm(const marie_typeinfo_t *t, const char *fields, marie_buf_t *out, xb_error_t *err)
{
    enc_ctx_t c = { .type = t, .rc = -99 };
    marie_buf_init(&c.out, 1 << 24);
    xb_doc_parser_t *p = xb_doc_parser_create(NULL, encode_cb, &c);
    assert_non_null(p);
    assert_int_equal(xb_doc_parser_feed(p, "<message>", 9), 0);
    assert_int_equal(xb_doc_parser_feed(p, fields, strlen(fields)), 0);
    assert_int_equal(xb_doc_parser_feed(p, "</message>", 10), 0);
    assert_int_equal(c.docs, 1);
    xb_doc_parser_destroy(p);
    *out = c.out;
    if (err)
        *err = c.err;
    return c.rc;
}

static const marie_type_t *registry(const char *name)
{
    for (size_t i = 0; marie_types[i]; i++)
        if (strcmp(marie_types[i]->name, name) == 0)
            return marie_types[i];
    return NULL;
}

static void test_fingerprints_match_lcm_gen(void **state)
{
    assert_true(marie_typeinfos_count >= marie_types_count);
    for (size_t i = 0; marie_types[i]; i++) {
        const marie_typeinfo_t *t = marie_typeinfo_find(marie_types[i]->name);
        assert_non_null(t);
        if (t->fingerprint != marie_types[i]->hash())
            fail_msg("%s: fingerprint %llx, lcm-gen says %llx", t->name,
                     (unsigned long long)t->fingerprint, (unsigned long long)marie_types[i]->hash());
    }
    assert_ptr_equal(marie_typeinfo_find("pose_cov_t"), marie_typeinfo_find("marie.pose_cov_t"));
    assert_null(marie_typeinfo_find("marie.no_such_t"));
}

/* For every type and many samples: our encoding decodes with lcm-gen's C code to the same
 * fields, lcm-gen re-encodes it to the same bytes, and our XML of it encodes back identically. */
static void test_every_type_round_trips_field_by_field(void **state)
{
    int checked = 0;
    for (size_t i = 0; marie_typeinfos[i]; i++) {
        const marie_typeinfo_t *t = marie_typeinfos[i];
        const marie_type_t *mt = registry(t->name);
        assert_non_null(mt);
        for (uint32_t seed = 1; seed <= 40; seed++) {
            marie_buf_t xml;
            xb_canon_t want, got;
            marie_buf_init(&xml, 0);
            xb_canon_init(&want);
            xb_canon_init(&got);
            xb_sample(t, seed * 7919u + (uint32_t)i, &xml, &want);
            marie_buf_put(&xml, "", 1);

            marie_buf_t b1;
            xb_error_t err = { "", "" };
            if (xml_to_lcm(t, xml.data, &b1, &err) != 0)
                fail_msg("%s seed %u: %s %s\n%s", t->name, seed, err.code, err.reason, xml.data);

            void *msg = calloc(1, mt->size);
            assert_int_equal(mt->decode(b1.data, 0, (int)b1.len, msg), (int)b1.len);
            assert_int_equal(xb_struct_dump(&got, t->name, msg), 0);
            if (strcmp(xb_canon_text(&want), xb_canon_text(&got)) != 0)
                fail_msg("%s seed %u: fields differ\nwant:\n%s\ngot:\n%s\nxml: %s", t->name, seed,
                         xb_canon_text(&want), xb_canon_text(&got), xml.data);

            int n = mt->encoded_size(msg);
            assert_int_equal(n, (int)b1.len);
            char *b2 = malloc((size_t)n);
            assert_int_equal(mt->encode(b2, 0, n, msg), n);
            assert_memory_equal(b2, b1.data, (size_t)n);

            /* lcm-gen's bytes -> our XML -> our bytes again */
            marie_buf_t x2, b3;
            marie_buf_init(&x2, 0);
            if (xb_decode(t, b2, (size_t)n, &x2, &err) != 0)
                fail_msg("%s: decode: %s", t->name, err.reason);
            marie_buf_put(&x2, "", 1);
            assert_int_equal(xml_to_lcm(t, x2.data, &b3, &err), 0);
            assert_int_equal(b3.len, (size_t)n);
            assert_memory_equal(b3.data, b2, (size_t)n);

            /* Every truncation of a valid payload is refused cleanly. */
            if (seed <= 2)
                for (int cut = 0; cut < n; cut++) {
                    marie_buf_t x3;
                    marie_buf_init(&x3, 0);
                    assert_int_equal(xb_decode(t, b2, (size_t)cut, &x3, &err), -1);
                    assert_int_equal(x3.len, 0);
                    marie_buf_free(&x3);
                }

            mt->decode_cleanup(msg);
            free(msg);
            free(b2);
            marie_buf_free(&x2);
            marie_buf_free(&b3);
            marie_buf_free(&b1);
            marie_buf_free(&xml);
            xb_canon_free(&want);
            xb_canon_free(&got);
            checked++;
        }
    }
    assert_true(checked >= 40 * 20);
}

static void expect_error(const char *type, const char *fields, const char *code)
{
    marie_buf_t out;
    xb_error_t err = { "", "" };
    const marie_typeinfo_t *t = marie_typeinfo_find(type);
    assert_non_null(t);
    if (xml_to_lcm(t, fields, &out, &err) != -1)
        fail_msg("%s accepted: %s", type, fields);
    if (strcmp(err.code, code) != 0)
        fail_msg("%s: got %s (%s), want %s", fields, err.code, err.reason, code);
    assert_int_equal(out.len, 0);
    marie_buf_free(&out);
}

static void test_wrong_fields_are_refused_with_a_reason(void **state)
{
    expect_error("pose2d_t", "<x>1</x><z>2</z>", "unknown-field");
    expect_error("pose2d_t", "<x>one</x>", "bad-value");
    expect_error("pose2d_t", "<x>1</x><x>2</x>", "bad-value");
    expect_error("pose2d_t", "<x><y>1</y></x>", "unknown-field");
    expect_error("pose2d_t", "stray text<x>1</x>", "bad-value");
    expect_error("gyro_t", "<status>128</status>", "bad-value");
    expect_error("gyro_t", "<bias_valid>maybe</bias_valid>", "bad-value");
    expect_error("gyro_t", "<utime>99999999999999999999</utime>", "bad-value");
    expect_error("gyro_t", "<utime>1.5</utime>", "bad-value");
    expect_error("laser_scan_t", "<angle_min>1e39</angle_min>", "bad-value");
    expect_error("laser_scan_t", "<ranges>1 2 x</ranges>", "bad-value");
    expect_error("laser_scan_t", "<nranges>3</nranges><ranges>1 2</ranges>", "bad-length");
    expect_error("laser_scan_t", "<nranges>-1</nranges>", "bad-length");
    expect_error("pose_cov_t", "<cov>1 2 3</cov>", "bad-length");
    expect_error("pose_cov_t", "<pose><x>1</x><w>2</w></pose>", "unknown-field");
    expect_error("image_t", "<data>not base64!</data>", "bad-value");
    expect_error("image_t", "<data encoding=\"hex\">00</data>", "bad-value");
    expect_error("path_t", "<poses><pose/></poses>", "unknown-field");
    expect_error("path_t", "<poses>text</poses>", "bad-value");
    expect_error("event_t", "<text encoding=\"base64\">YQBi</text>", "bad-value");  /* NUL */
    expect_error("event_t", "<text encoding=\"rot13\">a</text>", "bad-value");
}

static void test_defaults_and_inferred_lengths(void **state)
{
    const marie_typeinfo_t *t = marie_typeinfo_find("marie.laser_scan_t");
    marie_buf_t out;
    assert_int_equal(xml_to_lcm(t, "<ranges> 1 2.5\n 3 </ranges><nintensities>0</nintensities>", &out, NULL), 0);
    marie_laser_scan_t m;
    assert_int_equal(marie_laser_scan_t_decode(out.data, 0, (int)out.len, &m), (int)out.len);
    assert_int_equal(m.nranges, 3);
    assert_true(m.ranges[1] == 2.5f);
    assert_int_equal(m.nintensities, 0);
    assert_int_equal(m.utime, 0);
    marie_laser_scan_t_decode_cleanup(&m);
    marie_buf_free(&out);

    /* An absent fixed array is zeros; an absent message is all defaults. */
    t = marie_typeinfo_find("marie.pose_cov_t");
    marie_buf_init(&out, 0);
    xb_error_t err;
    assert_int_equal(xb_encode(t, NULL, &out, &err), 0);
    marie_pose_cov_t pc;
    assert_int_equal(marie_pose_cov_t_decode(out.data, 0, (int)out.len, &pc), (int)out.len);
    assert_string_equal(pc.frame, "");
    assert_true(pc.cov[8] == 0.0);
    marie_pose_cov_t_decode_cleanup(&pc);
    marie_buf_free(&out);
}

static void test_decode_refuses_foreign_and_oversized_payloads(void **state)
{
    const marie_typeinfo_t *pose = marie_typeinfo_find("marie.pose2d_t");
    const marie_typeinfo_t *cov = marie_typeinfo_find("marie.pose_cov_t");
    marie_buf_t out, x;
    xb_error_t err;
    assert_int_equal(xml_to_lcm(pose, "<x>1</x>", &out, NULL), 0);
    marie_buf_init(&x, 0);
    assert_int_equal(xb_decode(cov, out.data, out.len, &x, &err), -1);
    assert_string_equal(err.code, "bad-fingerprint");
    marie_buf_free(&x);
    marie_buf_init(&x, 10);
    assert_int_equal(xb_decode(pose, out.data, out.len, &x, &err), -1);
    assert_string_equal(err.code, "too-large");
    assert_int_equal(x.len, 0);
    marie_buf_free(&x);
    marie_buf_free(&out);

    /* A length field claiming more elements than the payload holds. */
    marie_laser_scan_t m = { 0 };
    float r[2] = { 1, 2 };
    m.nranges = 2;
    m.ranges = r;
    uint8_t buf[256];
    int n = marie_laser_scan_t_encode(buf, 0, sizeof buf, &m);
    assert_true(n > 0);
    buf[8 + 8 + 16 + 3] = 0x7f;     /* nranges low byte */
    buf[8 + 8 + 16 + 0] = 0x7f;     /* nranges high byte: huge */
    marie_buf_init(&x, 0);
    assert_int_equal(xb_decode(marie_typeinfo_find("laser_scan_t"), buf, (size_t)n, &x, &err), -1);
    assert_string_equal(err.code, "bad-message");
    marie_buf_free(&x);
}

static void test_strings_xml_cannot_carry_use_base64(void **state)
{
    marie_event_t e = { 0 };
    e.source = (char *)"a\x01z";
    e.kind = (char *)"k\xff";
    e.text = (char *)"<&>\"\t\n\r";
    uint8_t buf[256];
    int n = marie_event_t_encode(buf, 0, sizeof buf, &e);
    marie_buf_t x, out;
    xb_error_t err;
    marie_buf_init(&x, 0);
    assert_int_equal(xb_decode(marie_typeinfo_find("event_t"), buf, (size_t)n, &x, &err), 0);
    marie_buf_put(&x, "", 1);
    assert_non_null(strstr(x.data, "<source encoding=\"base64\">YQF6</source>"));
    assert_non_null(strstr(x.data, "<text>&lt;&amp;&gt;&quot;&#9;&#10;&#13;</text>"));
    assert_null(strchr(x.data, '\n'));
    assert_int_equal(xml_to_lcm(marie_typeinfo_find("event_t"), x.data, &out, NULL), 0);
    assert_int_equal(out.len, (size_t)n);
    assert_memory_equal(out.data, buf, (size_t)n);
    marie_buf_free(&x);
    marie_buf_free(&out);
}

/* ---- document stream ---- */

typedef struct {
    int docs;
    char names[16][32];
} docs_t;

static void count_cb(void *user, xb_node_t *root)
{
    docs_t *d = user;
    if (d->docs < 16)
        snprintf(d->names[d->docs], 32, "%s", root->name);
    d->docs++;
}

static void test_stream_is_cut_into_documents(void **state)
{
    const char *s = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<a x=\"1\"><b>t</b></a>\n"
                    "  <c/><?xml version=\"1.0\"?><d><!-- note --><e/></d>\r\n<f>";
    /* Whole, then byte by byte: the same documents come out. */
    for (int step = 0; step < 2; step++) {
        docs_t d = { 0 };
        xb_doc_parser_t *p = xb_doc_parser_create(NULL, count_cb, &d);
        if (step == 0) {
            assert_int_equal(xb_doc_parser_feed(p, s, strlen(s)), 0);
        } else {
            for (size_t i = 0; i < strlen(s); i++)
                assert_int_equal(xb_doc_parser_feed(p, s + i, 1), 0);
        }
        assert_int_equal(d.docs, 3);
        assert_string_equal(d.names[0], "a");
        assert_string_equal(d.names[1], "c");
        assert_string_equal(d.names[2], "d");
        assert_true(xb_doc_parser_partial(p));
        assert_int_equal(xb_doc_parser_feed(p, "</f>", 4), 0);
        assert_int_equal(d.docs, 4);
        assert_false(xb_doc_parser_partial(p));
        xb_doc_parser_destroy(p);
    }
}

typedef struct {
    size_t text_len, children;
    int ok, docs;
} textdoc_t;

static void text_cb(void *user, xb_node_t *root)
{
    textdoc_t *d = user;
    d->docs++;
    d->text_len = root->text_len;
    d->children = (size_t)root->nchildren;
    d->ok = strlen(root->text) == root->text_len;
    for (size_t i = 0; d->ok && i < root->text_len; i++)
        d->ok = root->text[i] == (root->first ? "xy"[i % 2] : "0123456789\n"[i % 11]);
}

/* A long text, or a text interleaved with elements, costs memory linear in the document, in
 * whatever pieces it comes, and all of it goes back when the document ends. */
static void test_long_texts_cost_their_length(void **state)
{
    xb_doc_limits_t lim = { 4u << 20, 8 };
    textdoc_t d = { 0 };
    xb_doc_parser_t *p = xb_doc_parser_create(&lim, text_cb, &d);
    size_t idle = xb_doc_parser_memory(p);
    enum { TEXT = 1000000, PIECE = 100 };
    char piece[PIECE];
    assert_int_equal(xb_doc_parser_feed(p, "<a>", 3), 0);
    for (size_t off = 0; off < TEXT; off += PIECE) {
        for (size_t i = 0; i < PIECE; i++)
            piece[i] = "0123456789\n"[(off + i) % 11];
        assert_int_equal(xb_doc_parser_feed(p, piece, PIECE), 0);
    }
    size_t held = xb_doc_parser_memory(p);
    print_message("1 MB text in %d-byte pieces: parser holds %zu bytes\n", PIECE, held);
    assert_true(held < TEXT + TEXT / 2 + idle + 65536);
    assert_int_equal(xb_doc_parser_feed(p, "</a>", 4), 0);
    assert_int_equal(d.docs, 1);
    assert_int_equal(d.text_len, TEXT);
    assert_true(d.ok);
    assert_true(xb_doc_parser_memory(p) <= idle + 65536);

    /* Mixed content: every piece of text follows a child element. */
    enum { PAIRS = 50000 };
    assert_int_equal(xb_doc_parser_feed(p, "<a>", 3), 0);
    for (int i = 0; i < PAIRS; i++)
        assert_int_equal(xb_doc_parser_feed(p, "xy<b/>", 6), 0);
    held = xb_doc_parser_memory(p);
    print_message("%d text pieces between elements (%d bytes): parser holds %zu bytes\n", PAIRS,
                  PAIRS * 6, held);
    assert_true(held < (size_t)PAIRS * 6 * 40);     /* a node per 4-byte element dominates */
    assert_int_equal(xb_doc_parser_feed(p, "</a>", 4), 0);
    assert_int_equal(d.docs, 2);
    assert_int_equal(d.text_len, 2 * PAIRS);
    assert_int_equal(d.children, PAIRS);
    assert_true(d.ok);
    xb_doc_parser_destroy(p);
}

static void expect_fatal(const char *s, const xb_doc_limits_t *lim, const char *code, int docs_before)
{
    docs_t d = { 0 };
    xb_doc_parser_t *p = xb_doc_parser_create(lim, count_cb, &d);
    assert_int_equal(xb_doc_parser_feed(p, s, strlen(s)), -1);
    assert_string_equal(xb_doc_parser_error(p)->code, code);
    assert_int_equal(d.docs, docs_before);
    assert_int_equal(xb_doc_parser_feed(p, "<a/>", 4), -1);     /* stays failed */
    xb_doc_parser_destroy(p);
}

static void test_bad_streams_fail_once_and_stay_failed(void **state)
{
    xb_doc_limits_t lim = { 64, 4 };
    expect_fatal("<a><b></a>", NULL, "malformed", 0);
    expect_fatal("<a/>junk<b/>", NULL, "malformed", 1);
    expect_fatal("<a/><!DOCTYPE a [<!ENTITY x \"y\">]><a>&x;</a>", NULL, "malformed", 1);
    expect_fatal("<a><b><c><d><e/></d></c></b></a>", &lim, "too-deep", 0);
    expect_fatal("<a>0123456789012345678901234567890123456789012345678901234567890123456789</a>",
                 &lim, "too-large", 0);
    expect_fatal("<a/><b x=\"0123456789012345678901234567890123456789012345678901234567890123456789",
                 &lim, "too-large", 1);
    expect_fatal("<a>\xff</a>", NULL, "malformed", 0);
    expect_fatal("<a>&#1;</a>", NULL, "malformed", 0);
}

/* What the bridge wrote before it had its own fast paths: the shortest of %.15g..%.17g that
 * reads back. */
static void printf_real(double v, char *buf, size_t size)
{
    for (int prec = 15; prec <= 17; prec++) {
        snprintf(buf, size, "%.*g", prec, v);
        if (strtod(buf, NULL) == v)
            return;
    }
}

static void expect_real_text(double v)
{
    char got[64], want[64];
    xb_format_real(MARIE_PRIM_DOUBLE, v, got, sizeof got);
    printf_real(v, want, sizeof want);
    if (strcmp(got, want) != 0)
        fail_msg("%.17g written as %s, printf gives %s", v, got, want);
    double back;
    assert_int_equal(xb_parse_real(MARIE_PRIM_DOUBLE, got, strlen(got), &back), 0);
    assert_memory_equal(&back, &v, sizeof v);
}

static void expect_real_read(const char *text)
{
    char *end;
    double want = strtod(text, &end), got;
    assert_int_equal(xb_parse_real(MARIE_PRIM_DOUBLE, text, strlen(text), &got), 0);
    if (memcmp(&got, &want, sizeof got) != 0)
        fail_msg("'%s' read as %.17g, strtod gives %.17g", text, got, want);
}

static void test_reals_read_and_written_as_strtod_and_printf_do(void **state)
{
    static const double edges[] = { 0.0, -0.0, 1e-4, 9.99999999999999e-5, 1e-5, 1e15, 1e15 - 1,
                                    1e14, 0.1, 0.2, 0.3, 1.0 / 3, 12.345678, -3.25, 0.000125 * 3,
                                    0.000125 * 7, 1.5707963267948966, 100, 123456789012345e-18,
                                    2.5e-300, 1.7976931348623157e308, 4.9e-324 };
    for (size_t i = 0; i < sizeof edges / sizeof *edges; i++)
        expect_real_text(edges[i]);
    uint64_t r = 88172645463325252ull;
    for (int i = 0; i < 200000; i++) {
        r ^= r << 13; r ^= r >> 7; r ^= r << 17;
        double v;
        if (i % 3 == 0) {
            memcpy(&v, &r, sizeof v);                                   /* any bits */
            if (isnan(v) || isinf(v))
                continue;
        } else {                                                        /* short decimals */
            v = (double)(int64_t)(r % 1000000000000000ull) / pow(10, (double)((r >> 50) % 24));
            if (r >> 63)
                v = -v;
        }
        expect_real_text(v);
        char text[64];
        snprintf(text, sizeof text, "%.*g", (int)(1 + (r >> 40) % 17), v);
        expect_real_read(text);
    }
    static const char *texts[] = { "1.", ".5", "-0", "+0", "0.0000", "1e0005", "1e22", "1e23",
                                   "123456789012345e-22", "1234567890123456", "0x10", "INF",
                                   "00000000000000000000001.5", "1.50000000000000000000",
                                   "  2.5\n", "1e-400" };
    for (size_t i = 0; i < sizeof texts / sizeof *texts; i++)
        expect_real_read(texts[i]);
    static const char *bad[] = { "", ".", "-", "1e", "1e+", "1.5.", "1..5", "--1", "1e400", "1 2" };
    double v;
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++)
        assert_int_equal(xb_parse_real(MARIE_PRIM_DOUBLE, bad[i], strlen(bad[i]), &v), -1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fingerprints_match_lcm_gen),
        cmocka_unit_test(test_every_type_round_trips_field_by_field),
        cmocka_unit_test(test_wrong_fields_are_refused_with_a_reason),
        cmocka_unit_test(test_defaults_and_inferred_lengths),
        cmocka_unit_test(test_decode_refuses_foreign_and_oversized_payloads),
        cmocka_unit_test(test_strings_xml_cannot_carry_use_base64),
        cmocka_unit_test(test_stream_is_cut_into_documents),
        cmocka_unit_test(test_bad_streams_fail_once_and_stay_failed),
        cmocka_unit_test(test_long_texts_cost_their_length),
        cmocka_unit_test(test_reals_read_and_written_as_strtod_and_printf_do),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
