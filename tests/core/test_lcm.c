/* test_lcm: marie's own reader and sender of LCM's UDP multicast (core/bus/bus.h) against liblcm as
 * the peer (lcm_publish with its own fragmentation; lcm_subscribe and lcm_handle reading what
 * marie_bus_publish sent), and against hand-made datagrams that are not what LCM sends. Runs in
 * its own network namespace (make test). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "core/bus/bus.h"
#include "core/bus/provider.h"
#include "core/loop.h"
#include "core/time.h"
#include "tests/udp.h"

#define URL "udpm://239.255.76.67:7667?ttl=0"

typedef struct {
    int n;
    uint32_t sizes[32];  /* of the first 32 messages, in their order of arrival */
    char channel[64];
    uint8_t *data;      /* the last message */
    uint32_t size;
    int bad;            /* messages whose bytes were not the pattern */
} got_t;

static void pattern(uint8_t *p, size_t n, unsigned seed)
{
    for (size_t i = 0; i < n; i++)
        p[i] = (uint8_t)(i * 31 + seed);
}

static void on_msg(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    got_t *g = user;
    if (g->n < 32)
        g->sizes[g->n] = rb->data_size;
    g->n++;
    snprintf(g->channel, sizeof g->channel, "%s", channel);
    free(g->data);
    g->data = malloc(rb->data_size ? rb->data_size : 1);
    memcpy(g->data, rb->data, rb->data_size);
    g->size = rb->data_size;
    uint8_t *want = malloc(rb->data_size ? rb->data_size : 1);
    pattern(want, rb->data_size, rb->data_size ? ((uint8_t *)rb->data)[0] : 0);
    if (memcmp(want, rb->data, rb->data_size) != 0)
        g->bad++;
    free(want);
}

/* Handles what arrives for ms milliseconds, or until `until` messages came to g. */
static void pump(lcm_t *lcm, got_t *g, int until, int ms)
{
    int64_t end = marie_mono_us() + ms * 1000;
    while (marie_mono_us() < end && (!g || g->n < until)) {
        struct pollfd p = {marie_bus_fd(lcm), POLLIN, 0};
        if (poll(&p, 1, 10) > 0)
            marie_bus_handle(lcm, 64);
    }
}

static void publish_pattern(lcm_t *pub, const char *channel, size_t n, unsigned seed)
{
    uint8_t *p = malloc(n);
    pattern(p, n, seed);
    assert_int_equal(lcm_publish(pub, channel, p, (unsigned)n), 0);
    free(p);
}

/* liblcm sends short messages and fragmented ones; marie gets every byte, in order. */
static void test_from_liblcm(void **state)
{
    lcm_t *pub = lcm_create(URL), *rx = marie_bus_create(URL);
    assert_non_null(pub);
    assert_non_null(rx);
    assert_true(marie_bus_native(rx));
    got_t small = {0}, big = {0};
    assert_non_null(marie_bus_subscribe(rx, "T_SMALL", on_msg, &small));
    assert_non_null(marie_bus_subscribe(rx, "T_BIG\\.[0-9]+", on_msg, &big));
    const size_t sizes[] = {0, 1, 64, 8192, 65000};
    for (size_t i = 0; i < 5; i++) {
        publish_pattern(pub, "T_SMALL", sizes[i], 0);
        pump(rx, &small, (int)i + 1, 2000);
        assert_int_equal(small.n, (int)i + 1);
        assert_int_equal(small.size, sizes[i]);
    }
    for (unsigned k = 0; k < 3; k++) {
        publish_pattern(pub, "T_BIG.42", 921600 + k, 7 * k);
        pump(rx, &big, (int)k + 1, 2000);
        assert_int_equal(big.n, (int)k + 1);
        assert_int_equal(big.size, 921600 + k);
        assert_string_equal(big.channel, "T_BIG.42");
        assert_int_equal(big.data[0], (uint8_t)(7 * k));
    }
    publish_pattern(pub, "T_BIG.x", 100000, 0);     /* not matched by the expression */
    publish_pattern(pub, "T_BIG.7", 100000, 3);
    pump(rx, &big, 4, 2000);
    assert_int_equal(big.n, 4);
    assert_string_equal(big.channel, "T_BIG.7");
    assert_int_equal(small.bad + big.bad, 0);
    marie_bus_stats_t st;
    marie_bus_stats(rx, &st);
    assert_int_equal(st.messages, 10);
    assert_int_equal(st.malformed + st.incomplete + st.dropped, 0);
    free(small.data);
    free(big.data);
    marie_bus_destroy(rx);
    lcm_destroy(pub);
}

