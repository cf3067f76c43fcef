/* test_config: system files load with profiles and hashes, and every error names file:line:col. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>

#include "core/component.h"

#define DATA "tests/data/core/"

static int has_error(const marie_errors_t *e, const char *needle)
{
    for (size_t i = 0; i < e->n; i++)
        if (strstr(e->msgs[i], needle))
            return 1;
    marie_errors_print(e, stderr);
    return 0;
}

static void loads_components_ports_and_params(void **state)
{
    marie_errors_t e = {0};
    marie_system_t *sys = marie_system_load(DATA "system_ok.yaml", NULL, &e);
    assert_non_null(sys);
    assert_int_equal(e.n, 0);
    assert_string_equal(sys->name, "example");
    assert_int_equal(sys->nhosts, 2);
    assert_int_equal(sys->ncomponents, 2);
    const marie_component_cfg_t *p = marie_system_component(sys, "producer");
    const marie_component_cfg_t *c = marie_system_component(sys, "consumer");
    assert_non_null(p);
    assert_non_null(c);
    assert_string_equal(p->host, "onboard1");
    assert_string_equal(p->ports[0].channel, "EXAMPLE_A");
    assert_int_equal(p->restart.policy, MARIE_RESTART_ON_FAILURE);
    assert_true(p->restart.backoff_min_s > 0.19 && p->restart.backoff_min_s < 0.21);
    assert_int_equal(c->restart.policy, MARIE_RESTART_ALWAYS);
    assert_int_equal(c->ndepends, 1);
    assert_string_equal(c->depends[0], "producer");
    assert_string_equal(marie_node_get(p->params, "label")->value, "robot");
    marie_system_destroy(sys);
}

static void profile_replaces_only_what_differs(void **state)
{
    marie_errors_t e = {0};
    marie_system_t *robot = marie_system_load(DATA "system_ok.yaml", NULL, &e);
    marie_system_t *sim = marie_system_load(DATA "system_ok.yaml", "sim", &e);
    assert_non_null(robot);
    assert_non_null(sim);
    const marie_component_cfg_t *rp = marie_system_component(robot, "producer");
    const marie_component_cfg_t *sp = marie_system_component(sim, "producer");
    assert_string_equal(marie_node_get(sp->params, "label")->value, "sim");
    /* The shared component keeps an identical configuration hash; the replaced one does not. */
    assert_string_equal(marie_component_hash(marie_system_component(robot, "consumer")), marie_component_hash(marie_system_component(sim, "consumer")));
    assert_string_not_equal(marie_component_hash(rp), marie_component_hash(sp));
    assert_int_equal(strlen(marie_component_hash(rp)), 64);
    marie_system_destroy(robot);
    marie_system_destroy(sim);
    marie_system_t *none = marie_system_load(DATA "system_ok.yaml", "moon", &e);
    assert_null(none);
    assert_true(has_error(&e, "no profile 'moon'"));
    marie_errors_clear(&e);
}

static void missing_file_is_reported(void **state)
{
    marie_errors_t e = {0};
    assert_null(marie_system_load(DATA "nope.yaml", NULL, &e));
    assert_true(has_error(&e, DATA "nope.yaml: cannot open: No such file"));
    marie_errors_clear(&e);
}

static void bad_yaml_has_line_and_column(void **state)
{
    marie_errors_t e = {0};
    assert_null(marie_system_load(DATA "bad_yaml.yaml", NULL, &e));
    assert_true(e.n >= 1);
    /* The flow sequence opened on line 4 is never closed. */
    assert_non_null(strstr(e.msgs[0], DATA "bad_yaml.yaml:"));
    int line = 0, col = 0;
    assert_int_equal(sscanf(e.msgs[0] + strlen(DATA "bad_yaml.yaml:"), "%d:%d:", &line, &col), 2);
    assert_true(line >= 4);
    assert_true(col >= 1);
    marie_errors_clear(&e);
}

static void unknown_key_and_bad_values_point_at_them(void **state)
{
    marie_errors_t e = {0};
    assert_null(marie_system_load(DATA "unknown_key.yaml", NULL, &e));
    assert_true(has_error(&e, DATA "unknown_key.yaml:4:5: unknown key 'colour' in component"));
    marie_errors_clear(&e);
    assert_null(marie_system_load(DATA "bad_dep.yaml", NULL, &e));
    assert_true(has_error(&e, DATA "bad_dep.yaml:5:11: component 'x': host 'b' is not in hosts"));
    assert_true(has_error(&e, "depends on unknown component 'nobody'"));
    assert_true(has_error(&e, DATA "bad_dep.yaml:7:14: restart policy: expected always, on-failure or never"));
    marie_errors_clear(&e);
}

/* A component definition to check parameter and port binding. */
static const marie_port_spec_t probe_ports[] = {
    {"out", &marie_type_counter_t, MARIE_OUT, MARIE_PUSH, "EXAMPLE"},
    {"needs", &marie_type_counter_t, MARIE_IN, MARIE_PUSH, NULL},
    {0},
};
static const marie_param_spec_t probe_params[] = {
    {"rate_hz", MARIE_PARAM_DOUBLE, "10", ""},
    {"label", MARIE_PARAM_STRING, "x", ""},
    {0},
};
static const marie_component_def_t probe = {.kind = "probe", .ports = probe_ports, .params = probe_params};

static marie_component_t *create(marie_errors_t *e, const char *file, const char *name, const char *extra)
{
    char *argv[8] = {"probe", "--system", (char *)file, "--name", (char *)name};
    int argc = 5;
    if (extra)
        argv[argc++] = (char *)extra;
    return marie_component_create(&probe, argc, argv, NULL, e);
}

static void wrong_type_and_unknown_param(void **state)
{
    marie_errors_t e = {0};
    assert_null(create(&e, DATA "wrong_type.yaml", "producer", "--port=needs=X"));
    assert_true(has_error(&e, DATA "wrong_type.yaml:5:16: rate_hz: expected a number, got 'fast'"));
    marie_errors_clear(&e);
    assert_null(create(&e, DATA "unknown_param.yaml", "producer", "--port=needs=X"));
    assert_true(has_error(&e, DATA "unknown_param.yaml:6:7: unknown parameter 'speed' for probe 'producer'"));
    marie_errors_clear(&e);
}

