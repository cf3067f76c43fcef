/* test_progcheck: the programs' check that marie-am makes itself when every description is in
 * its cache (marie_progcheck_cached_only): it runs nothing, says when a program has to describe
 * itself first, and once the descriptions are cached refuses a bad entry with the same
 * file:line:col messages as the check that runs the programs. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/config.h"
#include "managers/progcheck.h"

static char dir[64], sys_path[96], cache[96];

/* A system with one marie-test-comp whose print_hz is `hz`. */
static marie_system_t *system_with(const char *hz)
{
    char comp[PATH_MAX];
    const char *b = getenv("B") ? getenv("B") : "build";
    assert_non_null(realpath(b, comp));
    strncat(comp, "/tests/bin/marie-test-comp", sizeof comp - strlen(comp) - 1);
    FILE *f = fopen(sys_path, "w");
    assert_non_null(f);
    fprintf(f, "system: t\nhosts: [h]\ncomponents:\n  c:\n    exec: %s\n    host: h\n    params: {print_hz: %s}\n",
            comp, hz);
    fclose(f);
    marie_errors_t errs = {0};
    marie_system_t *s = marie_system_load(sys_path, NULL, &errs);
    marie_errors_print(&errs, stderr);
    marie_errors_clear(&errs);
    assert_non_null(s);
    return s;
}

/* The check's verdict and its messages (caller frees), by a checker of its own on the cache. */
static int check(marie_system_t *s, bool cached_only, bool *must_run, char **text)
{
    marie_progcheck_t *p = marie_progcheck_create(NULL, cache);
    assert_non_null(p);
    if (cached_only)
        marie_progcheck_cached_only(p);
    marie_errors_t errs = {0};
    int rc = marie_progcheck_system(p, s, NULL, "h", &errs);
    *must_run = marie_progcheck_must_run(p);
    size_t len;
    FILE *m = open_memstream(text, &len);
    marie_errors_print(&errs, m);
    fclose(m);
    marie_errors_clear(&errs);
    marie_progcheck_destroy(p);
    return rc;
}

static void cached_check_runs_nothing_then_refuses_the_same(void **state)
{
    marie_system_t *s = system_with("fast");
    bool must_run;
    char *first, *ran, *cached;
    /* nothing cached: the cached-only check gives no verdict, and says why */
    check(s, true, &must_run, &first);
    assert_true(must_run);
    /* the full check runs the program, refuses, and fills the cache */
    assert_int_equal(check(s, false, &must_run, &ran), -1);
    assert_false(must_run);
    assert_non_null(strstr(ran, ":7:"));
    assert_non_null(strstr(ran, "print_hz: expected a number, got 'fast'"));
    /* now from the cache alone: the same verdict and messages */
    assert_int_equal(check(s, true, &must_run, &cached), -1);
    assert_false(must_run);
    assert_string_equal(cached, ran);
    free(first);
    free(ran);
    free(cached);
    marie_system_destroy(s);
    /* a good entry passes from the cache */
    s = system_with("2");
    assert_int_equal(check(s, true, &must_run, &cached), 0);
    assert_false(must_run);
    free(cached);
    marie_system_destroy(s);
}

/* A program that is not a marie component (no marker): the cached-only check leaves it to the
 * full one (which does not run it) rather than reading the program itself, and from then on
 * knows it from the cache. */
static void a_plain_program_is_known_from_the_cache(void **state)
{
    FILE *f = fopen(sys_path, "w");
    assert_non_null(f);
    fprintf(f, "system: t\nhosts: [h]\ncomponents:\n  c:\n    exec: /bin/sleep\n    host: h\n    args: [5]\n");
    fclose(f);
    marie_errors_t errs = {0};
    marie_system_t *s = marie_system_load(sys_path, NULL, &errs);
    marie_errors_clear(&errs);
    assert_non_null(s);
    bool must_run;
    char *text;
    check(s, true, &must_run, &text);
    assert_true(must_run);
    free(text);
    assert_int_equal(check(s, false, &must_run, &text), 0);
    assert_false(must_run);
    free(text);
    assert_int_equal(check(s, true, &must_run, &text), 0);
    assert_false(must_run);
    free(text);
    marie_system_destroy(s);
}

int main(void)
{
    snprintf(dir, sizeof dir, "/tmp/marie-progcheck-XXXXXX");
    if (!mkdtemp(dir))
        return 1;
    snprintf(sys_path, sizeof sys_path, "%s/sys.yaml", dir);
    snprintf(cache, sizeof cache, "%s/describe", dir);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(cached_check_runs_nothing_then_refuses_the_same),
        cmocka_unit_test(a_plain_program_is_known_from_the_cache),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    return system(cmd) == 0 ? rc : 1;
}