/* Short messages on channels nobody subscribes to never leave the kernel (a socket filter made
 * from the subscriptions); a subscription that may match anything lets everything through. */
static void test_kernel_filter(void **state)
{
    lcm_t *pub = lcm_create(URL), *rx = marie_bus_create(URL);
    got_t a = {0}, b = {0}, any = {0};
    marie_bus_subscribe(rx, "T_FILT_A", on_msg, &a);
    marie_bus_sub_t *sb = marie_bus_subscribe(rx, "T_FILT_B[0-9]*", on_msg, &b);
    const char *chans[] = {"T_FILT_A", "T_FILT_AB", "T_FILT_", "T_FILT_B", "T_FILT_B12", "T_FILT_Bx", "OTHER", "T"};
    for (int i = 0; i < 8; i++)
        publish_pattern(pub, chans[i], 10, 0);
    pump(rx, NULL, 0, 300);
    marie_bus_stats_t st;
    marie_bus_stats(rx, &st);
    assert_int_equal(a.n, 1);
    assert_int_equal(b.n, 2);
    /* T_FILT_B, T_FILT_B12 and T_FILT_Bx start as the expression's literal part: read, and
     * the last refused by the expression; the other five never read. */
    assert_int_equal(st.messages, 4);
    marie_bus_unsubscribe(rx, sb);
    marie_bus_sub_t *sa = marie_bus_subscribe(rx, ".*", on_msg, &any);
    for (int i = 0; i < 8; i++)
        publish_pattern(pub, chans[i], 10, 0);
    pump(rx, &any, 8, 2000);
    assert_int_equal(any.n, 8);
    assert_int_equal(a.n, 2);
    assert_int_equal(b.n, 2);
    marie_bus_unsubscribe(rx, sa);
    publish_pattern(pub, "OTHER", 10, 0);
    publish_pattern(pub, "T_FILT_A", 10, 0);
    pump(rx, &a, 3, 2000);
    marie_bus_stats(rx, &st);
    assert_int_equal(st.messages, 4 + 8 + 1);
    free(a.data);
    free(b.data);
    free(any.data);
    marie_bus_destroy(rx);
    lcm_destroy(pub);
}

/* A liblcm reader and marie's reader on the same host both get each message. */
static void test_beside_liblcm(void **state)
{
    lcm_t *pub = lcm_create(URL), *lib = lcm_create(URL), *rx = marie_bus_create(URL);
    got_t a = {0}, b = {0};
    assert_non_null(lcm_subscribe(lib, "T_BOTH", on_msg, &a));
    assert_non_null(marie_bus_subscribe(rx, "T_BOTH", on_msg, &b));
    publish_pattern(pub, "T_BOTH", 100000, 1);     /* liblcm's socket holds 208 kB here */
    pump(rx, &b, 1, 2000);
    lcm_handle_timeout(lib, 2000);
    assert_int_equal(a.n, 1);
    assert_int_equal(b.n, 1);
    assert_int_equal(a.size, b.size);
    assert_memory_equal(a.data, b.data, a.size);
    free(a.data);
    free(b.data);
    marie_bus_destroy(rx);
    lcm_destroy(lib);
    lcm_destroy(pub);
}

static void send_raw(int fd, const void *d, size_t n)
{
    assert_int_equal(test_udp_send(fd, d, n), (ssize_t)n);
}

static size_t short_msg(uint8_t *out, uint32_t seq, const char *channel, const char *text)
{
    uint32_t h[2] = {htonl(0x4c433032), htonl(seq)};
    memcpy(out, h, 8);
    size_t cl = strlen(channel) + 1, tl = strlen(text);
    memcpy(out + 8, channel, cl);
    memcpy(out + 8 + cl, text, tl);
    return 8 + cl + tl;
}

/* A fragment: header, then (fragment 0) the channel, then len bytes of data. */
static size_t fragment(uint8_t *out, uint32_t seq, uint32_t size, uint32_t offset, uint16_t no, uint16_t count,
                       const char *channel, size_t len)
{
    uint32_t h[4] = {htonl(0x4c433033), htonl(seq), htonl(size), htonl(offset)};
    uint16_t f[2] = {htons(no), htons(count)};
    memcpy(out, h, 16);
    memcpy(out + 16, f, 4);
    size_t k = 20;
    if (channel) {
        memcpy(out + k, channel, strlen(channel) + 1);
        k += strlen(channel) + 1;
    }
    memset(out + k, 'x', len);
    return k + len;
}