static void unbound_port_is_an_error(void **state)
{
    marie_errors_t e = {0};
    assert_null(create(&e, DATA "unbound.yaml", "probe", NULL));
    assert_true(has_error(&e, DATA "unbound.yaml:2:3: probe 'probe': port 'needs' is not bound to a channel"));
    marie_errors_clear(&e);
    /* Bound from the command line it is fine, and the default channel applies to the other port. */
    marie_component_t *c = create(&e, DATA "unbound.yaml", "probe", "--port=needs=WANTED");
    assert_non_null(c);
    assert_string_equal(marie_port_channel(marie_port(c, "needs")), "WANTED");
    assert_string_equal(marie_port_channel(marie_port(c, "out")), "EXAMPLE");
    assert_true(marie_param_double(c, "rate_hz") == 10.0);
    marie_component_destroy(c);
}

static void command_line_params_override_the_file(void **state)
{
    marie_errors_t e = {0};
    char *argv[] = {"probe", "--system", DATA "system_ok.yaml", "--name", "producer", "--port", "needs=N",
                    "--param", "label=overridden"};
    static const marie_port_spec_t ports[] = {
        {"out", &marie_type_counter_t, MARIE_OUT, MARIE_PUSH, NULL}, {"needs", NULL, MARIE_IN, MARIE_PUSH, NULL}, {0}};
    marie_component_def_t def = probe;
    def.ports = ports;
    marie_component_t *c = marie_component_create(&def, 9, argv, NULL, &e);
    assert_non_null(c);
    assert_string_equal(marie_param_str(c, "label"), "overridden");
    assert_true(marie_param_double(c, "rate_hz") == 20.0);
    assert_string_equal(marie_port_channel(marie_port(c, "out")), "EXAMPLE_A");
    marie_component_destroy(c);
    char *bad[] = {"probe", "--param", "rate_hz=[1, 2]", "--port", "needs=N"};
    assert_null(marie_component_create(&probe, 5, bad, NULL, &e));
    assert_true(has_error(&e, "rate_hz: expected a number, got a sequence"));
    marie_errors_clear(&e);
}

/* Parameters declared once: each MARIE_PARAM_AT entry's value lands in its field, from the
 * default, the file or the command line, ${VAR} expanded. */
typedef struct {
    int64_t count;
    double rate_hz;
    bool on;
    const char *label;
    const char *path;
} bound_params_t;
static const marie_param_spec_t bound_params[] = {
    MARIE_PARAM_AT(bound_params_t, count, INT, "3", "how many"),
    MARIE_PARAM_AT(bound_params_t, rate_hz, DOUBLE, "10", "Hz"),
    MARIE_PARAM_AT(bound_params_t, on, BOOL, "true", ""),
    MARIE_PARAM_AT(bound_params_t, label, STRING, "x", ""),
    MARIE_PARAM_AT(bound_params_t, path, STRING, "${MARIE_TEST_RUN:-/tmp}/can", ""),
    {0},
};

static void bound_params_fill_their_fields(void **state)
{
    marie_errors_t e = {0};
    static const marie_port_spec_t no_ports[] = {{0}};
    marie_component_def_t def = {.kind = "bound", .ports = no_ports, .params = bound_params,
                                 .params_size = sizeof(bound_params_t)};
    setenv("MARIE_TEST_RUN", "/run/x", 1);
    char *argv[] = {"bound", "--param", "rate_hz=2.5", "--param", "on=false", "--param", "label=hi"};
    marie_component_t *c = marie_component_create(&def, 7, argv, NULL, &e);
    assert_non_null(c);
    const bound_params_t *p = marie_component_params(c);
    assert_non_null(p);
    assert_int_equal(p->count, 3);
    assert_true(p->rate_hz == 2.5);
    assert_false(p->on);
    assert_string_equal(p->label, "hi");
    assert_string_equal(p->path, "/run/x/can");
    /* The by-name reads see the same values. */
    assert_true(marie_param_double(c, "rate_hz") == 2.5);
    marie_component_destroy(c);
    unsetenv("MARIE_TEST_RUN");
    /* A component without the struct gets none. */
    c = create(&e, DATA "unbound.yaml", "probe", "--port=needs=WANTED");
    assert_non_null(c);
    assert_null(marie_component_params(c));
    marie_component_destroy(c);
}

/* The by-name reads of the types a params struct is not needed for: a bool and any YAML. */
static void params_read_by_name(void **state)
{
    static const marie_port_spec_t no_ports[] = {{0}};
    static const marie_param_spec_t specs[] = {
        {"on", MARIE_PARAM_BOOL, "false", ""},
        {"area", MARIE_PARAM_NODE, NULL, ""},
        {0},
    };
    marie_component_def_t def = {.kind = "byname", .ports = no_ports, .params = specs};
    char *argv[] = {"byname", "--param", "on=true", "--param", "area={x: 1, y: 2}"};
    marie_errors_t e = {0};
    marie_component_t *c = marie_component_create(&def, 5, argv, NULL, &e);
    if (!c)
        marie_errors_print(&e, stderr);
    assert_non_null(c);
    assert_true(marie_param_bool(c, "on"));
    const marie_node_t *a = marie_param_node(c, "area");
    assert_non_null(a);
    assert_non_null(marie_node_get(a, "y"));
    assert_string_equal(marie_node_get(a, "y")->value, "2");
    marie_component_destroy(c);
}

static void quit_loop(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user) { marie_loop_quit(loop); }

/* A program with its own main runs its component in steps: run starts it and returns once the
 * loop is told to quit. */
static void run_starts_and_returns_on_quit(void **state)
{
    marie_errors_t e = {0};
    marie_component_t *c = create(&e, DATA "unbound.yaml", "probe", "--port=needs=WANTED");
    assert_non_null(c);
    assert_non_null(marie_loop_add_oneshot(marie_component_loop(c), 100000, quit_loop, NULL));
    assert_int_equal(marie_component_run(c), 0);
    assert_int_equal(marie_component_state(c), MARIE_STATE_RUNNING);
    marie_component_destroy(c);
}

static void tick_nothing(marie_component_t *c, int64_t overruns) {}

