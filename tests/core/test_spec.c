/* test_spec: a component describes its ports and parameters, and a system file entry is checked
 * against that description with file:line:col for each mistake. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "core/spec.h"

static const marie_port_spec_t ports[] = {
    {"out", &marie_type_counter_t, MARIE_OUT, MARIE_PUSH, "OUT"},
    {"cmd", &marie_type_counter_t, MARIE_IN, MARIE_EVENT, NULL},     /* must be bound */
    {0},
};
static const marie_param_spec_t params[] = {
    {"rate_hz", MARIE_PARAM_DOUBLE, "10", "rate"},
    {"count", MARIE_PARAM_INT, "1", "a \"quoted\" help"},
    {"device", MARIE_PARAM_STRING, NULL, "required"},
    {"on", MARIE_PARAM_BOOL, "true", ""},
    {"table", MARIE_PARAM_NODE, "[]", ""},
    {0},
};
static const marie_component_def_t def = {.kind = "probe", .ports = ports, .params = params};

static marie_doc_t *describe(void)
{
    char *text = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&text, &len);
    marie_spec_describe(&def, f);
    fclose(f);
    marie_errors_t e = {0};
    marie_doc_t *d = marie_doc_parse("describe", text, len, &e);
    marie_errors_print(&e, stderr);
    marie_errors_clear(&e);
    free(text);
    return d;
}

static int has_error(const marie_errors_t *e, const char *needle)
{
    for (size_t i = 0; i < e->n; i++)
        if (strstr(e->msgs[i], needle))
            return 1;
    marie_errors_print(e, stderr);
    return 0;
}

/* Load `entry` as component p of a system file, check it, and return the errors. */
static marie_errors_t check_entry(const char *entry)
{
    char path[] = "/tmp/marie-test-spec.XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    dprintf(fd, "components:\n  p:\n%s", entry);
    close(fd);
    marie_errors_t e = {0};
    marie_system_t *sys = marie_system_load(path, NULL, &e);
    unlink(path);
    marie_errors_print(&e, stderr);
    assert_non_null(sys);
    marie_doc_t *d = describe();
    assert_non_null(d);
    marie_spec_check(marie_doc_root(d), marie_system_component(sys, "p"), &e);
    marie_doc_destroy(d);
    marie_system_destroy(sys);
    return e;
}

static void the_description_is_json_with_every_port_and_parameter(void **state)
{
    marie_doc_t *d = describe();
    assert_non_null(d);
    const marie_node_t *root = marie_doc_root(d);
    assert_true(marie_spec_valid(root));
    assert_string_equal(marie_node_get(root, "kind")->value, "probe");
    const marie_node_t *pp = marie_node_get(root, "params"), *po = marie_node_get(root, "ports");
    assert_int_equal(pp->n, 5);
    assert_int_equal(po->n, 2);
    assert_string_equal(marie_node_get(pp->items[2], "name")->value, "device");
    assert_false(marie_node_get(pp->items[2], "default")->quoted);      /* JSON null: required */
    assert_string_equal(marie_node_get(pp->items[1], "help")->value, "a \"quoted\" help");
    assert_string_equal(marie_node_get(po->items[0], "type")->value, "marie.counter_t");
    assert_string_equal(marie_node_get(po->items[1], "mech")->value, "event");
    marie_doc_destroy(d);
}

static void a_good_entry_passes(void **state)
{
    marie_errors_t e = check_entry("    exec: x\n    params: {device: /dev/x, rate_hz: 2.5, count: 3, on: no,"
                                   " table: [1, 2]}\n    ports: {cmd: CMD}\n");
    assert_int_equal(e.n, 0);
    /* args may bind what the params and ports do not */
    e = check_entry("    exec: x\n    args: [--param, device=/dev/y, --port=cmd=C, --param=count=4]\n");
    assert_int_equal(e.n, 0);
}

static void each_mistake_is_reported_where_it_is(void **state)
{
    marie_errors_t e = check_entry("    exec: x\n"
                                   "    params: {device: d, rate_hz: fast, count: 1.5, colour: red}\n"
                                   "    ports: {cmd: C, nosuch: N}\n");
    assert_true(has_error(&e, ":4:34: rate_hz: expected a number, got 'fast'"));
    assert_true(has_error(&e, ":4:47: count: expected an integer, got '1.5'"));
    assert_true(has_error(&e, ":4:52: unknown parameter 'colour' for probe 'p' (known: rate_hz, count, device"));
    assert_true(has_error(&e, ":5:29: probe 'p' has no port 'nosuch' (ports: out, cmd)"));
    assert_int_equal(e.n, 4);
    marie_errors_clear(&e);
    e = check_entry("    exec: x\n    params: {rate_hz: .nan}\n");
    assert_true(has_error(&e, ":4:23: rate_hz: expected a finite number, got '.nan'"));
    assert_true(has_error(&e, ":2:3: probe 'p': missing required parameter 'device'"));
    assert_true(has_error(&e, ":2:3: probe 'p': port 'cmd' is not bound to a channel"));
    assert_int_equal(e.n, 3);
    marie_errors_clear(&e);
    e = check_entry("    exec: x\n    args: [--param, device=d, --port, cmd=C, --param, 'rate_hz=[1]', --param, x=1]\n");
    assert_true(has_error(&e, "rate_hz: expected a number, got a sequence"));
    assert_true(has_error(&e, ":4:11: args: --param x=1: probe 'p' has no such parameter"));
    assert_int_equal(e.n, 2);
    marie_errors_clear(&e);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(the_description_is_json_with_every_port_and_parameter),
        cmocka_unit_test(a_good_entry_passes),
        cmocka_unit_test(each_mistake_is_reported_where_it_is),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
