/* test_webserve: the web pages' server on a loop, with real TCP clients in the same thread (so a
 * write that waited would hang the test): a page that never reads loses old state frames and,
 * past the hard bound, is closed while another page gets every frame; half requests cannot keep
 * a file from a browser; malformed requests are answered and counted; the page bound; a
 * fragmented command between pings. And the parsers on RFC 6455's own examples. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include "core/time.h"
#include "tools/webcommon/webproto.h"
#include "tools/webcommon/webserve.h"

typedef struct {
    marie_loop_t *loop;
    webserve_t *w;
    char dir[64];
    int hellos, cmds;
    char cmd[8192];
} fx_t;

static void on_cmd(void *user, int client, const char *addr, bool hello, const char *text, size_t len)
{
    fx_t *f = user;
    if (hello) {
        f->hellos++;
        return;
    }
    f->cmds++;
    snprintf(f->cmd, sizeof f->cmd, "%.*s", (int)len, text);
}

static int setup(void **state)
{
    fx_t *f = calloc(1, sizeof *f);
    snprintf(f->dir, sizeof f->dir, "/tmp/test_webserve.XXXXXX");
    assert_non_null(mkdtemp(f->dir));
    char path[128];
    snprintf(path, sizeof path, "%s/index.html", f->dir);
    FILE *fp = fopen(path, "w");
    fputs("<html>the page</html>\n", fp);
    fclose(fp);
    static const webserve_file_t files[] = {{"/", "index.html", "text/html"}};
    webserve_cfg_t cfg = {.www = f->dir, .files = files, .nfiles = 1, .name = "test", .on_cmd = on_cmd, .user = f};
    char why[256];
    f->loop = marie_loop_create();
    f->w = webserve_start(f->loop, "127.0.0.1", 0, &cfg, why, sizeof why);
    assert_non_null(f->w);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fx_t *f = *state;
    webserve_stop(f->w);
    marie_loop_destroy(f->loop);
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", f->dir);
    assert_int_equal(system(cmd), 0);
    free(f);
    return 0;
}

static int port_of(fx_t *f)
{
    char url[64];
    webserve_url(f->w, NULL, url, sizeof url);
    return atoi(strrchr(url, ':') + 1);
}

static int dial(fx_t *f, int rcvbuf)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    if (rcvbuf)
        setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port_of(f))};
    inet_pton(AF_INET, "127.0.0.1", &sa.sin_addr);
    assert_int_equal(connect(fd, (struct sockaddr *)&sa, sizeof sa), 0);
    return fd;
}

static void say(int fd, const void *data, size_t len)
{
    assert_int_equal(send(fd, data, len, MSG_NOSIGNAL), (ssize_t)len);
}

/* Runs the loop and reads fd until its bytes hold `want` (or 5 s pass); returns them. */
static const char *hear(fx_t *f, int fd, const char *want, char *buf, size_t cap)
{
    size_t len = 0;
    buf[0] = 0;
    for (int64_t end = marie_mono_us() + 5000000; marie_mono_us() < end && !strstr(buf, want);) {
        marie_loop_run_once(f->loop, 5);
        ssize_t n = recv(fd, buf + len, cap - len - 1, MSG_DONTWAIT);
        if (n > 0)
            len += (size_t)n;
        buf[len] = 0;
    }
    return buf;
}

static int page(fx_t *f, int rcvbuf, const char *origin, char *answer, size_t cap)
{
    int fd = dial(f, rcvbuf);
    char req[512];
    int n = snprintf(req, sizeof req,
                     "GET /ws HTTP/1.1\r\nHost: 127.0.0.1:%d\r\nUpgrade: websocket\r\nConnection: keep-alive, Upgrade\r\n"
                     "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\nOrigin: %s\r\n\r\n",
                     port_of(f), origin);
    say(fd, req, (size_t)n);
    hear(f, fd, "\r\n\r\n", answer, cap);
    return fd;
}

static int open_page(fx_t *f, int rcvbuf)
{
    char origin[64], answer[512];
    snprintf(origin, sizeof origin, "http://127.0.0.1:%d", port_of(f));
    int fd = page(f, rcvbuf, origin, answer, sizeof answer);
    assert_non_null(strstr(answer, "HTTP/1.1 101"));
    assert_non_null(strstr(answer, "Sec-WebSocket-Accept: s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\n"));
    return fd;
}

