/* test_logcap: captured output is split into lines, rate-limited, rotated and tailed, and
 * /proc usage parsing copes with odd command names. */
#include <errno.h>
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "managers/logcap.h"
#include "core/procstat.h"

typedef struct {
    char lines[32][MARIE_LINE_MAX + 1];
    int n;
} got_t;

static void collect(const char *line, size_t len, void *user)
{
    got_t *g = user;
    if (g->n < 32) {
        memcpy(g->lines[g->n], line, len);
        g->lines[g->n][len] = 0;
        g->n++;
    }
}

static void test_lines_split_across_reads(void **state)
{
    marie_linebuf_t lb = {0};
    got_t g = {0};
    marie_linebuf_feed(&lb, "hel", 3, collect, &g);
    assert_int_equal(g.n, 0);
    marie_linebuf_feed(&lb, "lo\r\nworld\n\npart", 15, collect, &g);
    assert_int_equal(g.n, 3);
    assert_string_equal(g.lines[0], "hello");
    assert_string_equal(g.lines[1], "world");
    assert_string_equal(g.lines[2], "");
    marie_linebuf_flush(&lb, collect, &g);
    assert_int_equal(g.n, 4);
    assert_string_equal(g.lines[3], "part");
}

static void test_overlong_line_cut(void **state)
{
    marie_linebuf_t lb = {0};
    got_t g = {0};
    char big[MARIE_LINE_MAX * 2 + 10];
    memset(big, 'x', sizeof big);
    big[sizeof big - 1] = '\n';
    marie_linebuf_feed(&lb, big, sizeof big, collect, &g);
    assert_int_equal(g.n, 3);
    assert_int_equal(strlen(g.lines[0]), MARIE_LINE_MAX);
    assert_int_equal(strlen(g.lines[2]), 9);
}

static void test_rate_limit(void **state)
{
    marie_ratelimit_t rl;
    marie_ratelimit_init(&rl, 10, 20);
    int pass = 0;
    for (int i = 0; i < 100; i++)
        pass += marie_ratelimit_take(&rl, 1000000);
    assert_int_equal(pass, 20);                 /* the burst */
    pass = 0;
    for (int i = 0; i < 100; i++)
        pass += marie_ratelimit_take(&rl, 1000000 + 500000);   /* half a second later */
    assert_int_equal(pass, 5);
}

static void test_rotation_and_tail(void **state)
{
    char dir[] = "/tmp/marie-test-logcap-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char path[128];
    snprintf(path, sizeof path, "%s/c.log", dir);
    marie_logfile_t *lf = marie_logfile_open(path, 100, 2);
    assert_non_null(lf);
    char line[32];
    for (int i = 0; i < 40; i++) {
        int n = snprintf(line, sizeof line, "line %02d\n", i);   /* 8 bytes */
        assert_int_equal(marie_logfile_write(lf, line, (size_t)n), 0);
    }
    marie_logfile_close(lf);
    struct stat st;
    assert_int_equal(stat(path, &st), 0);
    assert_true(st.st_size <= 100);
    char p1[160], p2[160], p3[160];
    snprintf(p1, sizeof p1, "%s.1", path);
    snprintf(p2, sizeof p2, "%s.2", path);
    snprintf(p3, sizeof p3, "%s.3", path);
    assert_int_equal(stat(p1, &st), 0);
    assert_int_equal(stat(p2, &st), 0);
    assert_int_not_equal(stat(p3, &st), 0);   /* keep = 2 */
    got_t g = {0};
    assert_int_equal(marie_logfile_tail(path, 3, collect, &g), 0);
    assert_int_equal(g.n, 3);
    assert_string_equal(g.lines[2], "line 39");
    assert_string_equal(g.lines[0], "line 37");
    /* more than the current file holds: the rotated one fills in, oldest first */
    got_t g2 = {0};
    marie_logfile_tail(path, 14, collect, &g2);
    assert_int_equal(g2.n, 14);
    assert_string_equal(g2.lines[13], "line 39");
    assert_string_equal(g2.lines[0], "line 26");
    char cmd[96];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

/* The error rule: -1 with errno, as every marie call fails (not -errno). */
static void test_failures_set_errno(void **state)
{
    got_t g = {0};
    errno = 0;
    assert_int_equal(marie_logfile_tail("/nonexistent/marie/c.log", 5, collect, &g), -1);
    assert_int_equal(errno, ENOENT);
    assert_int_equal(g.n, 0);
    errno = 0;
    assert_null(marie_logfile_open("/nonexistent/marie/c.log", 100, 2));
    assert_int_equal(errno, ENOENT);
    marie_logfile_t *lf = marie_logfile_open("/dev/full", 0, 1);
    assert_non_null(lf);
    errno = 0;
    assert_int_equal(marie_logfile_write(lf, "x\n", 2), -1);
    assert_int_equal(errno, ENOSPC);
    marie_logfile_close(lf);
}

/* A missing log file is made at its first line, not at open (a component that never prints
 * leaves none); an existing one is appended to. */
static void test_file_made_at_first_line(void **state)
{
    char dir[] = "/tmp/marie-logcap-XXXXXX", path[64];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/c.log", dir);
    marie_logfile_t *lf = marie_logfile_open(path, 0, 1);
    assert_non_null(lf);
    assert_int_equal(access(path, F_OK), -1);
    assert_int_equal(marie_logfile_write(lf, "one\n", 4), 0);
    marie_logfile_close(lf);
    assert_non_null(lf = marie_logfile_open(path, 0, 1));
    assert_int_equal(marie_logfile_write(lf, "two\n", 4), 0);
    marie_logfile_close(lf);
    char buf[16] = "";
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    assert_string_equal(buf, "one\ntwo\n");
    unlink(path);
    rmdir(dir);
}

static void test_proc_stat_parse(void **state)
{
    int64_t ut, st;
    const char *text = "1234 (we) ird (name)) S 1 1234 1234 0 -1 4194560 100 0 0 0 57 13 0 0 20 0 1 0 5 0 0";
    assert_int_equal(marie_proc_parse_stat(text, &ut, &st), 0);
    assert_int_equal(ut, 57);
    assert_int_equal(st, 13);
    assert_int_not_equal(marie_proc_parse_stat("garbage", &ut, &st), 0);
    int64_t cpu, rss;
    assert_int_equal(marie_proc_usage(getpid(), &cpu, &rss), 0);
    assert_true(rss > 0);
    int64_t t1, t2;
    assert_int_equal(marie_proc_starttime(getpid(), &t1), 0);
    assert_int_equal(marie_proc_starttime(getpid(), &t2), 0);
    assert_true(t1 > 0);
    assert_int_equal(t1, t2);
    assert_int_equal(marie_proc_starttime(getppid(), &t2), 0);
    assert_true(t2 <= t1);      /* the parent started first */
    assert_int_not_equal(marie_proc_starttime(0x7ffffff0, &t2), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_lines_split_across_reads),
        cmocka_unit_test(test_overlong_line_cut),
        cmocka_unit_test(test_rate_limit),
        cmocka_unit_test(test_rotation_and_tail),
        cmocka_unit_test(test_failures_set_errno),
        cmocka_unit_test(test_file_made_at_first_line),
        cmocka_unit_test(test_proc_stat_parse),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
