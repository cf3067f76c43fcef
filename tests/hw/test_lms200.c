/* test_lms200: the LMS200 codec against published telegrams, scan files and damaged streams. */
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

#include "hw/lms200/lms200.h"
#include "tests/fails.h"

#define DATA "tests/data/hw/lms200/"

typedef struct {
    char name[64];
    uint8_t b[64];
    size_t n;
} vector_t;

static int load_vectors(vector_t *v, int max)
{
    FILE *f = fopen(DATA "vectors.txt", "r");
    assert_non_null(f);
    char line[512];
    int n = 0;
    while (n < max && fgets(line, sizeof line, f)) {
        if (line[0] == '#' || line[0] == '\n')
            continue;
        char *tok = strtok(line, " \t\n");
        snprintf(v[n].name, sizeof v[n].name, "%s", tok);
        v[n].n = 0;
        while ((tok = strtok(NULL, " \t\n")))
            v[n].b[v[n].n++] = (uint8_t)strtoul(tok, NULL, 16);
        n++;
    }
    fclose(f);
    return n;
}

static const vector_t *vec(const vector_t *v, int n, const char *name)
{
    for (int i = 0; i < n; i++)
        if (strcmp(v[i].name, name) == 0)
            return &v[i];
    fail_msg("no vector %s", name);
    return NULL;
}

static size_t load_file(const char *path, uint8_t *buf, size_t cap)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    size_t n = fread(buf, 1, cap, f);
    fclose(f);
    return n;
}

/* Collects what the parser delivers. */
typedef struct {
    int n;
    uint8_t cmds[64];
    uint8_t addrs[64];
    lms200_scan_t scan;
    int scans;
    int acks, naks;
} sink_t;

static void on_telegram(void *user, const lms200_telegram_t *t)
{
    sink_t *s = user;
    if (s->n < 64) {
        s->cmds[s->n] = t->cmd;
        s->addrs[s->n] = t->addr;
    }
    s->n++;
    if (t->cmd == LMS200_REPLY_SCAN && lms200_decode_scan(t, &s->scan) == 0)
        s->scans++;
}

static void on_ack(void *user, uint8_t b)
{
    sink_t *s = user;
    if (b == LMS200_ACK)
        s->acks++;
    else
        s->naks++;
}

static void test_crc_matches_published_telegrams(void **state)
{
    vector_t v[32];
    int n = load_vectors(v, 32);
    assert_true(n >= 8);
    for (int i = 0; i < n; i++) {
        uint16_t c = lms200_crc(v[i].b, v[i].n - 2);
        assert_int_equal(c & 0xff, v[i].b[v[i].n - 2]);
        assert_int_equal(c >> 8, v[i].b[v[i].n - 1]);
    }
}

static void test_encoders_reproduce_published_telegrams(void **state)
{
    vector_t v[32];
    int n = load_vectors(v, 32);
    uint8_t out[64];
    int k = 0;
#define EXPECT(NAME, CALL) do { size_t l_ = (CALL); const vector_t *x_ = vec(v, n, NAME); \
        assert_int_equal(l_, x_->n); assert_memory_equal(out, x_->b, l_); k++; } while (0)
    EXPECT("mode_continuous", lms200_encode_mode(out, sizeof out, 0, LMS200_MODE_CONTINUOUS, NULL));
    EXPECT("mode_stop", lms200_encode_mode(out, sizeof out, 0, LMS200_MODE_STOP, NULL));
    EXPECT("mode_baud_500000", lms200_encode_mode(out, sizeof out, 0, (uint8_t)lms200_baud_mode(500000), NULL));
    EXPECT("mode_baud_9600", lms200_encode_mode(out, sizeof out, 0, (uint8_t)lms200_baud_mode(9600), NULL));
    EXPECT("mode_install", lms200_encode_mode(out, sizeof out, 0, LMS200_MODE_INSTALL, NULL));
    EXPECT("request_values", lms200_encode_request(out, sizeof out, 0));
    EXPECT("variant_180_050", lms200_encode_variant(out, sizeof out, 0, 180, 50));
    EXPECT("reply_mode_ok", lms200_encode_mode_reply(out, sizeof out, 0, LMS200_MODE_OK, 0x10));
#undef EXPECT
    assert_int_equal(k, 8);
}