/* Datagrams that are not LCM's, or contradict themselves: counted, never delivered, and the
 * bus keeps working. */
static void test_malformed(void **state)
{
    lcm_t *rx = marie_bus_create(URL);
    got_t g = {0}, other = {0};
    assert_non_null(marie_bus_subscribe(rx, "T_BAD", on_msg, &g));
    /* Short messages whose channel cannot match a subscription are dropped by the kernel's
     * filter, unread and uncounted (like anyone's traffic on other channels): this one lets
     * channels that start "T_BAD" through, terminated or not. */
    assert_non_null(marie_bus_subscribe(rx, "T_BAD.+", on_msg, &other));
    int fd = test_udp_socket();
    static uint8_t d[70000];
    send_raw(fd, "LC0", 3);                                        /* shorter than a header */
    send_raw(fd, "hello world, not LCM", 20);                      /* no magic */
    memcpy(d, "LC02\0\0\0\1T_BAD", 13);
    memset(d + 13, 'A', 95);
    send_raw(fd, d, 108);                                           /* channel never ends */
    send_raw(fd, d, fragment(d, 1, 100, 0, 0, 0, "T_BAD", 10));     /* no fragments */
    send_raw(fd, d, fragment(d, 1, 100, 0, 3, 2, NULL, 10));        /* fragment 3 of 2 */
    send_raw(fd, d, fragment(d, 1, 100, 95, 1, 2, NULL, 10));       /* past the end */
    send_raw(fd, d, fragment(d, 1, 100, 4, 0, 2, "T_BAD", 10));     /* first one not at 0 */
    send_raw(fd, d, fragment(d, 1, 1u << 30, 0, 0, 2, "T_BAD", 10)); /* a gigabyte */
    pump(rx, NULL, 0, 300);
    marie_bus_stats_t st;
    marie_bus_stats(rx, &st);
    assert_int_equal(st.malformed, 8);
    assert_int_equal(g.n, 0);
    /* Every fragment came, but they overlap and leave a hole: refused whole. */
    send_raw(fd, d, fragment(d, 2, 100, 0, 0, 2, "T_BAD", 50));
    send_raw(fd, d, fragment(d, 2, 100, 40, 1, 2, NULL, 50));
    /* A message started and abandoned for the next one: counted incomplete. */
    send_raw(fd, d, fragment(d, 3, 100, 0, 0, 2, "T_BAD", 50));
    send_raw(fd, d, short_msg(d, 4, "T_BAD", "fine"));
    pump(rx, &g, 1, 2000);
    send_raw(fd, d, fragment(d, 5, 100, 50, 1, 2, NULL, 50));        /* out of order, */
    send_raw(fd, d, fragment(d, 5, 100, 50, 1, 2, NULL, 50));        /* a duplicate: ignored, */
    send_raw(fd, d, fragment(d, 5, 100, 0, 0, 2, "T_BAD", 50));      /* the first: whole */
    pump(rx, &g, 2, 2000);
    marie_bus_stats(rx, &st);
    assert_int_equal(st.malformed, 9);
    assert_int_equal(st.incomplete, 1);
    assert_int_equal(g.n, 2);
    assert_int_equal(g.size, 100);
    assert_int_equal(other.n, 0);
    close(fd);
    free(g.data);
    marie_bus_destroy(rx);
}

/* A fragment of size bytes at offset, its data the pattern on_msg expects (seed 0). */
static size_t pattern_fragment(uint8_t *out, uint32_t seq, uint32_t size, uint32_t offset, uint16_t no,
                               uint16_t count, const char *channel, size_t len)
{
    size_t n = fragment(out, seq, size, offset, no, count, channel, len);
    for (size_t i = 0; i < len; i++)
        out[n - len + i] = (uint8_t)((offset + i) * 31);
    return n;
}

/* Short messages someone takes are read whole, one system call each; a fragment that comes
 * after one is copied into its place from there, and what follows a fragment is peeked again.
 * Queued together and read in one call: every message whole, in the order it was completed. */
