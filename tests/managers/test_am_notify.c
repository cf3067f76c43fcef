/* test_am_notify: marie-am speaks the systemd notify protocol to a real AF_UNIX datagram
 * socket: READY=1 once it manages its host, WATCHDOG=1 at half the watchdog interval,
 * STOPPING=1 on SIGTERM; its components do not inherit the notify socket; and the pings come
 * from the manager's loop, so they stop while the loop is stuck (systemd then restarts it). */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static int64_t mono_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

/* Receive notify datagrams until `want` has been seen `count` times or timeout_ms passes. */
static int wait_for_msg(int fd, const char *want, int count, int timeout_ms, char *all, size_t alllen)
{
    int seen = 0;
    int64_t end = mono_ms() + timeout_ms;
    while (seen < count && mono_ms() < end) {
        struct pollfd p = {fd, POLLIN, 0};
        if (poll(&p, 1, (int)(end - mono_ms())) <= 0)
            continue;
        char buf[512];
        ssize_t n = recv(fd, buf, sizeof buf - 1, 0);
        if (n <= 0)
            continue;
        buf[n] = 0;
        strncat(all, buf, alllen - strlen(all) - 2);
        strcat(all, "|");
        for (char *line = strtok(buf, "\n"); line; line = strtok(NULL, "\n"))
            if (strcmp(line, want) == 0)
                seen++;
    }
    return seen;
}

static void test_ready_watchdog_stopping(void **state)
{
    char dir[] = "/tmp/marie-test-notify-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char sock[128], statedir[128], envfile[160];
    snprintf(sock, sizeof sock, "%s/notify", dir);
    snprintf(statedir, sizeof statedir, "%s/state", dir);
    snprintf(envfile, sizeof envfile, "%s/env.txt", dir);

    int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    assert_true(fd >= 0);
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%.100s", sock);
    assert_int_equal(bind(fd, (struct sockaddr *)&sa, sizeof sa), 0);

    /* a one-component system whose component writes down its environment */
    char sys[160];
    snprintf(sys, sizeof sys, "%s/sys.yaml", dir);
    FILE *f = fopen(sys, "w");
    assert_non_null(f);
    fprintf(f, "system: notify\nhosts: [n1]\ncomponents:\n  envdump:\n    exec: 'env > %s; exec sleep 30'\n"
               "    shell: true\n    heartbeat_timeout: 0\n    stop_timeout: 0.5\n", envfile);
    fclose(f);

    const char *bin = getenv("B") ? getenv("B") : "build";
    char am[256];
    snprintf(am, sizeof am, "%s/bin/marie-am", bin);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        setenv("NOTIFY_SOCKET", sock, 1);
        setenv("WATCHDOG_USEC", "300000", 1);
        unsetenv("WATCHDOG_PID");
        setenv("MARIE_KEY", "/nonexistent/key", 1);
        execl(am, am, "--host", "n1", "--state-dir", statedir, "--system", sys, (char *)NULL);
        _exit(127);
    }
    char all[8192] = "";
    assert_int_equal(wait_for_msg(fd, "READY=1", 1, 10000, all, sizeof all), 1);
    /* WATCHDOG_USEC=300 ms: a ping every 150 ms; three of them within 5 s whatever the load */
    assert_int_equal(wait_for_msg(fd, "WATCHDOG=1", 3, 5000, all, sizeof all), 3);
    /* the component's environment has marie's variables and none of the service plumbing */
    char env[8192] = "";
    for (int i = 0; i < 50 && !strstr(env, "MARIE_NAME="); i++) {
        usleep(100000);
        FILE *e = fopen(envfile, "r");
        if (e) {
            size_t n = fread(env, 1, sizeof env - 1, e);
            env[n] = 0;
            fclose(e);
        }
    }
    assert_non_null(strstr(env, "MARIE_NAME=envdump"));
    assert_non_null(strstr(env, "MARIE_HOST=n1"));
    assert_non_null(strstr(env, "MARIE_SYSTEM="));
    assert_null(strstr(env, "NOTIFY_SOCKET="));
    assert_null(strstr(env, "WATCHDOG_USEC="));

    kill(pid, SIGTERM);
    assert_int_equal(wait_for_msg(fd, "STOPPING=1", 1, 5000, all, sizeof all), 1);
    int status;
    assert_int_equal(waitpid(pid, &status, 0), pid);
    assert_true(WIFEXITED(status));
    assert_int_equal(WEXITSTATUS(status), 0);
    close(fd);
    char cmd[160];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