/* An on_init that runs again (after a failure) may ask for its timer again: it gets the same one. */
static void every_twice_is_one_timer(void **state)
{
    marie_errors_t e = {0};
    marie_component_t *c = create(&e, DATA "unbound.yaml", "probe", "--port=needs=WANTED");
    assert_non_null(c);
    marie_timer_t *t = marie_component_every(c, 10, tick_nothing);
    assert_non_null(t);
    assert_ptr_equal(marie_component_every(c, 20, tick_nothing), t);
    assert_int_equal(marie_timer_period(t), 50000);
    marie_component_destroy(c);
}

static void every_key_of_a_long_map_is_found(void **state)
{
    /* Long maps are looked up through an index: every key, at every length, must be found,
     * and a duplicate of any earlier key refused. */
    for (int n = 1; n <= 70; n++) {
        char text[4096] = "";
        for (int i = 0; i < n; i++)
            snprintf(text + strlen(text), sizeof text - strlen(text), "k%d: %d\n", i, i);
        marie_errors_t e = {0};
        marie_doc_t *d = marie_doc_parse("long.yaml", text, strlen(text), &e);
        assert_non_null(d);
        for (int i = 0; i < n; i++) {
            char key[16];
            snprintf(key, sizeof key, "k%d", i);
            const marie_node_t *v = marie_node_get(marie_doc_root(d), key);
            assert_non_null(v);
            assert_int_equal(atoi(v->value), i);
        }
        assert_null(marie_node_get(marie_doc_root(d), "nosuch"));
        marie_doc_destroy(d);
        for (int i = 0; i < n; i += 7) {
            char dup[4200];
            snprintf(dup, sizeof dup, "%sk%d: again\n", text, i);
            assert_null(marie_doc_parse("dup.yaml", dup, strlen(dup), &e));
            char want[64];
            snprintf(want, sizeof want, "duplicate key 'k%d' (first at line %d)", i, i + 1);
            assert_true(has_error(&e, want));
            marie_errors_clear(&e);
        }
    }
}

static void a_profile_entry_with_many_params_keeps_them(void **state)
{
    marie_errors_t e = {0};
    marie_system_t *sys = marie_system_load("config/spartacus.yaml", "sim", &e);
    assert_non_null(sys);
    const marie_component_cfg_t *sim = marie_system_component(sys, "sim");
    assert_non_null(sim);
    assert_string_equal(marie_node_get(sim->params, "speed")->value, "0");
    assert_string_equal(marie_node_get(sim->params, "world")->value, "office");
    assert_string_equal(marie_node_get(sim->params, "can")->value, "emu:${MARIE_RUN_DIR}/can");
    marie_system_destroy(sys);
}

static void duplicate_keys_and_aliases_are_refused(void **state)
{
    marie_errors_t e = {0};
    const char *dup = "a: 1\nb: 2\na: 3\n";
    assert_null(marie_doc_parse("dup.yaml", dup, strlen(dup), &e));
    assert_true(has_error(&e, "dup.yaml:3:1: duplicate key 'a' (first at line 1)"));
    marie_errors_clear(&e);
    const char *alias = "a: &x 1\nb: *x\n";
    assert_null(marie_doc_parse("alias.yaml", alias, strlen(alias), &e));
    assert_true(has_error(&e, "alias.yaml:2:"));
    assert_true(has_error(&e, "YAML aliases are not supported"));
    assert_int_equal(e.n, 1);
    marie_errors_clear(&e);
    /* Directives and NUL bytes never reach the YAML library (a directive with a NUL made it spin). */
    const char directive[] = "a: 1\n%YAML 1.2\n";
    assert_null(marie_doc_parse("d.yaml", directive, strlen(directive), &e));
    assert_true(has_error(&e, "d.yaml:2:1: YAML directives are not supported"));
    marie_errors_clear(&e);
    const char nul[] = "a: 1\nb: x\0y\n";
    assert_null(marie_doc_parse("n.yaml", nul, sizeof nul - 1, &e));
    assert_true(has_error(&e, "n.yaml:2:5: NUL byte"));
    marie_errors_clear(&e);
}


/* ---- the effective configuration, cycles, limits, speed ---- */

static char *write_tmp(const char *text, size_t len)
{
    char *path = strdup("/tmp/marie-test-config.XXXXXX");
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    assert_int_equal(write(fd, text, len), (ssize_t)len);
    close(fd);
    return path;
}

static marie_system_t *load_text(const char *text, const char *profile, marie_errors_t *e)
{
    char *path = write_tmp(text, strlen(text));
    marie_system_t *sys = marie_system_load(path, profile, e);
    unlink(path);
    free(path);
    return sys;
}

#define BASE_SYSTEM                                                                                   \
    "system: h\nhosts: [h1, h2]\n"                                                                    \
    "defaults:\n  restart: {policy: on-failure, backoff_min: 0.1, backoff_max: 5}\n"                  \
    "components:\n"                                                                                   \
    "  a:\n    exec: marie-example-producer\n    params: {rate_hz: 5}\n"                              \
    "  b:\n    exec: marie-example-consumer\n    depends: [a]\n    ports: {in: X}\n"                  \
    "    env: {K: v}\n    args: [--hold]\n"