static void test_fragments_among_shorts(void **state)
{
    lcm_t *rx = marie_bus_create(URL);
    got_t all = {0};
    assert_non_null(marie_bus_subscribe(rx, "T_MIX_S", on_msg, &all));
    assert_non_null(marie_bus_subscribe(rx, "T_MIX_B", on_msg, &all));
    int fd = test_udp_socket();
    static uint8_t d[2000];
    const char *text = "A`\x7f";         /* the pattern of 3 bytes, seed 'A' */
    send_raw(fd, d, short_msg(d, 1, "T_MIX_S", text));
    send_raw(fd, d, pattern_fragment(d, 2, 3000, 0, 0, 2, "T_MIX_B", 1500));    /* after a short */
    send_raw(fd, d, short_msg(d, 3, "T_MIX_S", text));                         /* after a fragment */
    send_raw(fd, d, short_msg(d, 4, "T_MIX_S", text));
    send_raw(fd, d, pattern_fragment(d, 2, 3000, 1500, 1, 2, NULL, 1500));     /* completes it */
    send_raw(fd, d, short_msg(d, 5, "T_MIX_S", text));
    send_raw(fd, d, pattern_fragment(d, 6, 3000, 0, 0, 2, "T_NOBODY", 1500));  /* nobody's */
    send_raw(fd, d, pattern_fragment(d, 6, 3000, 1500, 1, 2, NULL, 1500));
    send_raw(fd, d, short_msg(d, 7, "T_MIX_S", text));
    struct pollfd p = {marie_bus_fd(rx), POLLIN, 0};
    assert_int_equal(poll(&p, 1, 2000), 1);
    assert_int_equal(marie_bus_handle(rx, 64), 6);
    const uint32_t order[] = {3, 3, 3, 3000, 3, 3};
    assert_int_equal(all.n, 6);
    assert_memory_equal(all.sizes, order, sizeof order);
    assert_int_equal(all.bad, 0);
    marie_bus_stats_t st;
    marie_bus_stats(rx, &st);
    assert_int_equal(st.messages, 7);
    assert_int_equal(st.malformed + st.incomplete, 0);
    close(fd);
    free(all.data);
    marie_bus_destroy(rx);
}

typedef struct {
    lcm_t *lcm;
    marie_bus_sub_t *self;
    got_t later;
    int calls;
} reentry_t;

static void on_once(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    reentry_t *r = user;
    r->calls++;
    marie_bus_unsubscribe(r->lcm, r->self);
    assert_non_null(marie_bus_subscribe(r->lcm, "T_ONCE", on_msg, &r->later));
}

/* A handler may unsubscribe itself and subscribe anew. */
static void test_subscribe_from_handler(void **state)
{
    lcm_t *pub = lcm_create(URL), *rx = marie_bus_create(URL);
    reentry_t r = {rx};
    r.self = marie_bus_subscribe(rx, "T_ONCE", on_once, &r);
    for (int i = 0; i < 3; i++) {
        publish_pattern(pub, "T_ONCE", 16, 0);
        pump(rx, &r.later, i, 1000);
    }
    assert_int_equal(r.calls, 1);
    assert_int_equal(r.later.n, 2);
    free(r.later.data);
    marie_bus_destroy(rx);
    lcm_destroy(pub);
}

typedef struct {
    lcm_t *lcm;
    got_t inner;
    int intact;
} nested_t;

/* While delivering a message, read the bus again (a client waiting for a reply does). */
static void on_outer(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    nested_t *n = user;
    uint8_t *copy = malloc(rb->data_size);
    memcpy(copy, rb->data, rb->data_size);
    pump(n->lcm, &n->inner, 1, 2000);
    n->intact = memcmp(copy, rb->data, rb->data_size) == 0;
    free(copy);
}

static void test_nested_read(void **state)
{
    lcm_t *pub = lcm_create(URL), *rx = marie_bus_create(URL);
    nested_t n = {rx};
    marie_bus_subscribe(rx, "T_OUTER", on_outer, &n);
    marie_bus_subscribe(rx, "T_INNER", on_msg, &n.inner);
    publish_pattern(pub, "T_OUTER", 1000, 1);
    publish_pattern(pub, "T_INNER", 2000, 2);
    pump(rx, &n.inner, 1, 2000);
    assert_int_equal(n.inner.n, 1);
    assert_true(n.intact);
    free(n.inner.data);
    marie_bus_destroy(rx);
    lcm_destroy(pub);
}

/* A receive buffer too small for a burst: the datagrams the kernel dropped are counted (on a
 * bus whose subscriptions let every channel through: the kernel counts its filter's refusals
 * with the losses). */
static void test_drops_counted(void **state)
{
    lcm_t *pub = lcm_create(URL), *rx = marie_bus_create(URL "&recv_buf_size=8192");
    got_t g = {0};
    marie_bus_subscribe(rx, ".*", on_msg, &g);
    for (int i = 0; i < 200; i++)
        publish_pattern(pub, "T_FLOOD", 4000, 0);
    pump(rx, NULL, 0, 300);
    /* The kernel tells the count with the next datagram it queues. */
    publish_pattern(pub, "T_FLOOD", 4000, 0);
    pump(rx, NULL, 0, 300);
    marie_bus_stats_t st;
    marie_bus_stats(rx, &st);
    assert_true(st.dropped > 0);
    assert_int_equal(g.n + st.dropped, 201);
    free(g.data);
    marie_bus_destroy(rx);
    lcm_destroy(pub);
}