static void test_no_watchdog_without_env(void **state)
{
    /* Without WATCHDOG_USEC there are no pings, only READY. */
    char dir[] = "/tmp/marie-test-notify-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char sock[128], statedir[128];
    snprintf(sock, sizeof sock, "%s/notify", dir);
    snprintf(statedir, sizeof statedir, "%s/state", dir);
    int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%.100s", sock);
    assert_int_equal(bind(fd, (struct sockaddr *)&sa, sizeof sa), 0);
    const char *bin = getenv("B") ? getenv("B") : "build";
    char am[256];
    snprintf(am, sizeof am, "%s/bin/marie-am", bin);
    pid_t pid = fork();
    if (pid == 0) {
        setenv("NOTIFY_SOCKET", sock, 1);
        unsetenv("WATCHDOG_USEC");
        setenv("MARIE_KEY", "/nonexistent/key", 1);
        execl(am, am, "--host", "n2", "--state-dir", statedir, (char *)NULL);
        _exit(127);
    }
    char all[4096] = "";
    assert_int_equal(wait_for_msg(fd, "READY=1", 1, 10000, all, sizeof all), 1);
    assert_int_equal(wait_for_msg(fd, "WATCHDOG=1", 1, 600, all, sizeof all), 0);
    kill(pid, SIGTERM);
    int status;
    waitpid(pid, &status, 0);
    close(fd);
    char cmd[160];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

/* Receive notify datagrams until no WATCHDOG=1 has come for gap_ms (1) or timeout_ms passes
 * (0); *pings counts those seen. */
static int wait_for_gap(int fd, int gap_ms, int timeout_ms, int *pings)
{
    int64_t end = mono_ms() + timeout_ms, last = mono_ms();
    while (mono_ms() < end) {
        if (mono_ms() - last >= gap_ms)
            return 1;
        struct pollfd p = {fd, POLLIN, 0};
        if (poll(&p, 1, 100) <= 0)
            continue;
        char buf[512];
        ssize_t n = recv(fd, buf, sizeof buf - 1, 0);
        if (n <= 0)
            continue;
        buf[n] = 0;
        if (strstr(buf, "WATCHDOG=1")) {
            (*pings)++;
            last = mono_ms();
        }
    }
    return 0;
}

static void test_watchdog_stops_when_loop_stalls(void **state)
{
    /* The loop is stuck for real, not the process stopped: once READY, the file the manager
     * rewrites when a component exits (STATE/children.tmp) is made a FIFO nobody reads, so
     * its open() blocks the loop when the component ends 2 s later. A ping from a timer
     * thread would go on; systemd must see the pings stop. */
    char dir[] = "/tmp/marie-test-notify-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char sock[128], statedir[128], fifo[200], done[200], sys[160];
    snprintf(sock, sizeof sock, "%s/notify", dir);
    snprintf(statedir, sizeof statedir, "%s/state", dir);
    snprintf(fifo, sizeof fifo, "%s/children.tmp", statedir);
    snprintf(done, sizeof done, "%s/children", statedir);
    snprintf(sys, sizeof sys, "%s/sys.yaml", dir);
    FILE *f = fopen(sys, "w");
    assert_non_null(f);
    fprintf(f, "system: stall\nhosts: [n3]\ncomponents:\n  brief:\n    exec: 'exec sleep 2'\n"
               "    shell: true\n    heartbeat_timeout: 0\n    restart: {policy: never}\n");
    fclose(f);
    int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    snprintf(sa.sun_path, sizeof sa.sun_path, "%.100s", sock);
    assert_int_equal(bind(fd, (struct sockaddr *)&sa, sizeof sa), 0);
    const char *bin = getenv("B") ? getenv("B") : "build";
    char am[256];
    snprintf(am, sizeof am, "%s/bin/marie-am", bin);
    pid_t pid = fork();
    assert_true(pid >= 0);
    if (pid == 0) {
        setenv("NOTIFY_SOCKET", sock, 1);
        setenv("WATCHDOG_USEC", "300000", 1);
        unsetenv("WATCHDOG_PID");
        setenv("MARIE_KEY", "/nonexistent/key", 1);
        execl(am, am, "--host", "n3", "--state-dir", statedir, "--system", sys, (char *)NULL);
        _exit(127);
    }
    char all[8192] = "";
    assert_int_equal(wait_for_msg(fd, "READY=1", 1, 10000, all, sizeof all), 1);
    assert_int_equal(mkfifo(fifo, 0600), 0);
    /* pings every 150 ms, then none for 2 s (thirteen periods) once the component ends */
    int pings = 0;
    int gap = wait_for_gap(fd, 2000, 20000, &pings);
    printf("pings before the loop stuck: %d, then %s\n", pings, gap ? "none for 2 s" : "no gap");
    assert_true(gap);
    /* a reader comes: the manager finishes its write (the FIFO is renamed into place), the
     * loop goes on, and so do the pings */
    int rd = open(fifo, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    assert_true(rd >= 0);
    assert_int_equal(wait_for_msg(fd, "WATCHDOG=1", 3, 10000, all, sizeof all), 3);
    struct stat st;
    assert_int_equal(stat(done, &st), 0);
    assert_true(S_ISFIFO(st.st_mode));
    kill(pid, SIGTERM);
    int status;
    assert_int_equal(waitpid(pid, &status, 0), pid);
    close(rd);
    close(fd);
    char cmd[160];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ready_watchdog_stopping),
        cmocka_unit_test(test_no_watchdog_without_env),
        cmocka_unit_test(test_watchdog_stops_when_loop_stalls),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