/* A page's reader: whole frames from what it has received so far. */
typedef struct {
    uint8_t buf[1 << 20];
    size_t len;
    int frames, marks, last_mark, last_state;
    bool closed;
} reader_t;

static void take_frame(reader_t *r, int op, const char *data, size_t len)
{
    char p[32];
    size_t n = len < sizeof p - 1 ? len : sizeof p - 1;
    memcpy(p, data, n);
    p[n] = 0;
    r->frames++;
    if (op == WEBWS_CLOSE)
        r->closed = true;
    else if (n > 5 && memcmp(p, "mark ", 5) == 0)
        r->marks++, r->last_mark = atoi(p + 5);
    else if (n > 6 && memcmp(p, "state ", 6) == 0)
        r->last_state = atoi(p + 6);
}

static void drain(int fd, reader_t *r)
{
    ssize_t n;
    while ((n = recv(fd, r->buf + r->len, sizeof r->buf - r->len, MSG_DONTWAIT)) > 0)
        r->len += (size_t)n;
    for (;;) {
        webws_frame_t fr;
        const char *why;
        int hl = webws_parse(&fr, r->buf, r->len, &why);
        assert_true(hl >= 0);
        assert_false(hl > 0 && fr.masked);              /* a server's frames are not masked */
        if (hl == 0 || r->len < hl + fr.len)
            return;
        take_frame(r, fr.op, (const char *)r->buf + hl, (size_t)fr.len);
        memmove(r->buf, r->buf + hl + fr.len, r->len - hl - fr.len);
        r->len -= hl + fr.len;
    }
}

static void pump(fx_t *f, int fd, reader_t *r)
{
    marie_loop_run_once(f->loop, 0);
    drain(fd, r);
}

static void test_a_stalled_page_loses_old_state_and_holds_up_no_one(void **state)
{
    fx_t *f = *state;
    int good = open_page(f, 0), stalled = open_page(f, 2048);
    static reader_t r;
    memset(&r, 0, sizeof r);
    static char frame[32768];
    for (int i = 0; i < 400; i++) {             /* 12.8 MB of state, a mark every 50 frames */
        memset(frame, 'x', sizeof frame);
        int n = snprintf(frame, sizeof frame, "state %d", i);
        frame[n] = ' ';
        webserve_send(f->w, -1, frame, sizeof frame, true);
        if (i % 50 == 49) {
            n = snprintf(frame, sizeof frame, "mark %d", i);
            webserve_send(f->w, -1, frame, (size_t)n, false);
        }
        pump(f, good, &r);
    }
    for (int64_t end = marie_mono_us() + 5000000; r.last_state != 399 && marie_mono_us() < end;)
        pump(f, good, &r);
    webserve_stats_t st;
    webserve_stats(f->w, &st);
    assert_int_equal(r.marks, 8);               /* every mark, in order, and the newest state */
    assert_int_equal(r.last_mark, 399);
    assert_int_equal(r.last_state, 399);
    assert_true(st.dropped > 0);                /* all the stalled page's */
    assert_true(st.dropped < 400);
    assert_int_equal(st.pages, 2);
    assert_int_equal(st.slow_closed, 0);

    /* Frames that may not be dropped: past 16 MB waiting, the stalled page is closed. */
    int before = r.marks;
    for (int i = 0; i < 600; i++) {
        int n = snprintf(frame, sizeof frame, "mark %d", i);
        frame[n] = ' ';
        webserve_send(f->w, -1, frame, sizeof frame, false);
        pump(f, good, &r);
    }
    for (int64_t end = marie_mono_us() + 5000000; r.marks < before + 600 && marie_mono_us() < end;)
        pump(f, good, &r);
    webserve_stats(f->w, &st);
    assert_int_equal(r.marks, before + 600);
    assert_int_equal(st.slow_closed, 1);
    assert_int_equal(st.pages, 1);
    close(good);
    close(stalled);
}