static void test_parser_decodes_each_published_telegram(void **state)
{
    vector_t v[32];
    int n = load_vectors(v, 32);
    sink_t s = { 0 };
    lms200_parser_t *p = lms200_parser_create(on_telegram, on_ack, &s);
    for (int i = 0; i < n; i++)
        assert_int_equal(lms200_parser_feed(p, v[i].b, v[i].n), 1);
    assert_int_equal(s.n, n);
    const lms200_parser_stats_t *st = lms200_parser_stats(p);
    assert_int_equal(st->crc_errors + st->truncated + st->oversized + st->garbage_bytes, 0);

    /* The mode reply decodes as success with the device's status byte. */
    const vector_t *r = vec(v, n, "reply_mode_ok");
    sink_t s2 = { 0 };
    lms200_parser_t *p2 = lms200_parser_create(on_telegram, NULL, &s2);
    lms200_parser_feed(p2, r->b, r->n);
    assert_int_equal(s2.addrs[0], 0x80);
    assert_int_equal(s2.cmds[0], LMS200_REPLY_MODE);
    lms200_parser_destroy(p2);
    lms200_parser_destroy(p);
}

static void capture(void *user, const lms200_telegram_t *t)
{
    lms200_telegram_t *dst = user;
    static uint8_t raw[LMS200_MAX_TELEGRAM];
    memcpy(raw, t->raw, t->raw_len);
    *dst = *t;
    dst->raw = raw;
    dst->data = raw + (t->data - t->raw);
}

static void test_mode_and_variant_replies_decode(void **state)
{
    uint8_t out[64];
    lms200_telegram_t t = { 0 };
    lms200_parser_t *p = lms200_parser_create(capture, NULL, &t);
    size_t l = lms200_encode_mode_reply(out, sizeof out, 0, LMS200_MODE_BAD_PASSWORD, 0x10);
    assert_int_equal(lms200_parser_feed(p, out, l), 1);
    assert_true(t.has_status);
    assert_int_equal(t.status, 0x10);
    uint8_t res = 0xff;
    assert_int_equal(lms200_decode_mode_reply(&t, &res), 0);
    assert_int_equal(res, LMS200_MODE_BAD_PASSWORD);
    lms200_variant_t var;
    assert_fails(lms200_decode_variant_reply(&t, &var), EBADMSG);

    l = lms200_encode_variant_reply(out, sizeof out, 0, true, 180, 50, 0x10);
    assert_int_equal(lms200_parser_feed(p, out, l), 1);
    assert_int_equal(lms200_decode_variant_reply(&t, &var), 0);
    assert_true(var.ok);
    assert_int_equal(var.angle_deg, 180);
    assert_int_equal(var.res_cdeg, 50);
    assert_fails(lms200_decode_mode_reply(&t, &res), EBADMSG);
    lms200_parser_destroy(p);
}

static void test_scan_361_mm_file_decodes(void **state)
{
    uint8_t buf[2048];
    size_t n = load_file(DATA "scan_361_mm.bin", buf, sizeof buf);
    assert_int_equal(n, 732);       /* 4 + 726 + 2, as a real 0.5 deg scan */
    sink_t s = { 0 };
    lms200_parser_t *p = lms200_parser_create(on_telegram, NULL, &s);
    assert_int_equal(lms200_parser_feed(p, buf, n), 1);
    assert_int_equal(s.scans, 1);
    assert_int_equal(s.scan.n, 361);
    assert_int_equal(s.scan.unit, LMS200_UNIT_MM);
    assert_false(s.scan.partial);
    assert_int_equal(s.scan.values[0], 1000);
    assert_int_equal(s.scan.values[360], 1000 + 5 * 360);
    assert_int_equal(s.scan.values[100], 0x1FFF);
    assert_true(isinf(lms200_value_m(s.scan.values[100], s.scan.unit)));
    assert_float_equal(lms200_value_m(s.scan.values[200], s.scan.unit), 2.0, 1e-9);
    assert_int_equal(s.scan.status, 0x10);
    lms200_parser_destroy(p);
}

