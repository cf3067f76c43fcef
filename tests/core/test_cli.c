/* test_cli: a program's options from one table: values stored, ranges and numbers checked,
 * --help, unknown options. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "core/cli.h"

typedef struct {
    const char *url;
    int64_t node;
    double radius;
} cfg_t;

static int parse(cfg_t *c, char **argv)
{
    const marie_cli_opt_t opts[] = {
        { "can", MARIE_CLI_STRING, &c->url, 0, 0, "URL the bus" },
        { "node", MARIE_CLI_INT, &c->node, 0, 127, "N node id" },
        { "wheel-radius", MARIE_CLI_DOUBLE, &c->radius, 0.001, 10, "M wheel radius" },
        { NULL },
    };
    int argc = 0;
    while (argv[argc])
        argc++;
    /* the messages go to stderr and stdout: keep the test's output readable */
    FILE *saved_err = stderr, *saved_out = stdout;
    stderr = stdout = fopen("/dev/null", "w");
    int rc = marie_cli_parse("prog", opts, argc, argv);
    fclose(stderr);
    stderr = saved_err;
    stdout = saved_out;
    return rc;
}

static void values_given_are_stored_and_others_keep_their_defaults(void **state)
{
    cfg_t c = { NULL, 7, 0.1 };
    assert_int_equal(parse(&c, (char *[]){ "prog", "--can", "emu:/x", "--wheel-radius=0.25", "op", NULL }), -1);
    assert_string_equal(c.url, "emu:/x");
    assert_int_equal(c.node, 7);
    assert_true(c.radius == 0.25);
    assert_int_equal(optind, 4);        /* "op": the first operand */
    assert_int_equal(parse(&c, (char *[]){ "prog", "--node", "0x20", NULL }), -1);
    assert_int_equal(c.node, 32);
}

static void bad_values_exit_2_and_leave_the_value(void **state)
{
    const char *bad[][2] = { { "--node", "128" }, { "--node", "abc" }, { "--node", "1.5" }, { "--node", "" },
                             { "--wheel-radius", "0" }, { "--wheel-radius", "nan" }, { "--wheel-radius", "inf" },
                             { "--wheel-radius", "1e400" }, { "--wheel-radius", "0.2x" } };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        cfg_t c = { NULL, 7, 0.1 };
        assert_int_equal(parse(&c, (char *[]){ "prog", (char *)bad[i][0], (char *)bad[i][1], NULL }), 2);
        assert_int_equal(c.node, 7);
        assert_true(c.radius == 0.1);
    }
}

static void help_exits_0_and_unknown_or_missing_values_exit_2(void **state)
{
    cfg_t c = { 0 };
    assert_int_equal(parse(&c, (char *[]){ "prog", "--help", NULL }), 0);
    assert_int_equal(parse(&c, (char *[]){ "prog", "--speed", "3", NULL }), 2);
    assert_int_equal(parse(&c, (char *[]){ "prog", "--node", NULL }), 2);
    assert_int_equal(parse(&c, (char *[]){ "prog", "-x", NULL }), 2);
}

static void usage_lists_every_option(void **state)
{
    cfg_t c;
    const marie_cli_opt_t opts[] = {
        { "can", MARIE_CLI_STRING, &c.url, 0, 0, "URL the bus" },
        { "node", MARIE_CLI_INT, &c.node, 0, 127, "N node id" },
        { NULL },
    };
    char buf[512] = "";
    FILE *f = fmemopen(buf, sizeof buf - 1, "w");
    marie_cli_usage("prog", opts, f);
    fclose(f);
    assert_non_null(strstr(buf, "usage: prog"));
    assert_non_null(strstr(buf, "--can"));
    assert_non_null(strstr(buf, "N node id"));
    assert_non_null(strstr(buf, "--help"));
}

static void a_repeated_option_keeps_every_value_in_order(void **state)
{
    marie_cli_list_t tags = { .n = 0 };
    const marie_cli_opt_t opts[] = { { "tag", MARIE_CLI_LIST, &tags, 0, 0, "T a tag" }, { NULL } };
    FILE *saved = stderr;
    stderr = fopen("/dev/null", "w");
    int rc = marie_cli_parse("prog", opts, 5, (char *[]){ "prog", "--tag", "a", "--tag=b", "op", NULL });
    assert_int_equal(rc, -1);
    assert_int_equal(tags.n, 2);
    assert_string_equal(tags.items[0], "a");
    assert_string_equal(tags.items[1], "b");
    char *many[2 * MARIE_CLI_LIST_MAX + 4] = { "prog" };
    for (int i = 0; i <= MARIE_CLI_LIST_MAX; i++) {
        many[1 + 2 * i] = "--tag";
        many[2 + 2 * i] = "x";
    }
    tags.n = 0;
    rc = marie_cli_parse("prog", opts, 2 * MARIE_CLI_LIST_MAX + 3, many);
    fclose(stderr);
    stderr = saved;
    assert_int_equal(rc, 2);
    assert_int_equal(tags.n, MARIE_CLI_LIST_MAX);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(values_given_are_stored_and_others_keep_their_defaults),
        cmocka_unit_test(bad_values_exit_2_and_leave_the_value),
        cmocka_unit_test(help_exits_0_and_unknown_or_missing_values_exit_2),
        cmocka_unit_test(usage_lists_every_option),
        cmocka_unit_test(a_repeated_option_keeps_every_value_in_order),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