static void every_setting_enters_the_hash(void **state)
{
    /* Each variant changes one setting of b (directly or inherited); the hash must change and
     * the difference must name that setting. */
    static const struct { const char *from, *to, *field; } variants[] = {
        {"policy: on-failure", "policy: always", "restart"},
        {"backoff_max: 5", "backoff_max: 6", "restart"},
        {"hosts: [h1, h2]", "hosts: [h2, h1]", "host"},
        {"depends: [a]", "depends: []", "depends"},
        {"exec: marie-example-consumer", "exec: ./other", "exec"},
        {"{K: v}", "{K: w}", "env"},
        {"args: [--hold]", "args: []", "args"},
        {"ports: {in: X}", "ports: {in: Y}", "ports"},
        {"system: h\n", "system: h\nclock: sim\n", "clock"},
        {"system: h\n", "system: h\nlcm_url: udpm://239.255.76.67:7668?ttl=0\n", "lcm_url"},
        {"system: h\n", "system: h\nauth: {key_file: /k}\n", "auth"},
        {"system: h\n", "system: h\ntransports: {X: {kind: shm}}\n", "lcm_url"},
        {"    args: [--hold]\n", "    args: [--hold]\n    stop_timeout: 1\n", "stop_timeout"},
        {"    args: [--hold]\n", "    args: [--hold]\n    heartbeat_timeout: 0\n", "heartbeat_timeout"},
        {"    args: [--hold]\n", "    args: [--hold]\n    shell: true\n", "shell"},
        {"    args: [--hold]\n", "    args: [--hold]\n    params: {x: 1}\n", "params"},
        {"    args: [--hold]\n", "    args: [--hold]\n    sched: {policy: fifo, priority: 40}\n", "sched"},
        {"    args: [--hold]\n", "    args: [--hold]\n    sched: {cpus: [1]}\n", "sched"},
    };
    marie_errors_t e = {0};
    marie_system_t *base = load_text(BASE_SYSTEM, NULL, &e);
    assert_non_null(base);
    const marie_component_cfg_t *b0 = marie_system_component(base, "b");
    for (size_t i = 0; i < sizeof variants / sizeof variants[0]; i++) {
        const char *text = BASE_SYSTEM, *at = strstr(text, variants[i].from);
        assert_non_null(at);
        char buf[2048];
        snprintf(buf, sizeof buf, "%.*s%s%s", (int)(at - text), text, variants[i].to, at + strlen(variants[i].from));
        marie_system_t *v = load_text(buf, NULL, &e);
        if (!v)
            marie_errors_print(&e, stderr);
        assert_non_null(v);
        const marie_component_cfg_t *b1 = marie_system_component(v, "b");
        if (strcmp(marie_component_hash(b0), marie_component_hash(b1)) == 0)
            fprintf(stderr, "variant '%s' kept the hash\n", variants[i].to);
        assert_string_not_equal(marie_component_hash(b0), marie_component_hash(b1));
        char *diff = marie_component_differences(base, b0, v, b1);
        assert_non_null(diff);
        assert_string_equal(diff, variants[i].field);
        free(diff);
        marie_system_destroy(v);
    }
    /* Reordering what has no order (keys, env, depends) keeps it. */
    const char *reordered = "system: h\nhosts: [h1, h2]\n"
                            "defaults:\n  restart: {backoff_max: 5, backoff_min: 0.1, policy: on-failure}\n"
                            "components:\n"
                            "  b:\n    args: [--hold]\n    env: {K: v}\n    ports: {in: X}\n    depends: [a]\n"
                            "    exec: marie-example-consumer\n"
                            "  a:\n    exec: marie-example-producer\n    params: {rate_hz: 5}\n";
    marie_system_t *r = load_text(reordered, NULL, &e);
    assert_non_null(r);
    assert_string_equal(marie_component_hash(marie_system_component(r, "b")), marie_component_hash(b0));
    marie_system_destroy(r);
    marie_system_destroy(base);
}

static void the_loader_refuses_cycles_and_bad_backoff(void **state)
{
    marie_errors_t e = {0};
    const char *cycle = "components:\n  a: {exec: x, depends: [c]}\n  b: {exec: x, depends: [a]}\n"
                        "  c: {exec: x, depends: [b]}\n  d: {exec: x, depends: [a]}\n";
    assert_null(load_text(cycle, NULL, &e));
    assert_true(has_error(&e, "is part of a dependency cycle"));
    marie_errors_clear(&e);
    const char *backoff = "components:\n  a:\n    exec: x\n    restart: {backoff_min: 3, backoff_max: 1}\n";
    assert_null(load_text(backoff, NULL, &e));
    assert_true(has_error(&e, ":4:14: component 'a': restart backoff_min (3 s) is above backoff_max (1 s)"));
    marie_errors_clear(&e);
    const char *defaults = "defaults:\n  restart: {backoff_min: 9}\ncomponents:\n  a: {exec: x}\n";
    assert_null(load_text(defaults, NULL, &e));
    assert_true(has_error(&e, ":2:12: defaults: restart backoff_min (9 s) is above backoff_max (5 s)"));
    marie_errors_clear(&e);
    /* A chain of 100000 dependencies is no cycle, and checking it must not exhaust the stack. */
    size_t cap = 100000 * 48, len = 0;
    char *chain = malloc(cap);
    len += (size_t)snprintf(chain, cap, "components:\n  c0: {exec: x}\n");
    for (int i = 1; i < 100000; i++)
        len += (size_t)snprintf(chain + len, cap - len, "  c%d: {exec: x, depends: [c%d]}\n", i, i - 1);
    marie_system_t *sys = load_text(chain, NULL, &e);
    assert_non_null(sys);
    marie_system_destroy(sys);
    free(chain);
}