static void test_scan_181_cm_file_decodes_with_flags(void **state)
{
    uint8_t buf[2048];
    size_t n = load_file(DATA "scan_181_cm.bin", buf, sizeof buf);
    sink_t s = { 0 };
    lms200_parser_t *p = lms200_parser_create(on_telegram, NULL, &s);
    /* One byte at a time gives the same result as one chunk. */
    for (size_t i = 0; i < n; i++)
        lms200_parser_feed(p, buf + i, 1);
    assert_int_equal(s.scans, 1);
    assert_int_equal(s.scan.n, 181);
    assert_int_equal(s.scan.unit, LMS200_UNIT_CM);
    assert_int_equal(s.scan.values[0], 100);
    assert_int_equal(s.scan.flags[0], 1);
    assert_int_equal(s.scan.values[180], 280);
    assert_float_equal(lms200_value_m(s.scan.values[180], s.scan.unit), 2.80, 1e-9);
    lms200_parser_destroy(p);
}

static void test_encode_scan_round_trips(void **state)
{
    uint16_t v[361];
    for (int i = 0; i < 361; i++)
        v[i] = (uint16_t)(i * 17 % 8000);
    uint8_t out[LMS200_MAX_TELEGRAM];
    size_t l = lms200_encode_scan(out, sizeof out, 0, LMS200_UNIT_MM, v, 361, 0x10);
    uint8_t file[2048];
    assert_int_equal(l, 732);
    sink_t s = { 0 };
    lms200_parser_t *p = lms200_parser_create(on_telegram, NULL, &s);
    lms200_parser_feed(p, out, l);
    assert_int_equal(s.scans, 1);
    assert_memory_equal(s.scan.values, v, sizeof v);
    /* Same framing as the independently generated file. */
    size_t fl = load_file(DATA "scan_361_mm.bin", file, sizeof file);
    assert_memory_equal(out, file, 6);
    assert_int_equal(fl, l);
    lms200_parser_destroy(p);
}

static void test_garbage_before_and_between_is_skipped(void **state)
{
    vector_t v[32];
    int n = load_vectors(v, 32);
    const vector_t *a = vec(v, n, "reply_mode_ok");
    uint8_t stream[256];
    size_t k = 0;
    /* Garbage that contains STX bytes and plausible lengths. */
    const uint8_t junk1[] = { 0xff, 0x02, 0x13, 0x55, 0x02, 0x80, 0x05 };
    const uint8_t junk2[] = { 0x41, 0x42, 0x02, 0x02, 0x00 };
    memcpy(stream + k, junk1, sizeof junk1); k += sizeof junk1;
    memcpy(stream + k, a->b, a->n); k += a->n;
    memcpy(stream + k, junk2, sizeof junk2); k += sizeof junk2;
    memcpy(stream + k, a->b, a->n); k += a->n;
    sink_t s = { 0 };
    lms200_parser_t *p = lms200_parser_create(on_telegram, NULL, &s);
    lms200_parser_feed(p, stream, k);
    /* The STX in junk1 claims 517 bytes: the good telegrams behind it are held until enough
     * bytes arrived to refute it, then delivered all the same. */
    for (int i = 0; i < 80; i++)
        lms200_parser_feed(p, a->b, a->n);
    assert_int_equal(s.n, 82);
    const lms200_parser_stats_t *st = lms200_parser_stats(p);
    assert_true(st->garbage_bytes + st->crc_errors + st->truncated > 0);
    assert_int_equal(lms200_parser_pending(p), 0);
    lms200_parser_destroy(p);
}

static void test_crc_error_counted_and_next_telegram_kept(void **state)
{
    uint8_t buf[2048];
    size_t n = load_file(DATA "scan_361_mm.bin", buf, sizeof buf);
    uint8_t stream[4096];
    memcpy(stream, buf, n);
    stream[300] ^= 0x40;                        /* one flipped bit in a range value */
    memcpy(stream + n, buf, n);
    sink_t s = { 0 };
    lms200_parser_t *p = lms200_parser_create(on_telegram, NULL, &s);
    lms200_parser_feed(p, stream, 2 * n);
    const lms200_parser_stats_t *st = lms200_parser_stats(p);
    assert_int_equal(s.scans, 1);
    assert_int_equal(st->crc_errors, 1);
    assert_int_equal(st->truncated, 0);
    /* A flipped CRC byte alone is also caught. */
    memcpy(stream, buf, n);
    stream[n - 1] ^= 1;
    lms200_parser_feed(p, stream, n);
    lms200_parser_feed(p, buf, n);
    assert_int_equal(st->crc_errors, 2);
    assert_int_equal(s.scans, 2);
    lms200_parser_destroy(p);
}

