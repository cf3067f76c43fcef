/* test_limits: `limits:` read from a system file (sizes, ranges, positions of mistakes), and the
 * breach decisions on made-up samples: memory over its limit (watched) or a kernel kill in its
 * cgroup, CPU over its share for a whole window and not for a burst, files at the limit. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "core/config.h"
#include "managers/limits.h"

#define S(x) ((int64_t)((x) * 1e6))
#define MB (1LL << 20)

static int read_limits(const char *yaml, marie_limits_cfg_t *l, char *err, size_t len)
{
    marie_errors_t e = {0};
    marie_doc_t *d = marie_doc_parse("sys.yaml", yaml, strlen(yaml), &e);
    int rc = d ? marie_limits_cfg_read(marie_node_get(marie_doc_root(d), "limits"), l, &e) : -1;
    snprintf(err, len, "%s", e.n ? e.msgs[0] : "");
    marie_errors_clear(&e);
    marie_doc_destroy(d);
    return rc;
}

static void test_read(void **state)
{
    marie_limits_cfg_t l;
    char err[300], text[128];
    assert_int_equal(read_limits("limits: {memory: 256M, cpu: 0.5, nofile: 64, on_breach: stop}", &l, err, sizeof err), 0);
    assert_int_equal(l.memory, 256 * MB);
    assert_true(l.cpu == 0.5 && l.nofile == 64 && l.on_breach == MARIE_BREACH_STOP);
    assert_string_equal(marie_limits_cfg_text(&l, text, sizeof text), "memory 256M cpu 0.5 nofile 64 on_breach stop");
    assert_int_equal(read_limits("limits: {memory: 1.5GiB}", &l, err, sizeof err), 0);
    assert_int_equal(l.memory, 1536 * MB);
    assert_int_equal(l.on_breach, MARIE_BREACH_RESTART);
    assert_int_equal(read_limits("limits: {memory: 8388608}", &l, err, sizeof err), 0);
    assert_int_equal(l.memory, 8 * MB);
    const struct { const char *yaml, *err; } bad[] = {
        {"limits: {memory: lots}", "sys.yaml:1:18: limits memory: 4M to 1T"},
        {"limits: {memory: 1M}", "sys.yaml:1:18: limits memory: 4M to 1T"},
        {"limits: {cpu: 0}", "sys.yaml:1:15: limits cpu: 0.01 to 1024 cores, got 0"},
        {"limits: {cpu: .inf}", "sys.yaml:1:15: cpu: expected a finite number"},
        {"limits: {nofile: 3}", "sys.yaml:1:18: limits nofile: 16 to 1048576"},
        {"limits: {on_breach: stop}", "sys.yaml:1:9: limits: name at least one of memory, cpu and nofile"},
        {"limits: {memory: 64M, on_breach: kill}", "sys.yaml:1:34: limits on_breach: expected restart or stop"},
        {"limits: {swap: 1G}", "sys.yaml:1:10: unknown key 'swap' in limits"},
        {"limits: 64M", "sys.yaml:1:9: limits: expected a mapping"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(read_limits(bad[i].yaml, &l, err, sizeof err), -1);
        if (strncmp(err, bad[i].err, strlen(bad[i].err)) != 0)
            fail_msg("%s: got '%s', want '%s...'", bad[i].yaml, err, bad[i].err);
        assert_false(marie_limits_cfg_any(&l));
    }
}

static marie_limit_sample_t at(double t, int64_t rss, double cpu_s)
{
    return (marie_limit_sample_t){S(t), rss, S(cpu_s), -1, -1, -1};
}

static void test_memory_watched(void **state)
{
    marie_limits_cfg_t l = {.memory = 64 * MB};
    marie_limit_watch_t w = {0};
    char why[300];
    marie_limit_sample_t s = at(0, 10 * MB, 0);
    assert_int_equal(marie_limits_check(&l, false, &w, &s, why, sizeof why), MARIE_LIMIT_NONE);
    s = at(1, 64 * MB, 0.1);
    assert_int_equal(marie_limits_check(&l, false, &w, &s, why, sizeof why), MARIE_LIMIT_NONE);
    s = at(1.1, 65 * MB, 0.1);
    assert_int_equal(marie_limits_check(&l, false, &w, &s, why, sizeof why), MARIE_LIMIT_MEMORY);
    assert_string_equal(why, "memory: 65 MB resident, over its limit of 64 MB");
}

static void test_memory_cgroup_kill(void **state)
{
    marie_limits_cfg_t l = {.memory = 48 * MB};
    marie_limit_watch_t w = {0};
    char why[300];
    /* the count before this instance was 3 (earlier kills); its own rss is the kernel's business */
    marie_limit_sample_t s = {S(0), -1, -1, -1, 3, 0};
    marie_limits_start(&w, &s);
    s = (marie_limit_sample_t){S(1), 200 * MB, S(0.5), -1, 3, 0};
    assert_int_equal(marie_limits_check(&l, true, &w, &s, why, sizeof why), MARIE_LIMIT_NONE);
    s.oom_kills = 4;
    assert_int_equal(marie_limits_check(&l, true, &w, &s, why, sizeof why), MARIE_LIMIT_MEMORY);
    assert_string_equal(why, "memory: the kernel killed it at its limit of 48 MB (cgroup memory.max)");
}