static void sched_is_read_and_checked(void **state)
{
    marie_errors_t e = {0};
    const char *ok = "components:\n"
                     "  a:\n    exec: x\n    sched: {policy: fifo, priority: 44, cpus: [3, 1, 3]}\n"
                     "  b:\n    exec: x\n    sched: {policy: rr, priority: 1}\n"
                     "  c:\n    exec: x\n    sched: {cpus: 0}\n"
                     "  d:\n    exec: x\n"
                     "  e:\n    exec: x\n    sched: {spin_us: 50}\n"
                     "profiles:\n  sim: {clock: sim}\n";
    marie_system_t *sys = load_text(ok, NULL, &e);
    assert_non_null(sys);
    const marie_component_cfg_t *a = marie_system_component(sys, "a"), *c = marie_system_component(sys, "c");
    char text[128];
    assert_int_equal(a->sched.policy, MARIE_SCHED_FIFO);
    assert_int_equal(a->sched.priority, 44);
    assert_string_equal(marie_sched_cfg_text(&a->sched, text, sizeof text), "fifo 44 cpus 1,3");
    assert_string_equal(marie_sched_cfg_text(&marie_system_component(sys, "b")->sched, text, sizeof text), "rr 1");
    assert_string_equal(marie_sched_cfg_text(&c->sched, text, sizeof text), "other cpus 0");
    assert_false(marie_sched_cfg_any(&marie_system_component(sys, "d")->sched));
    const marie_component_cfg_t *sp = marie_system_component(sys, "e");
    assert_int_equal(sp->sched.spin_us, 50);
    assert_string_equal(marie_sched_cfg_text(&sp->sched, text, sizeof text), "other spin 50 us");
    assert_false(a->sched_sim);
    /* On the simulator's clock the setting is checked but not applied, and the hash says so. */
    marie_system_t *sim = load_text(ok, "sim", &e);
    assert_non_null(sim);
    const marie_component_cfg_t *sa = marie_system_component(sim, "a");
    assert_false(marie_sched_cfg_any(&sa->sched));
    assert_true(sa->sched_sim);
    char *diff = marie_component_differences(sys, a, sim, sa);
    assert_string_equal(diff, "sched,clock");
    free(diff);
    assert_int_equal(marie_system_component(sim, "e")->sched.spin_us, 0);   /* no spinning either */
    marie_system_destroy(sim);
    marie_system_destroy(sys);

    /* Each bad value is refused at its position, the file whole. */
    static const struct { const char *sched, *error; } bad[] = {
        {"{policy: fifi, priority: 40}", ":3:21: sched policy: expected other, fifo or rr, got 'fifi'"},
        {"{policy: fifo}", ":3:21: sched: policy fifo needs a priority (1 to 99)"},
        {"{policy: rr, priority: 0}", ":3:35: sched priority: expected 1 to 99, got 0"},
        {"{policy: fifo, priority: 100}", ":3:37: sched priority: expected 1 to 99, got 100"},
        {"{policy: fifo, priority: high}", ":3:37: priority: expected an integer, got 'high'"},
        {"{priority: 10}", ":3:23: sched priority: only policies fifo and rr have one"},
        {"{policy: other, priority: 10}", ":3:38: sched priority: only policies fifo and rr have one"},
        {"{cpus: []}", ":3:19: sched cpus: an empty list leaves no CPU to run on"},
        {"{cpus: [1, -1]}", ":3:23: sched cpus: CPU -1 is not 0 to 1023"},
        {"{cpus: [1024]}", ":3:20: sched cpus: CPU 1024 is not 0 to 1023"},
        {"{policy: fifo, priority: 40, nice: 5}", ":3:41: unknown key 'nice' in sched"},
        {"fifo", ":3:12: sched: expected a mapping such as {policy: fifo, priority: 40}"},
        {"{spin_us: -5}", ":3:22: sched spin_us: expected 0 to 10000 microseconds, got -5"},
        {"{spin_us: 20000}", ":3:22: sched spin_us: expected 0 to 10000 microseconds, got 20000"},
        {"{spin_us: fast}", ":3:22: "},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char file[256];
        snprintf(file, sizeof file, "components:\n  a:\n    sched: %s\n    exec: x\n", bad[i].sched);
        assert_null(load_text(file, NULL, &e));
        assert_true(has_error(&e, bad[i].error));
        marie_errors_clear(&e);
    }
    /* A sim profile does not make a bad setting good. */
    assert_null(load_text("clock: sim\ncomponents:\n  a:\n    sched: {policy: fast}\n    exec: x\n", NULL, &e));
    assert_true(has_error(&e, ":4:21: sched policy: expected other, fifo or rr, got 'fast'"));
    marie_errors_clear(&e);
}

static void non_finite_numbers_are_refused(void **state)
{
    static const char *const bad[] = {".nan", "nan", ".inf", "-.inf", "inf", "NaN"};
    marie_errors_t e = {0};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        char text[256];
        snprintf(text, sizeof text, "components:\n  a: {exec: x, stop_timeout: %s}\n", bad[i]);
        assert_null(load_text(text, NULL, &e));
        char want[128];
        snprintf(want, sizeof want, ":2:30: stop_timeout: expected a finite number, got '%s'", bad[i]);
        assert_true(has_error(&e, want));
        marie_errors_clear(&e);
    }
}

static void an_oversized_file_gets_a_position(void **state)
{
    /* 17 MB of 100-byte lines: the 16 MB limit falls on line 167773, column 17. */
    size_t len = 17u << 20;
    char *text = malloc(len);
    for (size_t i = 0; i < len; i++)
        text[i] = i % 100 == 99 ? '\n' : '#';
    char *path = write_tmp(text, len);
    free(text);
    marie_errors_t e = {0};
    assert_null(marie_system_load(path, NULL, &e));
    char want[256];
    snprintf(want, sizeof want, "%s:%d:%d: the file is larger than 16 MB", path, (16 << 20) / 100 + 1,
             (16 << 20) % 100 + 1);
    assert_true(has_error(&e, want));
    marie_errors_clear(&e);
    unlink(path);
    free(path);
}

/* A system of n components, each depending on the one before, `bytes` long at least. */
static char *big_system(size_t bytes)
{
    size_t cap = bytes + 4096, len = 0;
    char *t = malloc(cap);
    len += (size_t)snprintf(t, cap, "system: big\nhosts: [h1]\ncomponents:\n");
    for (int i = 0; len < bytes; i++)
        len += (size_t)snprintf(t + len, cap - len,
                                "  c%d:\n    exec: marie-example-producer\n    host: h1\n    depends: [c%d]\n"
                                "    ports: {out: CH_%d}\n    params: {rate_hz: 10, label: comp%d}\n",
                                i, i ? i - 1 : 1000000000, i, i);
    /* the first one depends on nothing */
    char *dep = strstr(t, "depends: [c1000000000]");
    memcpy(dep, "depends: []           ", strlen("depends: [c1000000000]"));
    return t;
}

static double cpu_seconds_to_load(const char *text)
{
    char *path = write_tmp(text, strlen(text));
    struct timespec a, b;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &a);
    marie_errors_t e = {0};
    marie_system_t *sys = marie_system_load(path, NULL, &e);
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &b);
    if (!sys)
        marie_errors_print(&e, stderr);
    assert_non_null(sys);
    marie_system_destroy(sys);
    unlink(path);
    free(path);
    return (double)(b.tv_sec - a.tv_sec) + (b.tv_nsec - a.tv_nsec) * 1e-9;
}