static void test_half_requests_cannot_keep_the_page_from_a_browser(void **state)
{
    fx_t *f = *state;
    int held[WEBSERVE_MAX_CONNS + 6];
    for (int i = 0; i < WEBSERVE_MAX_CONNS + 6; i++) {
        held[i] = dial(f, 0);
        say(held[i], "GET / HTTP/1.1\r\nHost: x\r\n", 25);
        marie_loop_run_once(f->loop, 0);
    }
    int fd = dial(f, 0);
    say(fd, "GET / HTTP/1.1\r\nHost: x\r\n\r\n", 27);
    char buf[4096];
    hear(f, fd, "</html>", buf, sizeof buf);
    assert_non_null(strstr(buf, "HTTP/1.1 200 OK\r\n"));
    assert_non_null(strstr(buf, "<html>the page</html>"));
    webserve_stats_t st;
    webserve_stats(f->w, &st);
    assert_true(st.refused >= 6);
    assert_true(st.conns <= WEBSERVE_MAX_CONNS);
    for (int i = 0; i < WEBSERVE_MAX_CONNS + 6; i++)
        close(held[i]);
    close(fd);
}

static void test_malformed_requests_are_answered_and_counted(void **state)
{
    fx_t *f = *state;
    static const struct {
        const char *req, *answer;
    } cases[] = {
        {"GARBAGE\r\n\r\n", "HTTP/1.1 400"},
        {"GET / HTTP/1.1\r\n\r\n", "HTTP/1.1 400"},                        /* no Host */
        {"GET / HTTP/1.1\r\nHost: x\r\n folded\r\n\r\n", "HTTP/1.1 400"},
        {"GET / HTTP/2.0\r\nHost: x\r\n\r\n", "HTTP/1.1 505"},
        {"GET /nothing HTTP/1.1\r\nHost: x\r\n\r\n", "HTTP/1.1 404"},       /* not malformed */
    };
    char buf[4096];
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        int fd = dial(f, 0);
        say(fd, cases[i].req, strlen(cases[i].req));
        assert_non_null(strstr(hear(f, fd, "\r\n\r\n", buf, sizeof buf), cases[i].answer));
        close(fd);
    }
    int fd = page(f, 0, "http://evil.example", buf, sizeof buf);
    assert_non_null(strstr(buf, "HTTP/1.1 403"));
    close(fd);
    webserve_stats_t st;
    webserve_stats(f->w, &st);
    assert_int_equal(st.bad_requests, 5);
    assert_int_equal(f->hellos, 0);
}

static void test_eight_pages_then_the_ninth_waits_for_room(void **state)
{
    fx_t *f = *state;
    int fds[WEBSERVE_MAX_PAGES];
    for (int i = 0; i < WEBSERVE_MAX_PAGES; i++)
        fds[i] = open_page(f, 0);
    assert_int_equal(f->hellos, WEBSERVE_MAX_PAGES);
    char origin[64], buf[512];
    snprintf(origin, sizeof origin, "http://127.0.0.1:%d", port_of(f));
    int ninth = page(f, 0, origin, buf, sizeof buf);
    assert_non_null(strstr(buf, "HTTP/1.1 503"));
    close(ninth);
    close(fds[0]);
    webserve_stats_t st;
    for (int64_t end = marie_mono_us() + 5000000; marie_mono_us() < end; marie_loop_run_once(f->loop, 5))
        if (webserve_stats(f->w, &st), st.pages < WEBSERVE_MAX_PAGES)
            break;
    fds[0] = open_page(f, 0);
    for (int i = 0; i < WEBSERVE_MAX_PAGES; i++)
        close(fds[i]);
}

static size_t client_frame(uint8_t *out, bool fin, int op, const char *data)
{
    size_t n = strlen(data), h = webws_head(out, op, n);
    out[0] = (uint8_t)((fin ? 0x80 : 0) | op);
    out[1] |= 0x80;
    uint8_t mask[4] = {0x37, 0xfa, 0x21, 0x3d};
    memcpy(out + h, mask, 4);
    memcpy(out + h + 4, data, n);
    webws_unmask(out + h + 4, n, mask, 0);
    return h + 4 + n;
}