/* MARIE_LCM_RECEIVE=liblcm leaves the bus to liblcm; the loop reads it the same way. */
static void test_liblcm_fallback(void **state)
{
    setenv("MARIE_LCM_RECEIVE", "liblcm", 1);
    lcm_t *pub = lcm_create(URL), *rx = marie_bus_create(URL);
    unsetenv("MARIE_LCM_RECEIVE");
    assert_false(marie_bus_native(rx));
    got_t g = {0};
    marie_bus_sub_t *s = marie_bus_subscribe(rx, "T_LIB", on_msg, &g);
    assert_non_null(s);
    marie_loop_t *loop = marie_loop_create();
    assert_int_equal(marie_loop_add_bus(loop, rx, 1), 0);
    publish_pattern(pub, "T_LIB", 200000, 5);
    for (int64_t end = marie_mono_us() + 2000000; g.n < 1 && marie_mono_us() < end;)
        marie_loop_run_once(loop, 10);
    assert_int_equal(g.n, 1);
    assert_int_equal(g.bad, 0);
    marie_bus_unsubscribe(rx, s);
    marie_loop_destroy(loop);
    free(g.data);
    marie_bus_destroy(rx);
    lcm_destroy(pub);
}

/* This program links liblcm and may call it on any handle: marie's buses in it are liblcm's
 * handles (a lcm_get_fileno() of liblcm's own on marie's own address would read garbage), and
 * liblcm is found in place, not opened a second time. */
static void test_handle_of_a_program_linking_liblcm(void **state)
{
    assert_true(marie_liblcm_in_process());
    lcm_t *rx = marie_bus_create(URL);
    assert_non_null(rx);
    assert_true(marie_bus_handle_is_liblcm(rx));
    assert_true(lcm_get_fileno(rx) >= 0);
    marie_bus_destroy(rx);
}

/* Other providers stay liblcm's. */
static void test_other_urls(void **state)
{
    lcm_t *m = marie_bus_create("memq://");
    assert_non_null(m);
    assert_false(marie_bus_native(m));
    marie_bus_destroy(m);
    lcm_t *t = marie_bus_create(URL "&transmit_only=true");
    assert_non_null(t);
    assert_false(marie_bus_native(t));
    marie_bus_destroy(t);
}

/* ---- marie_bus_publish ---- */

/* A socket that sees every datagram on the group, as any LCM reader's does: with each its
 * sender's port and the TTL it came with. */
static int sniffer(void)
{
    int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    int one = 1, big = 4 << 20;
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons(7667)};
    struct ip_mreq m = {.imr_interface.s_addr = htonl(INADDR_ANY)};
    inet_pton(AF_INET, "239.255.76.67", &m.imr_multiaddr);
    assert_true(fd >= 0);
    assert_int_equal(setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one), 0);
    assert_int_equal(bind(fd, (struct sockaddr *)&a, sizeof a), 0);
    assert_int_equal(setsockopt(fd, IPPROTO_IP, IP_ADD_MEMBERSHIP, &m, sizeof m), 0);
    assert_int_equal(setsockopt(fd, IPPROTO_IP, IP_RECVTTL, &one, sizeof one), 0);
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &big, sizeof big);
    return fd;
}

typedef struct {
    uint8_t *d;
    size_t len;
    uint16_t port;      /* the sender's */
    int ttl;
} dgram_t;

/* The next datagram (waiting up to 2 s), or len 0 and d NULL. Free d. */
static dgram_t sniff(int fd)
{
    dgram_t g = {0};
    struct pollfd p = {fd, POLLIN, 0};
    if (poll(&p, 1, 2000) <= 0)
        return g;
    g.d = malloc(65536);
    struct sockaddr_in from;
    union {
        char space[CMSG_SPACE(sizeof(int))];
        struct cmsghdr align;
    } ctl;
    struct iovec iov = {g.d, 65536};
    struct msghdr m = {.msg_name = &from, .msg_namelen = sizeof from, .msg_iov = &iov, .msg_iovlen = 1,
                       .msg_control = ctl.space, .msg_controllen = sizeof ctl.space};
    ssize_t n = recvmsg(fd, &m, 0);
    assert_true(n >= 0);
    g.len = (size_t)n;
    g.port = ntohs(from.sin_port);
    g.ttl = -1;
    for (struct cmsghdr *c = CMSG_FIRSTHDR(&m); c; c = CMSG_NXTHDR(&m, c))
        if (c->cmsg_level == IPPROTO_IP && c->cmsg_type == IP_TTL)
            memcpy(&g.ttl, CMSG_DATA(c), sizeof g.ttl);
    return g;
}