/* A device sending the same scan over and over, cut short five times in a row: five truncated
 * telegrams, not three (each failed candidate used to swallow the start of the next), then
 * the intact one. */
static void test_truncated_telegrams_in_a_row_each_counted(void **state)
{
    uint8_t buf[2048];
    size_t n = load_file(DATA "scan_361_mm.bin", buf, sizeof buf);
    assert_int_equal(n, lms200_scan_telegram_len(361));
    static uint8_t stream[8192];
    size_t len = 0;
    for (int i = 0; i < 5; i++) {
        memcpy(stream + len, buf, n / 2);
        len += n / 2;
    }
    memcpy(stream + len, buf, n);
    len += n;
    sink_t s = { 0 };
    lms200_parser_t *p = lms200_parser_create(on_telegram, NULL, &s);
    lms200_parser_feed(p, stream, len);
    const lms200_parser_stats_t *st = lms200_parser_stats(p);
    assert_int_equal(s.scans, 1);
    assert_int_equal(st->truncated, 5);
    assert_int_equal(st->crc_errors, 0);
    /* a whole telegram with a bad CRC is still a CRC error, and one cut by it truncated */
    memcpy(stream, buf, n / 3);
    memcpy(stream + n / 3, buf, n);
    stream[n / 3 + n - 1] ^= 0x5a;
    memcpy(stream + n / 3 + n, buf, n);
    lms200_parser_feed(p, stream, n / 3 + 2 * n);
    assert_int_equal(s.scans, 2);
    assert_int_equal(st->truncated, 6);
    assert_int_equal(st->crc_errors, 1);
    lms200_parser_destroy(p);
}

static void test_truncated_telegram_counted_and_next_kept(void **state)
{
    uint8_t buf[2048];
    size_t n = load_file(DATA "scan_361_mm.bin", buf, sizeof buf);
    uint8_t stream[4096];
    memcpy(stream, buf, 400);                   /* cut mid-scan */
    memcpy(stream + 400, buf, n);
    memcpy(stream + 400 + n, buf, n);
    sink_t s = { 0 };
    lms200_parser_t *p = lms200_parser_create(on_telegram, NULL, &s);
    lms200_parser_feed(p, stream, 400 + 2 * n);
    const lms200_parser_stats_t *st = lms200_parser_stats(p);
    assert_int_equal(s.scans, 2);
    assert_int_equal(st->truncated, 1);
    assert_int_equal(st->crc_errors, 0);
    /* A telegram cut off by silence counts as truncated when the line is reset. */
    lms200_parser_feed(p, buf, 100);
    assert_int_equal(lms200_parser_pending(p), 100);
    lms200_parser_reset(p);
    assert_int_equal(st->truncated, 2);
    assert_int_equal(lms200_parser_pending(p), 0);
    lms200_parser_feed(p, buf, n);
    assert_int_equal(s.scans, 3);
    lms200_parser_destroy(p);
}

static void test_oversized_length_counted(void **state)
{
    vector_t v[32];
    int n = load_vectors(v, 32);
    const vector_t *a = vec(v, n, "reply_mode_ok");
    uint8_t stream[64] = { 0x02, 0x80, 0xff, 0x7f };   /* 32767 bytes: not an LMS200 telegram */
    memcpy(stream + 4, a->b, a->n);
    sink_t s = { 0 };
    lms200_parser_t *p = lms200_parser_create(on_telegram, NULL, &s);
    lms200_parser_feed(p, stream, 4 + a->n);
    assert_int_equal(s.n, 1);
    assert_int_equal(lms200_parser_stats(p)->oversized, 1);
    lms200_parser_destroy(p);
}

