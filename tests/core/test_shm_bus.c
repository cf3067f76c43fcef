/* test_shm_bus: shared-memory publishers and subscribers on a real LCM bus (this test's
 * namespace): local subscribers read the ring and nothing whole goes on LCM; the notices are
 * there for lcm-spy, a subscriber in place reads them in their held slot; a subscriber on
 * "another host" asks and gets the messages over LCM. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "core/config.h"
#include "core/bus/shm_bus.h"
#include "core/time.h"
#include "core/typeinfo.h"
#include "tests/fails.h"
#include "tests/proc.h"

#define SIZE (100 * 1024)

typedef struct {
    long got, bad;
    uint8_t last;
} sink_t;

static void on_msg(const void *data, size_t len, void *user)
{
    sink_t *s = user;
    const uint8_t *p = data;
    /* every byte after the fingerprint carries the message number */
    if (len != SIZE || p[8] != p[len - 1])
        s->bad++;
    s->last = p[len - 1];
    s->got++;
}

static long notices, whole;

static void on_notice(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    marie_shm_notice_t n;
    if (marie_decode_checked(&marie_type_shm_notice_t, rb->data, rb->data_size, &n) == 0) {
        if (n.size == SIZE && n.seq > 0)
            notices++;
        marie_shm_notice_t_decode_cleanup(&n);
    }
}

static void on_whole(const lcm_recv_buf_t *rb, const char *ch, void *user) { whole++; }

static void message(uint8_t *m, int i)
{
    memset(m, i & 0xff, SIZE);
    memcpy(m, "\x12\x34\x56\x78\x9a\xbc\xde\xf0", 8);
}

static void spin(lcm_t **l, int n, int ms)
{
    for (int64_t end = marie_mono_us() + ms * 1000; marie_mono_us() < end;)
        for (int k = 0; k < n; k++)
            lcm_handle_timeout(l[k], 1);
}

static long held_in_ring;
static void on_held(const void *data, size_t len, void *user)
{
    held_in_ring += test_in_ring(data, len);
    on_msg(data, len, user);
}

static bool verdicts_ok = true;
static void on_verdict(bool ok, void *user) { verdicts_ok = verdicts_ok && ok; }

static void test_local_subscribers_read_the_ring(void **state)
{
    const char *url = marie_default_url();
    lcm_t *l[5];
    for (int k = 0; k < 5; k++)
        assert_non_null(l[k] = lcm_create(url));
    marie_shm_pub_t *pub = marie_shm_pub_create(l[0], "CAM", SIZE, 8);
    assert_non_null(pub);
    sink_t sink[3] = {{0}};
    marie_shm_sub_t *sub[3];
    for (int k = 0; k < 3; k++)
        assert_non_null(sub[k] = marie_shm_sub_create(l[k + 1], "CAM", SIZE, on_msg, &sink[k]));
    marie_shm_sub_in_place(sub[1], on_verdict); /* one reads in place, its slot held */
    marie_shm_sub_held(sub[1], on_held);
    marie_shm_sub_in_place(sub[2], NULL);       /* NULL: copy first, the default */
    lcm_subscribe(l[4], "CAM.SHM", on_notice, NULL);   /* what lcm-spy sees */
    lcm_subscribe(l[4], "CAM", on_whole, NULL);
    uint8_t *m = malloc(SIZE);
    for (int i = 1; i <= 20; i++) {
        message(m, i);
        assert_int_equal(marie_shm_pub_publish(pub, m, SIZE), 0);
        spin(l, 5, 20);
    }
    spin(l, 5, 200);
    for (int k = 0; k < 3; k++) {
        assert_int_equal(sink[k].got, 20);
        assert_int_equal(sink[k].bad, 0);
        assert_int_equal(marie_shm_sub_stats(sub[k])->received, 20);
        assert_int_equal(marie_shm_sub_stats(sub[k])->remote, 0);
    }
    assert_true(verdicts_ok);
    assert_int_equal(held_in_ring, 20);
    assert_int_equal(notices, 20);
    assert_int_equal(whole, 0);                 /* nobody asked: nothing big on LCM */
    assert_int_equal(marie_shm_pub_stats(pub)->lcm_copies, 0);
    /* Too big for a slot: refused, counted. */
    uint8_t *big = calloc(1, SIZE + 1);
    assert_fails(marie_shm_pub_publish(pub, big, SIZE + 1), EMSGSIZE);
    free(big);
    for (int k = 0; k < 3; k++)
        marie_shm_sub_destroy(sub[k]);
    marie_shm_pub_destroy(pub);
    for (int k = 0; k < 5; k++)
        lcm_destroy(l[k]);
    free(m);
}

static void test_remote_subscriber_gets_lcm_copies(void **state)
{
    const char *url = marie_default_url();
    lcm_t *l[2];
    for (int k = 0; k < 2; k++)
        assert_non_null(l[k] = lcm_create(url));
    sink_t far = {0};
    setenv("MARIE_SHM_HOST", "far-away", 1);    /* this subscriber plays another machine */
    marie_shm_sub_t *sub = marie_shm_sub_create(l[1], "MAP", SIZE, on_msg, &far);
    unsetenv("MARIE_SHM_HOST");
    marie_shm_sub_in_place(sub, on_verdict);    /* no effect on LCM copies */
    marie_shm_pub_t *pub = marie_shm_pub_create(l[0], "MAP", SIZE, 8);
    assert_non_null(sub);
    assert_non_null(pub);
    uint8_t *m = malloc(SIZE);
    /* The first notice tells the subscriber the writer is elsewhere: it asks... */
    message(m, 1);
    marie_shm_pub_publish(pub, m, SIZE);
    spin(l, 2, 200);
    assert_int_equal(far.got, 0);
    assert_true(marie_shm_pub_stats(pub)->wants >= 1);
    /* ...and from then on the messages come whole over LCM. */
    for (int i = 2; i <= 6; i++) {
        message(m, i);
        marie_shm_pub_publish(pub, m, SIZE);
        spin(l, 2, 50);
    }
    spin(l, 2, 200);
    assert_int_equal(far.got, 5);
    assert_int_equal(far.bad, 0);
    assert_int_equal(far.last, 6);
    assert_int_equal(marie_shm_sub_stats(sub)->remote, 5);
    assert_int_equal(marie_shm_sub_stats(sub)->received, 0);
    assert_int_equal(marie_shm_pub_stats(pub)->lcm_copies, 5);
    assert_true(verdicts_ok);
    marie_shm_sub_destroy(sub);
    marie_shm_pub_destroy(pub);
    for (int k = 0; k < 2; k++)
        lcm_destroy(l[k]);
    free(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_local_subscribers_read_the_ring),
        cmocka_unit_test(test_remote_subscriber_gets_lcm_copies),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
