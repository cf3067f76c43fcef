/* test_spawn: a spawned program runs with its argv, environment and output pipes, in its own
 * session, with default signal handling; a failed exec says why and exits 127; execvpe's ways
 * (PATH search, a script without #!) are kept; the children's memory is freed. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "managers/spawn.h"

typedef struct {
    char out[8192], err[8192];
    int status;
} ran_t;

static void read_all(int fd, char *buf, size_t cap)
{
    size_t n = 0;
    ssize_t r;
    while (n < cap - 1 && ((r = read(fd, buf + n, cap - 1 - n)) > 0 || (r < 0 && errno == EINTR)))
        if (r > 0)
            n += (size_t)r;
    buf[n] = 0;
}

static long run_nofile;         /* the next run's RLIMIT_NOFILE (0: the caller's) */

/* Spawns, reads stdout then stderr to their ends, reaps: the child's pid. */
static pid_t run(marie_spawner_t *s, const char *path, char *const *argv, char *const *envp, ran_t *r)
{
    int po[2], pe[2];
    assert_int_equal(pipe2(po, O_CLOEXEC), 0);
    assert_int_equal(pipe2(pe, O_CLOEXEC), 0);
    marie_spawn_req_t req = {
        .path = path, .argv = argv, .envp = envp, .out_fd = po[1], .err_fd = pe[1], .who = "test",
        .nofile = run_nofile,
    };
    pid_t pid = marie_spawn(s, &req);
    assert_true(pid > 0);
    close(po[1]);
    close(pe[1]);
    read_all(po[0], r->out, sizeof r->out);
    read_all(pe[0], r->err, sizeof r->err);
    close(po[0]);
    close(pe[0]);
    assert_int_equal(waitpid(pid, &r->status, 0), pid);
    return pid;
}

static char *const no_env[] = {NULL};

static void test_output_env_and_session(void **state)
{
    marie_spawner_t *s = marie_spawner_create();
    assert_non_null(s);
    char *argv[] = {"sh", "-c",
                    "echo \"$GREETING $1\"; echo to-stderr >&2; "
                    "set -- $(cut -d')' -f2 /proc/$$/stat); echo \"$3 $4 $$\"; readlink /proc/$$/fd/0",
                    "sh", "world", NULL};
    char *envp[] = {"GREETING=hello", NULL};
    ran_t r;
    pid_t pid = run(s, "/bin/sh", argv, envp, &r);
    assert_true(WIFEXITED(r.status) && WEXITSTATUS(r.status) == 0);
    char want[256];
    snprintf(want, sizeof want, "hello world\n%d %d %d\n/dev/null\n", (int)pid, (int)pid, (int)pid);
    assert_string_equal(r.out, want);           /* process group and session are its own */
    assert_string_equal(r.err, "to-stderr\n");
    marie_spawner_destroy(s);
}

/* A child's open-file limit is set before its exec: the program never runs without it. */
static void test_nofile_limit_before_exec(void **state)
{
    marie_spawner_t *s = marie_spawner_create();
    char *argv[] = {"sh", "-c", "ulimit -Sn; ulimit -Hn", NULL};
    ran_t r;
    run_nofile = 37;
    run(s, "/bin/sh", argv, no_env, &r);
    run_nofile = 0;
    assert_string_equal(r.out, "37\n37\n");
    run(s, "/bin/sh", argv, no_env, &r);
    assert_string_not_equal(r.out, "37\n37\n");
    marie_spawner_destroy(s);
}

static void test_signals_default_none_blocked(void **state)
{
    marie_spawner_t *s = marie_spawner_create();
    sigset_t block, old;
    sigemptyset(&block);
    sigaddset(&block, SIGUSR1);
    sigaddset(&block, SIGCHLD);
    sigprocmask(SIG_BLOCK, &block, &old);
    void (*was)(int) = signal(SIGPIPE, SIG_IGN);
    char *argv[] = {"/bin/grep", "^Sig\\(Blk\\|Ign\\)", "/proc/self/status", NULL};
    ran_t r;
    run(s, "/bin/grep", argv, no_env, &r);
    signal(SIGPIPE, was);
    sigprocmask(SIG_SETMASK, &old, NULL);
    /* Signals 32 and 33 are glibc's own: its posix_spawn (make's, for one) starts programs with
     * them ignored and glibc refuses to change them, so the child may inherit that; no other. */
    unsigned long long blk = 1, ign = 1;
    assert_int_equal(sscanf(r.out, "SigBlk:\t%llx\nSigIgn:\t%llx\n", &blk, &ign), 2);
    assert_true(blk == 0);
    assert_true((ign & ~0x180000000ull) == 0);
    marie_spawner_destroy(s);
}