static void test_a_fragmented_command_between_pings(void **state)
{
    fx_t *f = *state;
    int fd = open_page(f, 0);
    uint8_t msg[256];
    size_t n = client_frame(msg, false, WEBWS_TEXT, "{\"op\":");
    n += client_frame(msg + n, true, WEBWS_PING, "are you there");
    n += client_frame(msg + n, true, WEBWS_CONT, "\"pause\"}");
    say(fd, msg, n);
    char buf[512];
    hear(f, fd, "are you there", buf, sizeof buf);
    assert_int_equal((uint8_t)buf[0], 0x80 | WEBWS_PONG);
    assert_int_equal(f->cmds, 1);
    assert_string_equal(f->cmd, "{\"op\":\"pause\"}");
    /* an unmasked frame is a protocol error: closed with 1002 and counted */
    say(fd, "\x81\x02hi", 4);
    hear(f, fd, "unmasked", buf, sizeof buf);
    assert_int_equal((uint8_t)buf[0], 0x80 | WEBWS_CLOSE);
    assert_int_equal((uint8_t)buf[2] << 8 | (uint8_t)buf[3], 1002);
    webserve_stats_t st;
    webserve_stats(f->w, &st);
    assert_int_equal(st.bad_requests, 1);
    assert_int_equal(st.pages, 0);              /* closing: its place is free before its socket */
    close(fd);
}

static void test_parsers_on_the_rfcs_examples(void **state)
{
    char accept[29];
    assert_int_equal(webws_accept("dGhlIHNhbXBsZSBub25jZQ==", accept), 0);       /* RFC 6455 1.3 */
    assert_string_equal(accept, "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=");
    assert_int_equal(webws_accept("short", accept), -1);
    /* RFC 6455 5.7: a masked "Hello" */
    uint8_t hello[] = {0x81, 0x85, 0x37, 0xfa, 0x21, 0x3d, 0x7f, 0x9f, 0x4d, 0x51, 0x58};
    webws_frame_t fr;
    const char *why;
    assert_int_equal(webws_parse(&fr, hello, 1, &why), 0);
    assert_int_equal(webws_parse(&fr, hello, sizeof hello, &why), 6);
    assert_true(fr.fin && fr.masked && fr.op == WEBWS_TEXT && fr.len == 5);
    webws_unmask(hello + 6, 5, fr.mask, 0);
    assert_memory_equal(hello + 6, "Hello", 5);
    uint8_t rsv[] = {0xc1, 0x00}, ping[] = {0x09, 0x00};                          /* RSV1; a fragmented ping */
    assert_int_equal(webws_parse(&fr, rsv, 2, &why), -1);
    assert_int_equal(webws_parse(&fr, ping, 2, &why), -1);
    /* a request head, whole or in part */
    const char *req = "GET /ws?x=1 HTTP/1.1\r\nHost: h:1\r\nConnection: keep-alive, Upgrade\r\nUpgrade: WebSocket\r\n\r\n";
    webreq_t r;
    int status = 0;
    assert_int_equal(webreq_parse(&r, req, strlen(req) - 1, &status, &why), 0);
    assert_int_equal(webreq_parse(&r, req, strlen(req), &status, &why), (int)strlen(req));
    assert_string_equal(r.path, "/ws");
    assert_string_equal(r.host, "h:1");
    assert_true(r.upgrade_ws && r.conn_upgrade && r.conn_keep_alive && !r.conn_close);
    static char huge[WEBREQ_HEAD_MAX + 10];
    memset(huge, 'a', sizeof huge);
    assert_int_equal(webreq_parse(&r, huge, sizeof huge, &status, &why), -1);
    assert_int_equal(status, 431);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_a_stalled_page_loses_old_state_and_holds_up_no_one, setup, teardown),
        cmocka_unit_test_setup_teardown(test_half_requests_cannot_keep_the_page_from_a_browser, setup, teardown),
        cmocka_unit_test_setup_teardown(test_malformed_requests_are_answered_and_counted, setup, teardown),
        cmocka_unit_test_setup_teardown(test_eight_pages_then_the_ninth_waits_for_room, setup, teardown),
        cmocka_unit_test_setup_teardown(test_a_fragmented_command_between_pings, setup, teardown),
        cmocka_unit_test(test_parsers_on_the_rfcs_examples),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
