/* test_sdnotify: systemd's notify protocol spoken without libsystemd: the datagram reaches a
 * socket named by a path and one in the abstract namespace ("@name") whole; no socket is not an
 * error; an address form it does not speak is refused; the watchdog interval is read only when
 * it is meant for this process. systemd's own systemd-notify is the peer. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include "managers/sdnotify.h"

/* Bind a datagram socket at `name` ("/path" or "@abstract"); returns the fd. */
static int listen_at(const char *name)
{
    int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    assert_true(fd >= 0);
    struct sockaddr_un sa = {.sun_family = AF_UNIX};
    size_t len = strlen(name);
    memcpy(sa.sun_path, name, len);
    if (name[0] == '@')
        sa.sun_path[0] = '\0';
    socklen_t salen = (socklen_t)(offsetof(struct sockaddr_un, sun_path) + len + (name[0] == '/'));
    assert_int_equal(bind(fd, (struct sockaddr *)&sa, salen), 0);
    return fd;
}

static void expect_datagram(int fd, const char *want)
{
    char buf[256];
    ssize_t n = recv(fd, buf, sizeof buf - 1, MSG_DONTWAIT);
    assert_true(n >= 0);
    buf[n] = 0;
    assert_string_equal(buf, want);
}

static void test_path_and_abstract_sockets(void **state)
{
    char path[64], abstract[64];
    snprintf(path, sizeof path, "/tmp/marie-test-sdnotify-%d", (int)getpid());
    snprintf(abstract, sizeof abstract, "@marie-test-sdnotify-%d", (int)getpid());
    unlink(path);
    int a = listen_at(path), b = listen_at(abstract);
    setenv("NOTIFY_SOCKET", path, 1);
    assert_int_equal(marie_sd_notify("READY=1\nSTATUS=managing host h1"), 1);
    expect_datagram(a, "READY=1\nSTATUS=managing host h1");
    setenv("NOTIFY_SOCKET", abstract, 1);
    assert_int_equal(marie_sd_notify("WATCHDOG=1"), 1);
    expect_datagram(b, "WATCHDOG=1");
    close(a);
    close(b);
    unlink(path);
}

/* systemd's own sender, systemd-notify, to the same sockets: the same datagram as ours, so the
 * address encoding (path, abstract "@") and the payload are what systemd itself uses. */
static void test_same_datagram_as_systemd_notify(void **state)
{
    if (access("/usr/bin/systemd-notify", X_OK) != 0) {
        skip();   /* the systemd package (scripts/install-deps.sh base) */
        return;
    }
    char path[64], abstract[64], cmd[256];
    snprintf(path, sizeof path, "/tmp/marie-test-sdnotify-peer-%d", (int)getpid());
    snprintf(abstract, sizeof abstract, "@marie-test-sdnotify-peer-%d", (int)getpid());
    unlink(path);
    const char *names[] = {path, abstract};
    for (int i = 0; i < 2; i++) {
        int fd = listen_at(names[i]);
        snprintf(cmd, sizeof cmd, "NOTIFY_SOCKET='%s' /usr/bin/systemd-notify --no-block --ready "
                 "--status='managing host h1'", names[i]);
        assert_int_equal(system(cmd), 0);
        char theirs[256], ours[256];
        ssize_t n = recv(fd, theirs, sizeof theirs - 1, MSG_DONTWAIT);
        assert_true(n > 0);
        theirs[n] = 0;
        setenv("NOTIFY_SOCKET", names[i], 1);
        assert_int_equal(marie_sd_notify("READY=1\nSTATUS=managing host h1"), 1);   /* what marie-am sends */
        n = recv(fd, ours, sizeof ours - 1, MSG_DONTWAIT);
        assert_true(n > 0);
        ours[n] = 0;
        assert_string_equal(ours, theirs);
        close(fd);
    }
    unsetenv("NOTIFY_SOCKET");
    unlink(path);
}

static void test_no_socket_and_unknown_forms(void **state)
{
    unsetenv("NOTIFY_SOCKET");
    assert_int_equal(marie_sd_notify("READY=1"), 0);
    setenv("NOTIFY_SOCKET", "vsock:2:1234", 1);
    assert_int_equal(marie_sd_notify("READY=1"), -1);
    assert_int_equal(errno, EAFNOSUPPORT);
    setenv("NOTIFY_SOCKET", "/tmp/marie-test-sdnotify-nobody-listens", 1);
    assert_int_equal(marie_sd_notify("READY=1"), -1);
    unsetenv("NOTIFY_SOCKET");
}

static void test_watchdog_interval(void **state)
{
    char me[32];
    snprintf(me, sizeof me, "%d", (int)getpid());
    unsetenv("WATCHDOG_USEC");
    unsetenv("WATCHDOG_PID");
    assert_int_equal(marie_sd_watchdog_usec(), 0);
    setenv("WATCHDOG_USEC", "300000", 1);
    assert_int_equal(marie_sd_watchdog_usec(), 300000);
    setenv("WATCHDOG_PID", me, 1);
    assert_int_equal(marie_sd_watchdog_usec(), 300000);
    setenv("WATCHDOG_PID", "1", 1);                /* meant for another process */
    assert_int_equal(marie_sd_watchdog_usec(), 0);
    unsetenv("WATCHDOG_PID");
    setenv("WATCHDOG_USEC", "3s", 1);
    assert_int_equal(marie_sd_watchdog_usec(), 0);
    setenv("WATCHDOG_USEC", "0", 1);
    assert_int_equal(marie_sd_watchdog_usec(), 0);
    unsetenv("WATCHDOG_USEC");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_path_and_abstract_sockets),
        cmocka_unit_test(test_same_datagram_as_systemd_notify),
        cmocka_unit_test(test_no_socket_and_unknown_forms),
        cmocka_unit_test(test_watchdog_interval),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