static void test_exec_failure_says_why(void **state)
{
    marie_spawner_t *s = marie_spawner_create();
    char *argv[] = {"/nonexistent/prog", "x", NULL};
    ran_t r;
    run(s, "/nonexistent/prog", argv, no_env, &r);
    assert_true(WIFEXITED(r.status) && WEXITSTATUS(r.status) == 127);
    assert_string_equal(r.out, "");
    assert_string_equal(r.err, "test: exec /nonexistent/prog: No such file or directory\n");
    /* a bare name not in PATH: searched like execvpe, then the same report */
    char *bare[] = {"marie-no-such-program", NULL};
    run(s, NULL, bare, no_env, &r);
    assert_true(WIFEXITED(r.status) && WEXITSTATUS(r.status) == 127);
    assert_string_equal(r.err, "test: exec marie-no-such-program: No such file or directory\n");
    marie_spawner_destroy(s);
}

static void test_execvpe_ways(void **state)
{
    marie_spawner_t *s = marie_spawner_create();
    ran_t r;
    /* a bare name found in PATH */
    char *echo[] = {"echo", "found", NULL};
    run(s, NULL, echo, no_env, &r);
    assert_string_equal(r.out, "found\n");
    /* a script without #!: with no path given it runs through /bin/sh, as execvpe does;
     * given as the path, it is execve's: not an executable format */
    char dir[] = "/tmp/marie-test-spawn.XXXXXX", file[64];
    assert_non_null(mkdtemp(dir));
    snprintf(file, sizeof file, "%s/script", dir);
    FILE *f = fopen(file, "w");
    assert_non_null(f);
    fputs("echo \"script says $1\"\n", f);
    fclose(f);
    chmod(file, 0755);
    char *script[] = {file, "hi", NULL};
    run(s, NULL, script, no_env, &r);
    assert_true(WIFEXITED(r.status) && WEXITSTATUS(r.status) == 0);
    assert_string_equal(r.out, "script says hi\n");
    run(s, file, script, no_env, &r);
    assert_true(WIFEXITED(r.status) && WEXITSTATUS(r.status) == 127);
    char want[128];
    snprintf(want, sizeof want, "test: exec %s: Exec format error\n", file);
    assert_string_equal(r.err, want);
    unlink(file);
    rmdir(dir);
    marie_spawner_destroy(s);
}

static void test_many_then_all_freed(void **state)
{
    marie_spawner_t *s = marie_spawner_create();
    char *argv[] = {"/bin/true", NULL};
    int devnull = open("/dev/null", O_WRONLY | O_CLOEXEC);
    marie_spawn_req_t req = {.path = "/bin/true", .argv = argv, .envp = no_env, .out_fd = devnull, .err_fd = devnull, .who = "test"};
    enum { N = 200 };
    pid_t pids[N];
    for (int i = 0; i < N; i++) {
        pids[i] = marie_spawn(s, &req);
        assert_true(pids[i] > 0);
    }
    for (int i = 0; i < N; i++) {
        int st;
        assert_int_equal(waitpid(pids[i], &st, 0), pids[i]);
        assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
    }
    /* each has exec'd and exited: nothing of theirs is left */
    assert_int_equal(marie_spawner_sweep(s), 0);
    close(devnull);
    marie_spawner_destroy(s);
}

static void test_bad_request(void **state)
{
    marie_spawner_t *s = marie_spawner_create();
    char *argv[] = {NULL};
    marie_spawn_req_t req = {.path = "/bin/true", .argv = argv, .envp = no_env, .out_fd = 1, .err_fd = 2, .who = "test"};
    errno = 0;
    assert_int_equal(marie_spawn(s, &req), -1);
    assert_int_equal(errno, EINVAL);
    marie_spawner_destroy(s);
    marie_spawner_destroy(NULL);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_output_env_and_session),
        cmocka_unit_test(test_nofile_limit_before_exec),
        cmocka_unit_test(test_signals_default_none_blocked),
        cmocka_unit_test(test_exec_failure_says_why),
        cmocka_unit_test(test_execvpe_ways),
        cmocka_unit_test(test_many_then_all_freed),
        cmocka_unit_test(test_bad_request),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