static void test_cpu_over_a_window_not_a_burst(void **state)
{
    marie_limits_cfg_t l = {.cpu = 0.5};
    marie_limit_watch_t w = {0};
    char why[300];
    marie_limit_sample_t s = at(0, 0, 0);
    marie_limits_check(&l, false, &w, &s, why, sizeof why);
    /* a burst of 1 s at a whole core, then quiet: 0.2 core over the window */
    s = at(1, 0, 1);
    assert_int_equal(marie_limits_check(&l, false, &w, &s, why, sizeof why), MARIE_LIMIT_NONE);
    s = at(5, 0, 1);
    assert_int_equal(marie_limits_check(&l, false, &w, &s, why, sizeof why), MARIE_LIMIT_NONE);
    /* then 0.8 core for a whole window */
    s = at(10, 0, 5);
    assert_int_equal(marie_limits_check(&l, false, &w, &s, why, sizeof why), MARIE_LIMIT_CPU);
    assert_string_equal(why, "cpu: 0.80 core over 5 s, over its limit of 0.5");
    /* in a cgroup: held to its share, judged by how long it was held back */
    marie_limit_watch_t g = {0};
    s = (marie_limit_sample_t){S(0), -1, 0, -1, 0, 0};
    marie_limits_check(&l, true, &g, &s, why, sizeof why);
    s = (marie_limit_sample_t){S(5), -1, S(2.5), -1, 0, S(1)};
    assert_int_equal(marie_limits_check(&l, true, &g, &s, why, sizeof why), MARIE_LIMIT_NONE);
    s = (marie_limit_sample_t){S(10), -1, S(5), -1, 0, S(3)};
    assert_int_equal(marie_limits_check(&l, true, &g, &s, why, sizeof why), MARIE_LIMIT_CPU);
    assert_string_equal(why, "cpu: held to its limit of 0.5 core for 40% of 5 s (cgroup cpu.max)");
}

static void test_files_at_the_limit(void **state)
{
    marie_limits_cfg_t l = {.nofile = 64};
    marie_limit_watch_t w = {0};
    char why[300];
    marie_limit_sample_t s = at(0, 0, 0);
    s.nfiles = 63;
    assert_int_equal(marie_limits_check(&l, false, &w, &s, why, sizeof why), MARIE_LIMIT_NONE);
    s.nfiles = 64;
    assert_int_equal(marie_limits_check(&l, false, &w, &s, why, sizeof why), MARIE_LIMIT_NOFILE);
    assert_string_equal(why, "nofile: 64 files open, its limit (the next open fails)");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_read),
        cmocka_unit_test(test_memory_watched),
        cmocka_unit_test(test_memory_cgroup_kill),
        cmocka_unit_test(test_cpu_over_a_window_not_a_burst),
        cmocka_unit_test(test_files_at_the_limit),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