static void marie_publish_pattern(lcm_t *pub, const char *channel, size_t n, unsigned seed)
{
    uint8_t *p = malloc(n ? n : 1);
    pattern(p, n, seed);
    assert_int_equal(marie_bus_publish(pub, channel, p, (unsigned)n), 0);
    free(p);
}

/* Runs liblcm's handling until `until` messages came to g or 3 s passed. */
static void lib_pump(lcm_t *lib, got_t *g, int until)
{
    for (int64_t end = marie_mono_us() + 3000000; g->n < until && marie_mono_us() < end;)
        lcm_handle_timeout(lib, 50);
}

/* channel "T_TO_LIB": 9 bytes with its NUL, so 65490 bytes is the largest single datagram. */
static const uint32_t to_lib_sizes[] = {0, 1, 65489, 65490, 65491, 65492, 66560, 921600, 64, 921601};
#define NSIZES (sizeof to_lib_sizes / sizeof to_lib_sizes[0])

/* marie sends, a plain liblcm reader (its receive thread, lcm_handle) gets every message whole
 * and in order: empty, one byte, at and around the single-datagram limit, 65 KB and 900 KB. And
 * a marie reader on the sending bus itself gets them too (multicast loopback). */
static void test_to_liblcm(void **state)
{
    lcm_t *tx = marie_bus_create(URL), *lib = lcm_create(URL "&recv_buf_size=4194304");
    assert_non_null(tx);
    assert_non_null(lib);
    assert_true(marie_bus_sends(tx));
    got_t g = {0}, self = {0};
    assert_non_null(lcm_subscribe(lib, "T_TO_LIB", on_msg, &g));
    assert_non_null(marie_bus_subscribe(tx, "T_TO_LIB", on_msg, &self));
    for (size_t i = 0; i < NSIZES; i++) {
        marie_publish_pattern(tx, "T_TO_LIB", to_lib_sizes[i], (unsigned)i);
        pump(tx, &self, (int)i + 1, 2000);     /* the process's own reader drains as it goes */
    }
    lib_pump(lib, &g, (int)NSIZES);
    assert_int_equal(g.n, NSIZES);
    assert_int_equal(self.n, NSIZES);
    assert_memory_equal(g.sizes, to_lib_sizes, sizeof to_lib_sizes);
    assert_memory_equal(self.sizes, to_lib_sizes, sizeof to_lib_sizes);
    assert_int_equal(g.bad + self.bad, 0);
    assert_string_equal(g.channel, "T_TO_LIB");
    marie_bus_stats_t st;
    marie_bus_stats(tx, &st);
    assert_int_equal(st.malformed + st.incomplete + st.dropped, 0);
    free(g.data);
    free(self.data);
    lcm_destroy(lib);
    marie_bus_destroy(tx);
}

/* The bytes on the wire are liblcm's: a fresh liblcm instance and a fresh marie bus sending the
 * same messages send the same datagrams (sequence numbers included: both count from 0), one
 * LC02 datagram up to the limit, LC03 fragments past it. */
static void test_same_datagrams_as_liblcm(void **state)
{
    int fd = sniffer();
    lcm_t *lib = lcm_create(URL), *tx = marie_bus_create(URL);
    const uint32_t sizes[] = {0, 65490, 65491, 66560, 200000};
    const size_t want_frags[] = {1, 1, 2, 2, 4};
    for (int who = 0; who < 2; who++)
        for (size_t i = 0; i < 5; i++) {
            uint8_t *p = malloc(sizes[i] ? sizes[i] : 1);
            pattern(p, sizes[i], (unsigned)i);
            if (who == 0)
                assert_int_equal(lcm_publish(lib, "T_TO_LIB", p, sizes[i]), 0);
            else
                assert_int_equal(marie_bus_publish(tx, "T_TO_LIB", p, sizes[i]), 0);
            free(p);
        }
    size_t total = 0;
    for (size_t i = 0; i < 5; i++)
        total += want_frags[i];
    dgram_t *seen = calloc(2 * total, sizeof *seen);
    for (size_t i = 0; i < 2 * total; i++) {
        seen[i] = sniff(fd);
        assert_non_null(seen[i].d);
    }
    size_t k = 0;
    for (size_t i = 0; i < 5; i++)
        for (size_t f = 0; f < want_frags[i]; f++, k++) {
            const dgram_t *a = &seen[k], *b = &seen[total + k];
            assert_int_equal(a->len, b->len);
            assert_memory_equal(a->d, b->d, a->len);
            assert_memory_equal(b->d, want_frags[i] == 1 ? "LC02" : "LC03", 4);
            assert_true(b->port != a->port);        /* from marie's own socket */
        }
    for (size_t i = 0; i < 2 * total; i++)
        free(seen[i].d);
    free(seen);
    close(fd);
    marie_bus_destroy(tx);
    lcm_destroy(lib);
}