static void loading_time_grows_linearly(void **state)
{
    /* CPU time (not wall time, which other work on the machine inflates) per megabyte at 0.5 and
     * 4 MB: linear parsing keeps the ratio near 1; the old quadratic lookups made it about 8. */
    char *small = big_system(512 << 10), *large = big_system(4 << 20);
    double ts = 1e9;
    for (int i = 0; i < 3; i++) {
        double t = cpu_seconds_to_load(small);
        ts = t < ts ? t : ts;
    }
    double tl = cpu_seconds_to_load(large);
    double ratio = (tl / strlen(large)) / (ts / strlen(small));
    fprintf(stderr, "load: %.3f s for 0.5 MB, %.3f s for 4 MB, per-MB ratio %.2f\n", ts, tl, ratio);
    assert_true(ratio < 3.0);
    free(small);
    free(large);
}

/* The robot's shape is declared once, at the top of the system file: a component's robot_radius
 * comes from it unless its own entry sets one; a profile's robot replaces it and changes the
 * hash of the components that read it; bad values are refused with their position. */
typedef struct {
    double robot_radius, robot_clearance, other;
} robot_params_t;
static const marie_param_spec_t robot_params[] = {
    MARIE_PARAM_AT(robot_params_t, robot_radius, DOUBLE, "0.3", "m"),
    MARIE_PARAM_AT(robot_params_t, robot_clearance, DOUBLE, "0.1", "m"),
    MARIE_PARAM_AT(robot_params_t, other, DOUBLE, "1", ""),
    {0},
};

static void the_robot_section_feeds_robot_params(void **state)
{
    marie_errors_t e = {0};
    const char *text = "system: r\nrobot: {radius: 0.18, clearance: 0.05}\n"
                       "components:\n  a: {exec: a}\n  b: {exec: b, params: {robot_radius: 0.5}}\n"
                       "profiles:\n  big:\n    robot: {radius: 0.4}\n";
    char *path = write_tmp(text, strlen(text));
    static const marie_port_spec_t no_ports[] = {{0}};
    marie_component_def_t def = {.kind = "shaped", .ports = no_ports, .params = robot_params,
                                 .params_size = sizeof(robot_params_t)};
    char *argv_a[] = {"shaped", "--system", path, "--name", "a"};
    marie_component_t *c = marie_component_create(&def, 5, argv_a, NULL, &e);
    assert_non_null(c);
    const robot_params_t *p = marie_component_params(c);
    assert_true(p->robot_radius == 0.18 && p->robot_clearance == 0.05 && p->other == 1);
    marie_component_destroy(c);
    char *argv_b[] = {"shaped", "--system", path, "--name", "b"};
    c = marie_component_create(&def, 5, argv_b, NULL, &e);
    assert_non_null(c);
    assert_true(((const robot_params_t *)marie_component_params(c))->robot_radius == 0.5);
    marie_component_destroy(c);
    char *argv_big[] = {"shaped", "--system", path, "--name", "a", "--profile", "big"};
    c = marie_component_create(&def, 7, argv_big, NULL, &e);
    assert_non_null(c);
    p = marie_component_params(c);
    assert_true(p->robot_radius == 0.4 && p->robot_clearance == 0.1);   /* replaced whole */
    marie_component_destroy(c);
    marie_system_t *s1 = marie_system_load(path, NULL, &e), *s2 = marie_system_load(path, "big", &e);
    assert_non_null(s1);
    assert_non_null(s2);
    assert_string_not_equal(marie_component_hash(marie_system_component(s1, "a")), marie_component_hash(marie_system_component(s2, "a")));
    marie_system_destroy(s1);
    marie_system_destroy(s2);
    unlink(path);
    free(path);
    assert_int_equal(e.n, 0);
    assert_null(load_text("system: r\nrobot: {radius: -1}\ncomponents: {}\n", NULL, &e));
    assert_true(has_error(&e, ":2:17: robot.radius: must not be negative"));
    marie_errors_clear(&e);
    assert_null(load_text("system: r\nrobot: {radius: 0.2, wheels: 3}\ncomponents: {}\n", NULL, &e));
    assert_true(has_error(&e, "wheels"));
    marie_errors_clear(&e);
}

/* A profile that extends another applies on top of it: the parent's clock, replacements and
 * additions hold unless the child says otherwise; the child may drop what the parent added. */
static void a_profile_extends_another(void **state)
{
    marie_errors_t e = {0};
    const char *text = BASE_SYSTEM
        "  c:\n    exec: marie-example-producer\n"
        "profiles:\n"
        "  sim:\n    clock: sim\n    remove: [c]\n    components:\n"
        "      a: {exec: marie-example-producer, params: {rate_hz: 50}}\n"
        "      s: {exec: marie-example-producer}\n"
        "      t: {exec: marie-example-producer}\n"
        "  explore:\n    extends: sim\n    remove: [t, b]\n    components:\n"
        "      m: {exec: marie-example-producer}\n";
    marie_system_t *sim = load_text(text, "sim", &e), *ex = load_text(text, "explore", &e);
    assert_non_null(sim);
    assert_non_null(ex);
    assert_int_equal(ex->clock, MARIE_CLOCK_SIM);
    assert_int_equal(ex->ncomponents, 3);
    assert_non_null(marie_system_component(ex, "m"));
    assert_non_null(marie_system_component(ex, "s"));
    assert_null(marie_system_component(ex, "c"));
    assert_null(marie_system_component(ex, "t"));
    assert_null(marie_system_component(ex, "b"));
    /* a comes from sim, unchanged: the same hash in both profiles. */
    assert_string_equal(marie_node_get(marie_system_component(ex, "a")->params, "rate_hz")->value, "50");
    assert_string_equal(marie_component_hash(marie_system_component(ex, "a")), marie_component_hash(marie_system_component(sim, "a")));
    marie_system_destroy(sim);
    marie_system_destroy(ex);
    assert_int_equal(e.n, 0);
}

/* A profile's `params:` changes some parameters of a component it keeps, without copying its
 * entry: the others stay, the hash changes; a nearer profile that replaces the component
 * takes its own entry, one that removes it drops the override with it; a component that is
 * not there and a value that is not a mapping are errors at their line. */
