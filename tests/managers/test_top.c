/* test_top: marie top's table: status and heartbeats merged, rates, lost hosts, sorting, and
 * every line fitting the terminal. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "managers/top.h"

#define S 1000000LL

typedef struct {
    const char *name, *state;
    int pid, restarts;
    float cpu;
    long long rss;
} comp_t;

/* A manager's status for `host` with n components (hosts: the system's host list, may be NULL). */
static void status(top_t *t, const char *host, const comp_t *c, int n, const char **hosts, int nhosts, long long now)
{
    marie_am_component_status_t cs[16];
    memset(cs, 0, sizeof cs);
    for (int i = 0; i < n; i++) {
        cs[i].name = (char *)c[i].name;
        cs[i].group = (char *)"";
        cs[i].state = (char *)c[i].state;
        cs[i].pid = c[i].pid;
        cs[i].restarts = c[i].restarts;
        cs[i].cpu = c[i].cpu;
        cs[i].rss = c[i].rss;
        cs[i].uptime_us = 3723 * S;
        cs[i].config_hash = (char *)"";
    }
    marie_am_status_t st = {.host = (char *)host, .system = (char *)"sys", .system_hash = (char *)"",
                            .profile = (char *)"", .load1 = 0.5f, .ncpu = 2, .nhosts = nhosts,
                            .hosts = (char **)hosts, .ncomponents = n, .components = cs};
    assert_int_equal(top_on_status(t, &st, now), 0);
}

static void heartbeat(top_t *t, const char *host, const char *name, int pid, long long utime, long long in,
                      long long out, long long bad, long long now)
{
    marie_heartbeat_t hb = {.utime = utime, .component = (char *)name, .host = (char *)host, .pid = pid,
                            .reason = (char *)"", .state = 2, .msgs_in = in, .msgs_out = out, .bad_input = bad};
    assert_int_equal(top_on_heartbeat(t, &hb, now), 0);
}

static const top_row_t *find(top_t *t, const char *name, long long now)
{
    const top_row_t *r;
    size_t n = top_rows(t, TOP_SORT_NAME, now, &r);
    for (size_t i = 0; i < n; i++)
        if (strcmp(r[i].name, name) == 0)
            return &r[i];
    return NULL;
}

static const comp_t three[] = {
    {"odometry", "running", 101, 0, 12.5f, 3 << 20},
    {"localizer", "running", 102, 2, 85.0f, 40 << 20},
    {"planner", "backoff", 0, 5, 0.0f, 0},
};

static void test_status_gives_one_row_per_component(void **state)
{
    top_t *t = top_create();
    status(t, "onboard2", three, 3, NULL, 0, 10 * S);
    const top_row_t *r = find(t, "localizer", 10 * S);
    assert_non_null(r);
    assert_string_equal(r->host, "onboard2");
    assert_string_equal(r->state, "running");
    assert_int_equal(r->pid, 102);
    assert_int_equal(r->restarts, 2);
    assert_true(r->cpu > 84.9f && r->cpu < 85.1f);
    assert_int_equal(r->rss, 40 << 20);
    assert_null(find(t, "nothing", 10 * S));
    const top_row_t *rows;
    assert_int_equal(top_rows(t, TOP_SORT_CPU, 10 * S, &rows), 3);
    top_destroy(t);
}

static void test_sort_orders(void **state)
{
    top_t *t = top_create();
    static const comp_t other[] = {{"arbiter", "running", 201, 0, 30.0f, 1 << 20}};
    status(t, "onboard2", three, 3, NULL, 0, 10 * S);
    status(t, "onboard1", other, 1, NULL, 0, 10 * S);
    const top_row_t *r;
    assert_int_equal(top_rows(t, TOP_SORT_CPU, 10 * S, &r), 4);
    assert_string_equal(r[0].name, "localizer");   /* 85 */
    assert_string_equal(r[1].name, "arbiter");     /* 30 */
    assert_string_equal(r[2].name, "odometry");    /* 12.5 */
    assert_string_equal(r[3].name, "planner");
    top_rows(t, TOP_SORT_MEM, 10 * S, &r);
    assert_string_equal(r[0].name, "localizer");
    assert_string_equal(r[1].name, "odometry");
    assert_string_equal(r[2].name, "arbiter");
    top_rows(t, TOP_SORT_NAME, 10 * S, &r);
    assert_string_equal(r[0].name, "arbiter");
    assert_string_equal(r[3].name, "planner");
    top_rows(t, TOP_SORT_HOST, 10 * S, &r);
    assert_string_equal(r[0].host, "onboard1");
    assert_string_equal(r[1].name, "localizer");   /* then by name within the host */
    assert_int_equal(top_sort_parse("mem"), TOP_SORT_MEM);
    assert_int_equal(top_sort_parse("host"), TOP_SORT_HOST);
    assert_int_equal(top_sort_parse("rss"), -1);
    top_destroy(t);
}