/* The URL's ttl is the datagrams' TTL (0 by default: nothing leaves the host). */
static void test_ttl(void **state)
{
    const char *urls[] = {"udpm://239.255.76.67:7667", URL, "udpm://239.255.76.67:7667?ttl=3"};
    const int ttls[] = {0, 0, 3};
    int fd = sniffer();
    for (int i = 0; i < 3; i++) {
        lcm_t *tx = marie_bus_create(urls[i]);
        assert_true(marie_bus_sends(tx));
        marie_publish_pattern(tx, "T_TTL", 10, 0);
        marie_publish_pattern(tx, "T_TTL", 100000, 0);
        for (int k = 0; k < 3; k++) {
            dgram_t g = sniff(fd);
            assert_non_null(g.d);
            assert_int_equal(g.ttl, ttls[i]);
            free(g.d);
        }
        marie_bus_destroy(tx);
    }
    close(fd);
}

typedef struct {
    lcm_t *lcm;
    unsigned seed;
} sender_t;

static void *send_many(void *arg)
{
    sender_t *s = arg;
    for (int i = 0; i < 20; i++)
        marie_publish_pattern(s->lcm, "T_THREADS", 150000 + s->seed, s->seed);
    return NULL;
}

/* Two threads sending large messages on one bus at once: every message arrives whole (a
 * message's fragments are never interleaved with another's). */
static void test_threads_publish(void **state)
{
    lcm_t *tx = marie_bus_create(URL), *rx = marie_bus_create(URL "&recv_buf_size=8388608");
    got_t g = {0};
    marie_bus_subscribe(rx, "T_THREADS", on_msg, &g);
    sender_t a = {tx, 1}, b = {tx, 2};
    pthread_t ta, tb;
    pthread_create(&ta, NULL, send_many, &a);
    pthread_create(&tb, NULL, send_many, &b);
    pump(rx, &g, 40, 5000);
    pthread_join(ta, NULL);
    pthread_join(tb, NULL);
    pump(rx, &g, 40, 1000);
    assert_int_equal(g.n, 40);
    assert_int_equal(g.bad, 0);
    marie_bus_stats_t st;
    marie_bus_stats(rx, &st);
    assert_int_equal(st.incomplete + st.malformed, 0);
    free(g.data);
    marie_bus_destroy(rx);
    marie_bus_destroy(tx);
}

/* Where marie does not send, marie_bus_publish() is lcm_publish(): MARIE_LCM_SEND=liblcm,
 * MARIE_LCM_RECEIVE=liblcm, a bus made by lcm_create(), another provider. */
/* A batch: runs of short messages go in one system call, a large one in its fragments between
 * them, and a plain liblcm reader gets them all whole and in order; a bus liblcm sends on sends
 * the same batch one by one. */
static void test_publish_batch(void **state)
{
    static const uint32_t sizes[] = {0, 64, 330, 65490, 921600, 1, 2, 8192};
    enum { N = sizeof sizes / sizeof sizes[0] };
    lcm_t *lib = lcm_create(URL "&recv_buf_size=4194304");
    assert_non_null(lib);
    for (int pass = 0; pass < 2; pass++) {
        lcm_t *tx = pass == 0 ? marie_bus_create(URL) : lcm_create(URL);
        assert_non_null(tx);
        assert_int_equal(marie_bus_sends(tx), pass == 0);
        got_t g = {0};
        lcm_subscription_t *sub = lcm_subscribe(lib, "T_BATCH", on_msg, &g);
        uint8_t *bufs[N];
        marie_bus_msg_t m[N];
        int rc[N];
        for (int i = 0; i < N; i++) {
            bufs[i] = malloc(sizes[i] ? sizes[i] : 1);
            pattern(bufs[i], sizes[i], (unsigned)i);
            m[i] = (marie_bus_msg_t){"T_BATCH", bufs[i], sizes[i]};
            rc[i] = 7;
        }
        assert_int_equal(marie_bus_publish_batch(tx, m, N, rc), N);
        for (int i = 0; i < N; i++)
            assert_int_equal(rc[i], 0);
        lib_pump(lib, &g, N);
        assert_int_equal(g.n, N);
        assert_memory_equal(g.sizes, sizes, sizeof sizes);
        assert_int_equal(g.bad, 0);
        for (int i = 0; i < N; i++)
            free(bufs[i]);
        free(g.data);
        lcm_unsubscribe(lib, sub);
        if (pass == 0)
            marie_bus_destroy(tx);
        else
            lcm_destroy(tx);
    }
    lcm_destroy(lib);
}