static void a_profile_overrides_some_params(void **state)
{
    marie_errors_t e = {0};
    const char *text = BASE_SYSTEM
        "profiles:\n"
        "  sim:\n    components:\n"
        "      s: {exec: marie-example-producer, params: {rate_hz: 50, camera: true, world: office}}\n"
        "      v: {exec: marie-example-producer}\n"
        "    params: {a: {rate_hz: 7}, v: {rate_hz: 3}}\n"
        "  explore:\n    extends: sim\n    remove: [v]\n"
        "    components:\n      a: {exec: marie-example-producer, params: {rate_hz: 9}}\n"
        "    params:\n      s: {camera: false}\n";
    marie_system_t *sim = load_text(text, "sim", &e), *ex = load_text(text, "explore", &e);
    assert_non_null(sim);
    assert_non_null(ex);
    const marie_component_cfg_t *s = marie_system_component(ex, "s");
    assert_string_equal(marie_node_get(s->params, "camera")->value, "false");
    assert_string_equal(marie_node_get(s->params, "rate_hz")->value, "50");
    assert_string_equal(marie_node_get(s->params, "world")->value, "office");
    assert_int_equal(s->params->n, 3);
    assert_string_equal(marie_node_get(marie_system_component(sim, "s")->params, "camera")->value, "true");
    assert_string_not_equal(marie_component_hash(s), marie_component_hash(marie_system_component(sim, "s")));
    /* sim's override of a (the base's, rate_hz 5) holds in sim; explore's own a replaces it */
    assert_string_equal(marie_node_get(marie_system_component(sim, "a")->params, "rate_hz")->value, "7");
    assert_string_equal(marie_node_get(marie_system_component(ex, "a")->params, "rate_hz")->value, "9");
    assert_null(marie_system_component(ex, "v"));
    assert_int_equal(e.n, 0);
    marie_system_destroy(sim);
    marie_system_destroy(ex);

    assert_null(load_text(BASE_SYSTEM "profiles:\n  p:\n    params:\n      nope: {rate_hz: 1}\n", "p", &e));
    assert_true(has_error(&e, ":18:7: params: no component 'nope' in this profile"));
    marie_errors_clear(&e);
    assert_null(load_text(BASE_SYSTEM "profiles:\n  p:\n    params:\n      a: 5\n", "p", &e));
    assert_true(has_error(&e, ":18:10: params: a: expected a mapping"));
    marie_errors_clear(&e);
    assert_null(load_text(BASE_SYSTEM "profiles:\n  p:\n    remove: [a]\n    params:\n      a: {rate_hz: 1}\n", "p", &e));
    assert_true(has_error(&e, "params: no component 'a' in this profile"));
    marie_errors_clear(&e);
}

/* Empty mappings and sequences hash like any other value (the canonical form of a node with
 * no items; under UBSan a copy from their NULL items array stopped the program). */
static void empty_collections_hash(void **state)
{
    marie_errors_t e = {0};
    marie_system_t *sys = load_text("system: h\ncomponents:\n"
                                    "  a: {exec: marie-example-producer, params: {}, args: []}\n"
                                    "  b: {exec: marie-example-producer, params: {x: []}}\n", NULL, &e);
    assert_non_null(sys);
    assert_int_equal(strlen(marie_component_hash(marie_system_component(sys, "a"))), 64);
    assert_string_not_equal(marie_component_hash(marie_system_component(sys, "a")), marie_component_hash(marie_system_component(sys, "b")));
    char *c = marie_node_canonical(marie_system_component(sys, "b")->params);
    assert_string_equal(c, "{1:x=[],}");      /* keys length-prefixed */
    free(c);
    marie_system_destroy(sys);
    assert_int_equal(e.n, 0);
}

static void a_profile_chain_is_checked(void **state)
{
    marie_errors_t e = {0};
    assert_null(load_text(BASE_SYSTEM "profiles:\n  x:\n    extends: moon\n", "x", &e));
    assert_true(has_error(&e, ":17:14: no profile 'moon'"));
    marie_errors_clear(&e);
    assert_null(load_text(BASE_SYSTEM "profiles:\n  x:\n    extends: y\n  y:\n    extends: x\n", "x", &e));
    assert_true(has_error(&e, ":19:14: extends: profile 'x' leads back to itself (a cycle from 'x')"));
    marie_errors_clear(&e);
    char deep[1024] = BASE_SYSTEM "profiles:\n";
    for (int i = 0; i < 10; i++)
        snprintf(deep + strlen(deep), sizeof deep - strlen(deep), "  p%d:\n    extends: p%d\n", i, i + 1);
    strcat(deep, "  p10: {}\n");
    assert_null(load_text(deep, "p0", &e));
    assert_true(has_error(&e, "more than 8 deep"));
    marie_errors_clear(&e);
    assert_null(load_text(BASE_SYSTEM "profiles:\n  x:\n    extends: [y]\n", "x", &e));
    assert_int_equal(e.n, 1);
    marie_errors_clear(&e);
}

/* transports: a channel on shared memory or the fast path, with its sizes; every mistake has
 * its position. */
static void transports_are_read_and_checked(void **state)
{
    marie_errors_t e = {0};
    marie_system_t *sys = load_text(BASE_SYSTEM "transports:\n  CAM: {kind: shm, max_size: 1000000, slots: 4}\n"
                                                "  LOG: {kind: lcm}\n  CMD: {kind: local, max_size: 256}\n", NULL, &e);
    assert_non_null(sys);
    const marie_transport_cfg_t *t = marie_system_transport(sys, "CAM");
    assert_non_null(t);
    assert_true(t->shm);
    assert_int_equal(t->max_size, 1000000);
    assert_int_equal(t->slots, 4);
    assert_int_equal(t->line, 16);
    assert_string_equal(t->kind, "shm");
    assert_false(marie_system_transport(sys, "LOG")->shm);
    t = marie_system_transport(sys, "CMD");
    assert_true(t->shm);
    assert_string_equal(t->kind, "local");
    assert_int_equal(t->max_size, 256);
    assert_int_equal(t->slots, 8);
    assert_null(marie_system_transport(sys, "X"));
    marie_system_destroy(sys);
    assert_null(load_text(BASE_SYSTEM "transports:\n  CAM: {kind: tcp}\n", NULL, &e));
    assert_true(has_error(&e, ":16:15: transport of 'CAM': kind is shm, local or lcm, not 'tcp'"));
    marie_errors_clear(&e);
    assert_null(load_text(BASE_SYSTEM "transports:\n  CAM: {kind: shm, slots: 1}\n", NULL, &e));
    assert_true(has_error(&e, ":16:8: transport of 'CAM': max_size is 64 B to 1 GiB and slots 2 to 1024"));
    marie_errors_clear(&e);
    assert_null(load_text(BASE_SYSTEM "transports:\n  CAM: {kind: shm, size: 10}\n", NULL, &e));
    assert_true(has_error(&e, "size"));
    marie_errors_clear(&e);
    assert_null(load_text(BASE_SYSTEM "transports: [CAM]\n", NULL, &e));
    assert_true(has_error(&e, "transports: expected a mapping"));
    marie_errors_clear(&e);
}

