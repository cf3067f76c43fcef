/* test_buf: the text buffer grows, stays NUL-terminated, refuses appends past its maximum
 * without changing what it holds, and says so in `failed` until it is reset. An array grown
 * with marie_grow keeps its elements, doubles its room, and refuses a size it cannot hold
 * without touching the array. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>
#include <errno.h>
#include <stdlib.h>

#include "core/buf.h"

static void appends_grow_and_stay_terminated(void **state)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    assert_int_equal(marie_buf_puts(&b, "x="), 0);
    assert_int_equal(marie_buf_printf(&b, "%d", 42), 0);
    assert_int_equal(marie_buf_put(&b, ";", 1), 0);
    assert_string_equal(b.data, "x=42;");
    assert_int_equal(b.len, 5);
    /* longer than printf's stack copy, and than the first allocation */
    char big[1000];
    memset(big, 'a', sizeof big - 1);
    big[sizeof big - 1] = 0;
    assert_int_equal(marie_buf_printf(&b, "[%s]", big), 0);
    assert_int_equal(b.len, 5 + 2 + 999);
    assert_int_equal(b.data[b.len], 0);
    assert_int_equal(b.data[6], 'a');
    assert_int_equal(b.data[b.len - 1], ']');
    assert_false(b.failed);
    marie_buf_reset(&b);
    assert_int_equal(b.len, 0);
    assert_string_equal(b.data, "");
    marie_buf_free(&b);
    assert_null(b.data);
}

static void past_the_maximum_nothing_changes_and_failed_is_set(void **state)
{
    marie_buf_t b;
    marie_buf_init(&b, 8);
    assert_int_equal(marie_buf_puts(&b, "12345"), 0);
    assert_int_equal(marie_buf_puts(&b, "6789"), -1);
    assert_true(b.failed);
    assert_string_equal(b.data, "12345");
    assert_int_equal(marie_buf_printf(&b, "%s", "abcdefghijklmnopqrstuvwxyz0123456789abcdefghijklmnopqrstuvwxyz0123456789"
                                              "abcdefghijklmnopqrstuvwxyz0123456789abcdefghijklmnopqrstuvwxyz0123456789"
                                              "abcdefghijklmnopqrstuvwxyz0123456789abcdefghijklmnopqrstuvwxyz0123456789"
                                              "abcdefghijklmnopqrstuvwxyz0123456789"), -1);
    assert_string_equal(b.data, "12345");
    assert_int_equal(marie_buf_puts(&b, "678"), 0);     /* exactly the maximum */
    assert_string_equal(b.data, "12345678");
    assert_true(b.failed);                              /* still: the text is incomplete */
    marie_buf_reset(&b);
    assert_false(b.failed);
    assert_int_equal(marie_buf_reserve(&b, 9), -1);
    assert_int_equal(marie_buf_reserve(&b, 8), 0);
    marie_buf_free(&b);
}

static const char *json_of(marie_buf_t *b, const char *s)
{
    marie_buf_reset(b);
    assert_int_equal(marie_buf_json_str(b, s), 0);
    return b->data;
}

static void strings_become_valid_json_whatever_they_hold(void **state)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    assert_string_equal(json_of(&b, NULL), "\"\"");
    assert_string_equal(json_of(&b, "a\"b\\c"), "\"a\\\"b\\\\c\"");
    assert_string_equal(json_of(&b, "l1\nl2\x1b[2J\x7f"), "\"l1\\u000al2\\u001b[2J\\u007f\"");
    assert_string_equal(json_of(&b, "caf\xc3\xa9 \xe2\x80\xae"), "\"caf\xc3\xa9 \xe2\x80\xae\"");   /* UTF-8 kept */
    /* a stray byte, an overlong '/', a surrogate, a cut sequence: each one replacement */
    assert_string_equal(json_of(&b, "\xff\xc0\xaf\xed\xa0\x80\xe2\x80"),
                        "\"\\ufffd\\ufffd\\ufffd\\ufffd\\ufffd\\ufffd\\ufffd\\ufffd\"");
    marie_buf_free(&b);
    marie_buf_init(&b, 6);
    assert_int_equal(marie_buf_puts(&b, "ab"), 0);
    assert_int_equal(marie_buf_json_str(&b, "long text"), -1);
    assert_string_equal(b.data, "ab");                  /* nothing of it kept */
    marie_buf_free(&b);
}

static void arrays_grow_by_doubling_and_keep_their_elements(void **state)
{
    int *a = NULL;
    size_t n = 0, cap = 0;
    for (int i = 0; i < 1000; i++) {
        assert_int_equal(MARIE_GROW(a, cap, n + 1), 0);
        a[n++] = i;
    }
    assert_int_equal(cap, 1024);                        /* 16, 32, ... 1024 */
    for (int i = 0; i < 1000; i++)
        assert_int_equal(a[i], i);
    assert_int_equal(MARIE_GROW(a, cap, 10), 0);        /* room enough: nothing changes */
    assert_int_equal(cap, 1024);
    assert_int_equal(MARIE_GROW(a, cap, 5000), 0);      /* several doublings at once */
    assert_int_equal(cap, 8192);
    int *before = a;
    errno = 0;
    assert_int_equal(marie_grow((void **)&a, &cap, SIZE_MAX / 2, sizeof *a), -1);
    assert_int_equal(errno, ENOMEM);
    assert_ptr_equal(a, before);                        /* refused: the array as it was */
    assert_int_equal(cap, 8192);
    assert_int_equal(a[999], 999);
    free(a);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(appends_grow_and_stay_terminated),
        cmocka_unit_test(past_the_maximum_nothing_changes_and_failed_is_set),
        cmocka_unit_test(strings_become_valid_json_whatever_they_hold),
        cmocka_unit_test(arrays_grow_by_doubling_and_keep_their_elements),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