static void test_publish_fallback(void **state)
{
    lcm_t *lib = lcm_create(URL);
    got_t g = {0};
    assert_non_null(lcm_subscribe(lib, "T_FALLBACK", on_msg, &g));
    int fd = sniffer();     /* after liblcm's self-test message (sent as it subscribes) */
    const char *vars[] = {"MARIE_LCM_SEND", "MARIE_LCM_RECEIVE", NULL};
    for (int i = 0; i < 3; i++) {
        if (vars[i])
            setenv(vars[i], "liblcm", 1);
        lcm_t *tx = vars[i] ? marie_bus_create(URL) : lcm_create(URL);
        if (vars[i])
            unsetenv(vars[i]);
        assert_non_null(tx);
        assert_false(marie_bus_sends(tx));
        assert_int_equal(marie_bus_native(tx), i == 0);
        /* liblcm's own count of messages sent becomes 1 ... */
        assert_int_equal(lcm_publish(tx, "T_FALLBACK_FIRST", "", 0), 0);
        dgram_t d = sniff(fd);
        assert_non_null(d.d);
        free(d.d);
        marie_publish_pattern(tx, "T_FALLBACK", 100000, (unsigned)i);
        lib_pump(lib, &g, i + 1);
        assert_int_equal(g.n, i + 1);
        assert_int_equal(g.size, 100000);
        /* ... so liblcm sent this one: sequence number 1 (marie's sender would count from 0) */
        d = sniff(fd);
        assert_non_null(d.d);
        assert_memory_equal(d.d, "LC03\0\0\0\1", 8);
        free(d.d);
        while ((d = sniff(fd)).d && d.len == 65507)
            free(d.d);          /* the other fragment */
        free(d.d);
        if (vars[i])
            marie_bus_destroy(tx);
        else
            lcm_destroy(tx);
    }
    assert_int_equal(g.bad, 0);
    lcm_t *m = marie_bus_create("memq://");
    got_t mg = {0};
    assert_non_null(marie_bus_subscribe(m, "T_MEMQ", on_msg, &mg));
    assert_int_equal(marie_bus_publish(m, "T_MEMQ", "abc", 3), 0);
    assert_true(lcm_handle_timeout(m, 1000) > 0);
    assert_int_equal(mg.n, 1);
    marie_bus_destroy(m);
    char longname[80];
    memset(longname, 'C', 64);
    longname[64] = '\0';
    lcm_t *tx = marie_bus_create(URL);
    assert_int_equal(marie_bus_publish(tx, longname, "x", 1), -1);
    assert_int_equal(errno, EINVAL);
    marie_bus_destroy(tx);
    free(g.data);
    free(mg.data);
    lcm_destroy(lib);
    close(fd);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        /* first: before any test has opened liblcm through marie */
        cmocka_unit_test(test_handle_of_a_program_linking_liblcm),
        cmocka_unit_test(test_from_liblcm),
        cmocka_unit_test(test_kernel_filter),
        cmocka_unit_test(test_beside_liblcm),
        cmocka_unit_test(test_malformed),
        cmocka_unit_test(test_fragments_among_shorts),
        cmocka_unit_test(test_subscribe_from_handler),
        cmocka_unit_test(test_nested_read),
        cmocka_unit_test(test_drops_counted),
        cmocka_unit_test(test_liblcm_fallback),
        cmocka_unit_test(test_other_urls),
        cmocka_unit_test(test_to_liblcm),
        cmocka_unit_test(test_same_datagrams_as_liblcm),
        cmocka_unit_test(test_ttl),
        cmocka_unit_test(test_threads_publish),
        cmocka_unit_test(test_publish_batch),
        cmocka_unit_test(test_publish_fallback),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