static void test_host_silent_for_3s_is_lost(void **state)
{
    top_t *t = top_create();
    const char *hosts[] = {"onboard1", "onboard2", "laptop"};
    status(t, "onboard2", three, 3, hosts, 3, 10 * S);
    const top_host_t *h;
    assert_int_equal(top_hosts(t, 12 * S, &h), 3);
    assert_string_equal(h[0].name, "laptop");       /* by name */
    assert_false(h[0].heard);
    assert_true(h[0].lost);                         /* named by the system, never heard */
    assert_string_equal(h[2].name, "onboard2");
    assert_false(h[2].lost);
    assert_string_equal(find(t, "odometry", 12 * S)->state, "running");
    top_hosts(t, 13 * S + 1, &h);
    assert_true(h[2].lost);
    assert_int_equal(h[2].silent_us, 3 * S + 1);
    assert_string_equal(find(t, "odometry", 13 * S + 1)->state, "lost");
    status(t, "onboard2", three, 3, NULL, 0, 14 * S);   /* back */
    top_hosts(t, 14 * S, &h);
    assert_false(h[2].lost);
    assert_string_equal(find(t, "odometry", 14 * S)->state, "running");
    top_destroy(t);
}

static void test_rates_from_heartbeats(void **state)
{
    top_t *t = top_create();
    status(t, "h", three, 3, NULL, 0, 10 * S);
    heartbeat(t, "h", "odometry", 101, 100 * S, 1000, 200, 0, 10 * S);
    assert_true(find(t, "odometry", 10 * S)->in_rate < 0);      /* one heartbeat: no rate yet */
    heartbeat(t, "h", "odometry", 101, 101 * S, 1050, 220, 3, 11 * S);
    const top_row_t *r = find(t, "odometry", 11 * S);
    assert_true(r->in_rate > 49.9 && r->in_rate < 50.1);
    assert_true(r->out_rate > 19.9 && r->out_rate < 20.1);
    assert_int_equal(r->bad, 3);
    /* a state-change heartbeat 0.1 s later keeps the rate (too short a span to measure) */
    heartbeat(t, "h", "odometry", 101, 101 * S + 100000, 1051, 220, 3, 11 * S);
    r = find(t, "odometry", 11 * S);
    assert_true(r->in_rate > 49.9 && r->in_rate < 50.1);
    heartbeat(t, "h", "odometry", 101, 103 * S, 1250, 220, 3, 13 * S);
    r = find(t, "odometry", 13 * S);
    assert_true(r->in_rate > 99.9 && r->in_rate < 100.1);       /* (1250-1050) / 2 s */
    assert_true(r->out_rate == 0);
    /* silent for more than 3 s: unknown, not the old figure */
    assert_true(find(t, "odometry", 16 * S + 1)->in_rate < 0);
    /* restarted (new pid, counters from 0): no negative rate */
    heartbeat(t, "h", "odometry", 999, 104 * S, 5, 0, 0, 14 * S);
    assert_true(find(t, "odometry", 14 * S)->in_rate < 0);
    heartbeat(t, "h", "odometry", 999, 105 * S, 15, 0, 0, 15 * S);
    r = find(t, "odometry", 15 * S);
    assert_true(r->in_rate > 9.9 && r->in_rate < 10.1);
    top_destroy(t);
}

static void test_components_come_and_go(void **state)
{
    top_t *t = top_create();
    status(t, "h", three, 3, NULL, 0, 10 * S);
    status(t, "h", three, 2, NULL, 0, 11 * S);         /* planner removed from the system */
    assert_null(find(t, "planner", 11 * S));
    /* a component without a manager is shown from its heartbeat, then dropped when silent */
    heartbeat(t, "lab", "probe", 77, 50 * S, 1, 1, 0, 11 * S);
    const top_row_t *r = find(t, "probe", 11 * S);
    assert_non_null(r);
    assert_string_equal(r->state, "running");
    assert_int_equal(r->pid, 77);
    assert_int_equal(r->restarts, -1);
    assert_true(r->cpu < 0);
    assert_non_null(find(t, "probe", 21 * S));
    assert_null(find(t, "probe", 21 * S + 1));
    top_destroy(t);
}

static void test_rows_fit_every_width(void **state)
{
    top_t *t = top_create();
    static const comp_t c[] = {
        {"a_component_with_a_very_long_name_indeed_more_than_32", "running", 4194303, 123456, 199.9f, 5LL << 30},
        {"\033[2J\033]0;pwned\007", "running", 5, 0, 1.0f, 1000},
    };
    status(t, "a-host-name-far-too-long-for-its-column", c, 2, NULL, 0, 10 * S);
    heartbeat(t, "a-host-name-far-too-long-for-its-column", c[0].name, 4194303, 1 * S, 0, 0, 123456789, 10 * S);
    heartbeat(t, "a-host-name-far-too-long-for-its-column", c[0].name, 4194303, 2 * S, 12345678, 9, 123456789, 10 * S);
    const top_row_t *r;
    size_t n = top_rows(t, TOP_SORT_CPU, 10 * S, &r);
    assert_int_equal(n, 2);
    char buf[TOP_LINE_MAX];
    for (int w = 1; w <= 300; w++) {
        top_layout_t l;
        top_layout(&l, r, n, w);
        int len = top_format_header(&l, buf, sizeof buf);
        assert_true(len <= w);
        assert_int_equal((int)strlen(buf), len);
        for (size_t i = 0; i < n; i++) {
            len = top_format_row(&l, &r[i], buf, sizeof buf);
            assert_true(len <= w);
            for (int k = 0; buf[k]; k++)
                assert_true(buf[k] >= 0x20 && buf[k] < 0x7f);   /* no escape reaches the terminal */
        }
    }
    top_destroy(t);
}

