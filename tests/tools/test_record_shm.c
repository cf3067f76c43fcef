/* test_record_shm: marie-record records channels that the system file moves to shared memory
 * (kind: shm) and to the same-host fast path (kind: local) whole, not only their notices: it
 * asks for them as a subscriber on another host does, and lcm-logger (Debian's, which reads
 * LCM itself) writes what the writers then send. The log is read back with marie's own parser
 * and every image in it is checked byte by byte. */
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmocka.h>

#include "core/component.h"
#include "core/file.h"
#include "core/lcmlog.h"
#include "core/typeinfo.h"
#include "tests/proc.h"

#define SIZE 200000         /* past one datagram: the LCM copies go in fragments */
#define N 40

static const marie_port_spec_t tx_ports[] = {
    {"ring", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "T_REC_SHM"},
    {"fast", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "T_REC_LOCAL"},
    {0},
};
static const marie_component_def_t tx_def = {.kind = "tx", .ports = tx_ports};

static uint8_t byte_of(int k, int i) { return (uint8_t)(k * 7 + i * 3 + (i >> 11)); }

typedef struct {
    int whole[2], intact[2], notices[2];
} got_t;

static void on_event(void *user, const lcmlog_event_t *ev)
{
    got_t *g = user;
    char ch[64];
    snprintf(ch, sizeof ch, "%.*s", (int)ev->channel_len, ev->channel);
    int which = strncmp(ch, "T_REC_SHM", 9) == 0 ? 0 : strncmp(ch, "T_REC_LOCAL", 11) == 0 ? 1 : -1;
    if (which < 0)
        return;
    size_t base = which == 0 ? 9 : 11;
    if (strcmp(ch + base, ".SHM") == 0) {
        g->notices[which]++;
        return;
    }
    if (ch[base])
        return;                 /* the requests (.SHMWANT) */
    marie_image_t img;
    if (marie_decode_checked(&marie_type_image_t, ev->data, ev->data_len, &img) < 0)
        return;
    g->whole[which]++;
    int ok = img.size == SIZE;
    for (int i = 0; ok && i < img.size; i++)
        ok = img.data[i] == byte_of(img.row_stride, i);
    g->intact[which] += ok;
    marie_image_t_decode_cleanup(&img);
}

static void publish(marie_component_t *tx, const char *port, int k)
{
    static uint8_t px[SIZE];
    for (int i = 0; i < SIZE; i++)
        px[i] = byte_of(k, i);
    marie_image_t img = {.width = 1, .height = SIZE, .row_stride = k, .format = MARIE_IMAGE_T_FORMAT_GRAY8,
                         .size = SIZE, .data = px};
    assert_int_equal(marie_port_publish(marie_port(tx, port), &img), 0);
}

static void run(marie_component_t *c, int ms)
{
    for (int64_t end = marie_mono_us() + ms * 1000LL; marie_mono_us() < end;)
        marie_loop_run_once(marie_component_loop(c), 5);
}

static void shm_and_local_channels_are_recorded_whole(void **state)
{
    char sysfile[64] = "/tmp/marie-test-rec-XXXXXX.yaml", logfile[64] = "/tmp/marie-test-rec-XXXXXX";
    assert_int_equal(test_write_temp(sysfile, 5, "system: rec\n"
                                                 "transports:\n"
                                                 "  T_REC_SHM: {kind: shm, max_size: 300000, slots: 4}\n"
                                                 "  T_REC_LOCAL: {kind: local, max_size: 300000, slots: 4}\n"
                                                 "components:\n  tx: {exec: /bin/true}\n"),
                     0);
    assert_int_equal(test_write_temp(logfile, 0, ""), 0);
    /* lcm-logger (liblcm) reads with the URL's receive buffer: the kernel's default of 208 KB
     * holds one of these images */
    setenv("LCM_DEFAULT_URL", "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304", 1);
    char *argv[] = {"tx", "--system", sysfile, "--name", "tx"};
    marie_errors_t e = {0};
    marie_component_t *tx = marie_component_create(&tx_def, 5, argv, NULL, &e);
    marie_errors_print(&e, stderr);
    assert_non_null(tx);
    const char *why;
    assert_int_equal(marie_component_command(tx, MARIE_CMD_INIT, &why), 0);
    assert_int_equal(marie_component_command(tx, MARIE_CMD_START, &why), 0);

    /* a plain name (asked for from the start) and a pattern (asked for once a notice names it) */
    char rec[256];
    snprintf(rec, sizeof rec, "%s/bin/marie-record", getenv("B") ? getenv("B") : "build");
    char *rargv[] = {rec, "-q", "-f", "--min-free", "0", "-o", logfile, "-c", "T_REC_SHM", "-c", "T_REC_LOC.*", NULL};
    pid_t r = test_spawn(rargv, NULL);
    assert_true(r > 0);
    run(tx, 1500);              /* python and lcm-logger start */
    for (int k = 1; k <= N; k++) {
        publish(tx, "ring", k);
        run(tx, 25);
        publish(tx, "fast", k);
        run(tx, 25);
    }
    run(tx, 300);
    kill(r, SIGINT);
    int st;
    assert_int_equal(waitpid(r, &st, 0), r);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
    marie_component_destroy(tx);

    size_t len;
    char *text = marie_file_read(logfile, 1 << 30, &len);
    assert_non_null(text);
    got_t g = {0};
    lcmlog_parser_t *p = lcmlog_parser_create(on_event, NULL, &g);
    lcmlog_parser_feed(p, text, len);
    lcmlog_parser_finish(p);
    lcmlog_parser_destroy(p);
    free(text);
    unlink(logfile);
    unlink(sysfile);
    fprintf(stderr, "shm: %d whole (%d intact), %d notices; local: %d whole (%d intact), %d notices\n", g.whole[0],
            g.intact[0], g.notices[0], g.whole[1], g.intact[1], g.notices[1]);
    /* every shm image once its writer had heard the first request (within the first few) */
    assert_true(g.whole[0] >= N - 4);
    assert_int_equal(g.intact[0], g.whole[0]);
    assert_true(g.notices[0] >= N - 4);
    /* the fast path's notice comes once a second, with its first message: every image after it */
    assert_true(g.whole[1] >= N - 6);
    assert_int_equal(g.intact[1], g.whole[1]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(shm_and_local_channels_are_recorded_whole),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