static void test_ack_and_nak_between_telegrams(void **state)
{
    vector_t v[32];
    int n = load_vectors(v, 32);
    const vector_t *a = vec(v, n, "reply_mode_ok");
    uint8_t stream[64];
    stream[0] = LMS200_ACK;
    memcpy(stream + 1, a->b, a->n);
    stream[1 + a->n] = LMS200_NAK;
    sink_t s = { 0 };
    lms200_parser_t *p = lms200_parser_create(on_telegram, on_ack, &s);
    lms200_parser_feed(p, stream, a->n + 2);
    assert_int_equal(s.acks, 1);
    assert_int_equal(s.naks, 1);
    assert_int_equal(s.n, 1);
    assert_int_equal(lms200_parser_stats(p)->garbage_bytes, 0);
    lms200_parser_destroy(p);
}

/* A reset asked for from inside the callback (baud switch) drops the rest of that chunk. */
static lms200_parser_t *g_p;
static int g_seen;
static void reset_in_cb(void *user, const lms200_telegram_t *t)
{
    g_seen++;
    lms200_parser_reset(g_p);
}

static void test_reset_from_callback_drops_rest_of_chunk(void **state)
{
    vector_t v[32];
    int n = load_vectors(v, 32);
    const vector_t *a = vec(v, n, "reply_mode_ok");
    uint8_t stream[64];
    memcpy(stream, a->b, a->n);
    memcpy(stream + a->n, a->b, a->n);
    g_seen = 0;
    g_p = lms200_parser_create(reset_in_cb, NULL, NULL);
    lms200_parser_feed(g_p, stream, 2 * a->n);
    assert_int_equal(g_seen, 1);
    assert_int_equal(lms200_parser_pending(g_p), 0);
    lms200_parser_feed(g_p, a->b, a->n);
    assert_int_equal(g_seen, 2);
    lms200_parser_destroy(g_p);
}

static void test_bad_replies_are_refused(void **state)
{
    uint8_t out[64];
    lms200_telegram_t t = { 0 };
    lms200_parser_t *p = lms200_parser_create(capture, NULL, &t);
    /* A scan reply that claims 361 values but carries 2. */
    uint8_t d[] = { 0x69, 0x41, 0x10, 0x00, 0x20, 0x00 };
    size_t l = lms200_encode(out, sizeof out, 0x80, LMS200_REPLY_SCAN, d, sizeof d, 0x10);
    lms200_parser_feed(p, out, l);
    lms200_scan_t scan;
    assert_fails(lms200_decode_scan(&t, &scan), EBADMSG);
    /* Units "10 cm" (bits 14-15 = 2) are not produced by an LMS200. */
    uint8_t d2[] = { 0x01, 0x80, 0x10, 0x00 };
    l = lms200_encode(out, sizeof out, 0x80, LMS200_REPLY_SCAN, d2, sizeof d2, 0x10);
    lms200_parser_feed(p, out, l);
    assert_fails(lms200_decode_scan(&t, &scan), EBADMSG);
    /* Too small output buffers and bad passwords give 0. */
    assert_int_equal(lms200_encode_mode(out, 7, 0, LMS200_MODE_STOP, NULL), 0);
    assert_int_equal(lms200_encode_mode(out, sizeof out, 0, LMS200_MODE_INSTALL, "short"), 0);
    assert_int_equal(lms200_baud_mode(115200), -1);
    assert_int_equal(lms200_mode_baud(LMS200_MODE_BAUD_38400), 38400);
    lms200_parser_destroy(p);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_crc_matches_published_telegrams),
        cmocka_unit_test(test_encoders_reproduce_published_telegrams),
        cmocka_unit_test(test_parser_decodes_each_published_telegram),
        cmocka_unit_test(test_mode_and_variant_replies_decode),
        cmocka_unit_test(test_scan_361_mm_file_decodes),
        cmocka_unit_test(test_scan_181_cm_file_decodes_with_flags),
        cmocka_unit_test(test_encode_scan_round_trips),
        cmocka_unit_test(test_garbage_before_and_between_is_skipped),
        cmocka_unit_test(test_crc_error_counted_and_next_telegram_kept),
        cmocka_unit_test(test_truncated_telegram_counted_and_next_kept),
        cmocka_unit_test(test_truncated_telegrams_in_a_row_each_counted),
        cmocka_unit_test(test_oversized_length_counted),
        cmocka_unit_test(test_ack_and_nak_between_telegrams),
        cmocka_unit_test(test_reset_from_callback_drops_rest_of_chunk),
        cmocka_unit_test(test_bad_replies_are_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