/* Whether libfyaml is mapped into this process now. */
static bool yaml_library_mapped(void)
{
    FILE *f = fopen("/proc/self/maps", "r");
    assert_non_null(f);
    char line[512];
    bool found = false;
    while (!found && fgets(line, sizeof line, f))
        found = strstr(line, "libfyaml") != NULL;
    fclose(f);
    return found;
}

/* A component lets the YAML library go once started: what it read stays, the library's pages
 * leave the process, and a later parse (a re-init reading a map) opens it again. */
static void the_yaml_library_is_let_go_and_comes_back(void **state)
{
    marie_errors_t e = {0};
    marie_doc_t *a = marie_doc_parse("a", "k: [1, 2]\n", 10, &e);
    assert_non_null(a);
    assert_true(yaml_library_mapped());
    marie_yaml_unload();
    assert_false(yaml_library_mapped());
    const marie_node_t *k = marie_node_get(marie_doc_root(a), "k");
    assert_non_null(k);
    assert_int_equal(k->n, 2);
    assert_string_equal(k->items[1]->value, "2");
    marie_doc_t *b = marie_doc_parse("b", "x: [", 4, &e);
    assert_null(b);
    assert_true(has_error(&e, "b:2:1: YAML: flow sequence without a closing bracket"));
    assert_true(yaml_library_mapped());
    marie_yaml_unload();
    marie_yaml_unload();    /* nothing to let go: no effect */
    assert_false(yaml_library_mapped());
    marie_doc_destroy(a);
    marie_errors_clear(&e);
}

/* A lone plain word (every parameter's default) is built without the YAML library: the same
 * scalar as the library reads inside a sequence; anything else still goes through it. */
static void plain_words_read_as_yaml_reads_them(void **state)
{
    static const char *const words[] = {"0", "-1", "1.5e-3", "true", "null", "a_b.c/d+e", "-x", "x--y", "inf", NULL};
    for (int i = 0; words[i]; i++) {
        marie_errors_t e = {0};
        char seq[64];
        snprintf(seq, sizeof seq, "[%s]", words[i]);
        marie_doc_t *w = marie_doc_parse("w", words[i], strlen(words[i]), &e), *s = marie_doc_parse("s", seq, strlen(seq), &e);
        assert_non_null(w);
        assert_non_null(s);
        const marie_node_t *a = marie_doc_root(w), *b = marie_doc_root(s)->items[0];
        assert_int_equal(a->kind, MARIE_NODE_SCALAR);
        assert_string_equal(a->value, b->value);
        assert_int_equal(a->quoted, b->quoted);
        assert_int_equal(a->line, 1);
        assert_int_equal(a->col, 1);
        marie_doc_destroy(w);
        marie_doc_destroy(s);
    }
    /* not words: a lone "-" is a sequence, "---" a document, "a: b" a mapping, '' a quoted string */
    static const char *const others[] = {"-", "---", "...", "a: b", "''", "~", NULL};
    static const marie_node_kind_t kinds[] = {MARIE_NODE_SEQ, MARIE_NODE_SCALAR, MARIE_NODE_SCALAR, MARIE_NODE_MAP,
                                              MARIE_NODE_SCALAR, MARIE_NODE_SCALAR};
    for (int i = 0; others[i]; i++) {
        marie_errors_t e = {0};
        marie_doc_t *d = marie_doc_parse("o", others[i], strlen(others[i]), &e);
        if (d)
            assert_int_equal(marie_doc_root(d)->kind, kinds[i]);
        if (d && i == 4)
            assert_true(marie_doc_root(d)->quoted);
        marie_doc_destroy(d);
        marie_errors_clear(&e);
    }
}

int main(void)
{
    marie_log_set_threshold(MARIE_LOG_OFF);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(loads_components_ports_and_params),
        cmocka_unit_test(profile_replaces_only_what_differs),
        cmocka_unit_test(missing_file_is_reported),
        cmocka_unit_test(bad_yaml_has_line_and_column),
        cmocka_unit_test(unknown_key_and_bad_values_point_at_them),
        cmocka_unit_test(wrong_type_and_unknown_param),
        cmocka_unit_test(unbound_port_is_an_error),
        cmocka_unit_test(command_line_params_override_the_file),
        cmocka_unit_test(bound_params_fill_their_fields),
        cmocka_unit_test(params_read_by_name),
        cmocka_unit_test(run_starts_and_returns_on_quit),
        cmocka_unit_test(every_twice_is_one_timer),
        cmocka_unit_test(duplicate_keys_and_aliases_are_refused),
        cmocka_unit_test(every_key_of_a_long_map_is_found),
        cmocka_unit_test(a_profile_entry_with_many_params_keeps_them),
        cmocka_unit_test(every_setting_enters_the_hash),
        cmocka_unit_test(the_loader_refuses_cycles_and_bad_backoff),
        cmocka_unit_test(sched_is_read_and_checked),
        cmocka_unit_test(non_finite_numbers_are_refused),
        cmocka_unit_test(plain_words_read_as_yaml_reads_them),
        cmocka_unit_test(an_oversized_file_gets_a_position),
        cmocka_unit_test(loading_time_grows_linearly),
        cmocka_unit_test(the_robot_section_feeds_robot_params),
        cmocka_unit_test(a_profile_extends_another),
        cmocka_unit_test(a_profile_overrides_some_params),
        cmocka_unit_test(empty_collections_hash),
        cmocka_unit_test(a_profile_chain_is_checked),
        cmocka_unit_test(transports_are_read_and_checked),
        cmocka_unit_test(the_yaml_library_is_let_go_and_comes_back),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
