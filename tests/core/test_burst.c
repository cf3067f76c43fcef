/* test_burst: every message of a burst of large ones reaches a subscriber in another process,
 * whole and in order, before the next burst is published, while two busy loops hold both cores. */
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmocka.h>

#include "core/component.h"
#include "tests/proc.h"

#define SIZE 921600         /* a 640 x 480 RGB image */
#define PER_BURST 6
#define BURSTS 5
#define PERIOD_MS 300       /* from one burst's publish to the next */
#define N (PER_BURST * BURSTS)

/* What the subscriber process saw, in memory both processes map. */
typedef struct {
    _Atomic int ready;
    _Atomic int count;              /* messages handed over */
    _Atomic int order[N];           /* the sequence numbers, in the order they came */
    _Atomic int came[N];            /* per sequence number: 1 came, 2 came with the bytes sent */
} seen_t;

static seen_t *seen;

/* Message k's bytes: a pattern of its own, so a mixed or stale payload shows. */
static uint8_t byte_of(int k, int i) { return (uint8_t)(k * 31 + i * 7 + (i >> 11)); }

static void on_image(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    const marie_image_t *m = msg;
    int k = m->row_stride, ok = m->size == SIZE && k >= 0 && k < N;
    for (int i = 0; ok && i < SIZE; i += 4093)
        ok = m->data[i] == byte_of(k, i);
    int at = atomic_fetch_add(&seen->count, 1);
    if (at < N)
        atomic_store(&seen->order[at], k);
    if (k >= 0 && k < N)
        atomic_store(&seen->came[k], 1 + ok);
}

static int rx_init(marie_component_t *c)
{
    atomic_store(&seen->ready, 1);
    return marie_port_on_message(marie_port(c, "in"), on_image);
}

static const marie_port_spec_t rx_ports[] = {{"in", &marie_type_image_t, MARIE_IN, MARIE_PUSH, "T_BURST"}, {0}};
static const marie_port_spec_t tx_ports[] = {{"out", &marie_type_image_t, MARIE_OUT, MARIE_PUSH, "T_BURST"}, {0}};
static const marie_component_def_t rx_def = {.kind = "burst-rx", .ports = rx_ports, .on_init = rx_init};
static const marie_component_def_t tx_def = {.kind = "burst-tx", .ports = tx_ports};

static int subscriber_ready(void *user) { return atomic_load(&seen->ready); }

static void every_message_of_a_burst_arrives_before_the_next(void **state)
{
    seen = mmap(NULL, sizeof *seen, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
    assert_true(seen != MAP_FAILED);
    pid_t rx = fork();
    if (rx == 0)
        _exit(marie_main(&rx_def, 3, (char *[]){"burst-rx", "--name", "burst-rx", NULL}, NULL));
    marie_errors_t e = {0};
    marie_component_t *tx = marie_component_create(&tx_def, 3, (char *[]){"burst-tx", "--name", "burst-tx"}, NULL, &e);
    assert_non_null(tx);
    const char *why;
    assert_int_equal(marie_component_command(tx, MARIE_CMD_INIT, &why), 0);
    assert_int_equal(marie_component_command(tx, MARIE_CMD_START, &why), 0);
    marie_loop_t *loop = marie_component_loop(tx);
    assert_int_equal(marie_loop_run_until(loop, 5000, subscriber_ready, NULL), 1);
    marie_loop_run_until(loop, 200, NULL, NULL);    /* its subscription is in place */
    pid_t busy[2] = {0};
    assert_int_equal(test_busy_start(busy, 2), 0);
    uint8_t *px = malloc(SIZE);
    marie_image_t img = {.width = 640, .height = 480, .row_stride = 0, .format = MARIE_IMAGE_T_FORMAT_RGB8,
                         .size = SIZE, .data = px};
    int late = 0;
    for (int b = 0; b < BURSTS; b++) {
        for (int k = b * PER_BURST; k < (b + 1) * PER_BURST; k++) {
            for (int i = 0; i < SIZE; i++)
                px[i] = byte_of(k, i);
            img.row_stride = k;
            img.utime = marie_wall_us();
            assert_int_equal(marie_port_publish(marie_port(tx, "out"), &img), 0);
        }
        marie_loop_run_until(loop, PERIOD_MS, NULL, NULL);
        int got = 0;
        for (int k = b * PER_BURST; k < (b + 1) * PER_BURST; k++)
            got += atomic_load(&seen->came[k]) != 0;
        if (got < PER_BURST) {
            print_message("burst %d: %d of its %d messages came within %d ms\n", b, got, PER_BURST, PERIOD_MS);
            late++;
        }
    }
    test_busy_stop(busy, 2);
    free(px);
    kill(rx, SIGTERM);
    waitpid(rx, NULL, 0);
    marie_component_destroy(tx);
    assert_int_equal(late, 0);
    assert_int_equal(atomic_load(&seen->count), N);
    for (int i = 0; i < N; i++) {
        assert_int_equal(atomic_load(&seen->order[i]), i);
        assert_int_equal(atomic_load(&seen->came[i]), 2);
    }
    munmap(seen, sizeof *seen);
}

int main(void)
{
    marie_log_set_threshold(MARIE_LOG_WARN);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(every_message_of_a_burst_arrives_before_the_next),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
