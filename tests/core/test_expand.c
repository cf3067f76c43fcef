/* test_expand: ${NAME} and ${NAME:-default} in parameter strings. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "core/expand.h"

static void expect(const char *in, const char *want)
{
    char why[256] = "";
    char *out = marie_expand_env(in, why, sizeof why);
    assert_non_null(out);
    assert_string_equal(out, want);
    free(out);
}

static void set_variables_are_replaced(void **state)
{
    setenv("MARIE_T_DIR", "/run/x", 1);
    expect("emu:${MARIE_T_DIR}/can", "emu:/run/x/can");
    expect("${MARIE_T_DIR}${MARIE_T_DIR}", "/run/x/run/x");
    expect("${MARIE_T_DIR:-/tmp}/a", "/run/x/a");
}

static void defaults_apply_when_unset_or_empty(void **state)
{
    unsetenv("MARIE_T_NONE");
    expect("${MARIE_T_NONE:-/tmp}/a", "/tmp/a");
    setenv("MARIE_T_EMPTY", "", 1);
    expect("${MARIE_T_EMPTY:-d}", "d");
    expect("${MARIE_T_NONE:-}x", "x");
}

static void plain_dollars_are_kept(void **state)
{
    expect("cost $5 and $HOME", "cost $5 and $HOME");
    expect("", "");
}

static void unset_or_malformed_references_are_errors(void **state)
{
    unsetenv("MARIE_T_NONE");
    char why[256] = "";
    errno = 0;
    assert_null(marie_expand_env("a${MARIE_T_NONE}b", why, sizeof why));
    assert_int_equal(errno, EINVAL);
    assert_non_null(strstr(why, "MARIE_T_NONE is not set"));
    assert_null(marie_expand_env("a${MARIE_T_NONE", why, sizeof why));
    assert_non_null(strstr(why, "unclosed"));
    assert_null(marie_expand_env("${}", why, sizeof why));
    assert_non_null(strstr(why, "bad variable name"));
}

/* marie up -a: the named ${...} (with or without a default) take the argument's value, anywhere
 * in the text; the others stay for the components' environment. */
static void launch_arguments_fill_only_their_names(void **state)
{
    char *args[] = {"rate=20", "host=onboard1"}, why[256] = "";
    int used[2] = {0, 0};
    char *out = marie_expand_args("a: ${rate}\nb: ${host:-x} ${MARIE_RUN_DIR}/can ${rate}\nc: ${other:-5}", args, 2,
                                  used, why, sizeof why);
    assert_non_null(out);
    assert_string_equal(out, "a: 20\nb: onboard1 ${MARIE_RUN_DIR}/can 20\nc: ${other:-5}");
    assert_int_equal(used[0], 1);
    assert_int_equal(used[1], 1);
    free(out);
    char *unused[] = {"nothere=1"};
    used[0] = 0;
    out = marie_expand_args("a: ${rate}", unused, 1, used, why, sizeof why);
    assert_string_equal(out, "a: ${rate}");
    assert_int_equal(used[0], 0);
    free(out);
    char *bad[] = {"novalue"};
    errno = 0;
    assert_null(marie_expand_args("x", bad, 1, NULL, why, sizeof why));
    assert_int_equal(errno, EINVAL);
    assert_non_null(strstr(why, "expected name=value"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(set_variables_are_replaced),
        cmocka_unit_test(defaults_apply_when_unset_or_empty),
        cmocka_unit_test(plain_dollars_are_kept),
        cmocka_unit_test(unset_or_malformed_references_are_errors),
        cmocka_unit_test(launch_arguments_fill_only_their_names),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
