/* test_base64: RFC 4648's test vectors both ways, whitespace inside the text, and text that is
 * not base64 refused. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "core/base64.h"

static const char *vectors[][2] = {
    { "", "" }, { "f", "Zg==" }, { "fo", "Zm8=" }, { "foo", "Zm9v" },
    { "foob", "Zm9vYg==" }, { "fooba", "Zm9vYmE=" }, { "foobar", "Zm9vYmFy" },
};

static void rfc4648_vectors_both_ways(void **state)
{
    for (size_t i = 0; i < sizeof vectors / sizeof vectors[0]; i++) {
        const char *raw = vectors[i][0], *text = vectors[i][1];
        char out[16] = { 0 };
        assert_int_equal(marie_base64_len(strlen(raw)), strlen(text));
        marie_base64_encode(out, raw, strlen(raw));
        assert_string_equal(out, text);
        uint8_t back[16];
        assert_int_equal(marie_base64_decoded_len(text, strlen(text)), (long)strlen(raw));
        assert_int_equal(marie_base64_decode(text, strlen(text), back, sizeof back), (long)strlen(raw));
        assert_memory_equal(back, raw, strlen(raw));
    }
}

static void every_byte_value_round_trips(void **state)
{
    uint8_t raw[256], back[256];
    char text[344];
    for (int i = 0; i < 256; i++)
        raw[i] = (uint8_t)(255 - i);
    marie_base64_encode(text, raw, sizeof raw);
    assert_int_equal(marie_base64_decode(text, marie_base64_len(sizeof raw), back, sizeof back), 256);
    assert_memory_equal(back, raw, sizeof raw);
}

static void whitespace_is_skipped_and_bad_text_refused(void **state)
{
    uint8_t out[8];
    const char *spaced = " Zm9v\n YmFy\r\t";
    assert_int_equal(marie_base64_decode(spaced, strlen(spaced), out, sizeof out), 6);
    assert_memory_equal(out, "foobar", 6);
    const char *bad[] = { "Zm9", "Zm9v!", "Zg==Zg==", "Z===", "Zm9vYmFy=" };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++)
        assert_int_equal(marie_base64_decoded_len(bad[i], strlen(bad[i])), -1);
    assert_int_equal(marie_base64_decode("Zm9vYmFy", 8, out, 5), -1);     /* does not fit */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(rfc4648_vectors_both_ways),
        cmocka_unit_test(every_byte_value_round_trips),
        cmocka_unit_test(whitespace_is_skipped_and_bad_text_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