static void test_columns_dropped_from_the_right_when_narrow(void **state)
{
    top_t *t = top_create();
    status(t, "onboard2", three, 3, NULL, 0, 10 * S);
    const top_row_t *r;
    size_t n = top_rows(t, TOP_SORT_CPU, 10 * S, &r);
    top_layout_t l;
    char buf[TOP_LINE_MAX];
    top_layout(&l, r, n, 120);
    top_format_header(&l, buf, sizeof buf);
    assert_non_null(strstr(buf, "HOST"));
    assert_non_null(strstr(buf, "UPTIME"));
    assert_non_null(strstr(buf, "IN/s"));
    assert_non_null(strstr(buf, "OUT/s"));
    assert_non_null(strstr(buf, "BAD"));
    top_format_row(&l, &r[0], buf, sizeof buf);
    assert_non_null(strstr(buf, "onboard2 localizer "));
    assert_non_null(strstr(buf, " 85.0 "));
    assert_non_null(strstr(buf, " 40.0M "));
    assert_non_null(strstr(buf, " 1:02:03 "));     /* 3723 s */
    top_layout(&l, r, n, 50);
    top_format_header(&l, buf, sizeof buf);
    assert_null(strstr(buf, "BAD"));
    assert_null(strstr(buf, "IN/s"));
    assert_non_null(strstr(buf, "COMPONENT"));
    assert_non_null(strstr(buf, "STATE"));
    assert_non_null(strstr(buf, "CPU%"));
    top_destroy(t);
}

static void test_frame_never_taller_than_the_terminal(void **state)
{
    top_t *t = top_create();
    comp_t many[16];
    char names[16][16];
    for (int i = 0; i < 16; i++) {
        snprintf(names[i], sizeof names[i], "c%02d", i);
        many[i] = (comp_t){names[i], "running", 100 + i, 0, (float)i, 1 << 20};
    }
    status(t, "h1", many, 16, NULL, 0, 10 * S);
    status(t, "h2", many, 16, NULL, 0, 10 * S);
    top_line_t lines[64];
    top_view_t v = {.sort = TOP_SORT_CPU, .width = 80, .height = 12, .interval_s = 1};
    int n = top_frame(t, &v, 10 * S, lines, 64);
    assert_int_equal(n, 12);
    assert_int_equal(lines[0].kind, TOP_LINE_TITLE);
    assert_int_equal(lines[1].kind, TOP_LINE_HOST);
    assert_int_equal(lines[4].kind, TOP_LINE_HEADER);
    assert_int_equal(lines[11].kind, TOP_LINE_MORE);
    assert_non_null(strstr(lines[11].text, "26 more"));   /* 32 rows, 6 shown */
    assert_non_null(strstr(lines[5].text, "c15"));       /* highest CPU first */
    for (int i = 0; i < n; i++)
        assert_true((int)strlen(lines[i].text) <= 80);
    v.malformed = 3;
    v.width = 200;
    top_frame(t, &v, 10 * S, lines, 64);
    assert_non_null(strstr(lines[0].text, " 3 malformed "));
    v.malformed = 0;
    /* unlimited height: every row */
    v.height = 0;
    v.width = 200;
    assert_int_equal(top_frame_lines(t, 10 * S), 3 + 2 + 32);
    assert_int_equal(top_frame(t, &v, 10 * S, lines, 64), 3 + 2 + 32);
    /* lost hosts are marked */
    v.height = 0;
    n = top_frame(t, &v, 20 * S, lines, 64);
    assert_int_equal(lines[1].kind, TOP_LINE_HOST_LOST);
    assert_non_null(strstr(lines[1].text, "LOST"));
    assert_int_equal(lines[5].kind, TOP_LINE_ROW_BAD);
    /* a narrow terminal: nothing wider than it */
    v.width = 7;
    n = top_frame(t, &v, 10 * S, lines, 64);
    for (int i = 0; i < n; i++)
        assert_true((int)strlen(lines[i].text) <= 7);
    top_destroy(t);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_status_gives_one_row_per_component),
        cmocka_unit_test(test_sort_orders),
        cmocka_unit_test(test_host_silent_for_3s_is_lost),
        cmocka_unit_test(test_rates_from_heartbeats),
        cmocka_unit_test(test_components_come_and_go),
        cmocka_unit_test(test_rows_fit_every_width),
        cmocka_unit_test(test_columns_dropped_from_the_right_when_narrow),
        cmocka_unit_test(test_frame_never_taller_than_the_terminal),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
