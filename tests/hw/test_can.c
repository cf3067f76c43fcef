/* test_can: CAN frame I/O over socketpair and through the emulated bus; filters, error frames. */
#include <errno.h>
#include <poll.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>
#include <cmocka.h>

#include "hw/can/can.h"
#include "hw/can/canbus.h"
#include "tests/fails.h"

static struct can_frame frame(canid_t id, int len, uint8_t fill)
{
    struct can_frame f;
    memset(&f, 0, sizeof f);
    f.can_id = id;
    f.len = (uint8_t)len;
    memset(f.data, fill, (size_t)len);
    return f;
}

static void filter_semantics(void **state)
{
    struct can_filter f[2] = { { 0x181, 0x7FF }, { 0x700, 0x780 } };
    assert_true(can_filter_match(f, 2, 0x181));
    assert_false(can_filter_match(f, 2, 0x182));
    assert_true(can_filter_match(f, 2, 0x705));
    assert_true(can_filter_match(NULL, 0, 0x123));
    struct can_filter inv = { 0x080 | CAN_INV_FILTER, 0x7FF };
    assert_false(can_filter_match(&inv, 1, 0x080));
    assert_true(can_filter_match(&inv, 1, 0x081));
}

static void error_frames_decode_and_change_health(void **state)
{
    struct can_frame f = frame(CAN_ERR_FLAG | CAN_ERR_CRTL, CAN_ERR_DLC, 0);
    f.data[1] = CAN_ERR_CRTL_TX_PASSIVE;
    can_err_info_t info;
    assert_int_equal(can_err_decode(&f, &info), 0);
    assert_true(info.passive);
    assert_int_equal(can_health_next(CAN_BUS_ACTIVE, &info), CAN_BUS_PASSIVE);
    f = frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, CAN_ERR_DLC, 0);
    can_err_decode(&f, &info);
    assert_int_equal(can_health_next(CAN_BUS_PASSIVE, &info), CAN_BUS_BUS_OFF);
    f = frame(CAN_ERR_FLAG | CAN_ERR_RESTARTED, CAN_ERR_DLC, 0);
    can_err_decode(&f, &info);
    assert_int_equal(can_health_next(CAN_BUS_BUS_OFF, &info), CAN_BUS_ACTIVE);
    assert_int_equal(can_health_next(CAN_BUS_BUS_OFF, NULL), CAN_BUS_ACTIVE);
    f = frame(0x123, 2, 0);
    assert_fails(can_err_decode(&f, &info), EINVAL);
    char buf[32];
    f = frame(0x601, 2, 0xAB);
    assert_string_equal(can_frame_str(&f, buf, sizeof buf), "601#ABAB");
}

static void socketpair_roundtrip_counts_bad_packets(void **state)
{
    int sv[2];
    assert_int_equal(socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    can_bus_t *a = can_bus_from_fd(sv[0]);
    can_bus_t *b = can_bus_from_fd(sv[1]);
    assert_non_null(a);
    assert_non_null(b);
    struct can_frame in, out = frame(0x201, 6, 0x5A);
    assert_int_equal(can_bus_read(b, &in), 0);      /* nothing yet, non-blocking */
    assert_int_equal(can_bus_write(a, &out), 0);
    assert_int_equal(can_bus_read(b, &in), 1);
    assert_memory_equal(&in, &out, sizeof in);
    /* a packet that is not a frame, then one with DLC 9: both counted and skipped */
    uint8_t junk[5] = { 1, 2, 3, 4, 5 };
    assert_int_equal(send(sv[0], junk, sizeof junk, 0), 5);
    struct can_frame bad = frame(0x181, 8, 0);
    bad.len = 9;
    assert_int_equal(send(sv[0], &bad, sizeof bad, 0), (ssize_t)sizeof bad);
    assert_int_equal(can_bus_write(a, &out), 0);
    assert_int_equal(can_bus_read(b, &in), 1);
    assert_int_equal(can_bus_stats(b)->rx_bad, 2);
    /* software filters on the emulated backend */
    struct can_filter flt = { 0x181, 0x7FF };
    assert_int_equal(can_bus_set_filters(b, &flt, 1), 0);
    assert_int_equal(can_bus_write(a, &out), 0);
    struct can_frame t = frame(0x181, 2, 1);
    assert_int_equal(can_bus_write(a, &t), 0);
    assert_int_equal(can_bus_read(b, &in), 1);
    assert_int_equal(in.can_id, 0x181);
    assert_int_equal(can_bus_stats(b)->rx_filtered, 1);
    /* writing an oversize DLC is refused before it reaches the wire */
    assert_fails(can_bus_write(a, &bad), EINVAL);
    /* the peer goes away: reads say so */
    can_bus_close(a);
    assert_fails(can_bus_read(b, &in), EPIPE);
    can_bus_close(b);
}

/* Run the bus's loop until it has been idle for 20 ms. */
static void pump(marie_loop_t *loop)
{
    for (int i = 0; i < 20; i++)
        if (marie_loop_run_once(loop, 20) <= 0)
            break;
}

/* An emulated bus served from a loop of the test's own, at a path of its own. */
typedef struct {
    char path[64], url[80];
    marie_loop_t *loop;
    can_emubus_t *bus;
} emu_t;

static void emu_open(emu_t *e, const char *tag)
{
    snprintf(e->path, sizeof e->path, "/tmp/marie-test-canbus%s-%d.sock", tag, getpid());
    snprintf(e->url, sizeof e->url, "emu:%s", e->path);
    e->loop = marie_loop_create();
    e->bus = can_emubus_create(e->loop, e->path);
    assert_non_null(e->bus);
}

static void emu_close(emu_t *e)
{
    can_emubus_destroy(e->bus);
    marie_loop_destroy(e->loop);
}

static void emulated_bus_relays_to_others(void **state)
{
    emu_t e;
    emu_open(&e, "");
    can_bus_t *c[3];
    for (int i = 0; i < 3; i++) {
        c[i] = can_bus_open(e.url);
        assert_non_null(c[i]);
    }
    pump(e.loop);
    assert_int_equal(can_emubus_nclients(e.bus), 3);
    struct can_frame in, out = frame(0x080, 0, 0);
    assert_int_equal(can_bus_write(c[0], &out), 0);
    pump(e.loop);
    assert_int_equal(can_bus_read(c[1], &in), 1);
    assert_int_equal(can_bus_read(c[2], &in), 1);
    assert_int_equal(in.can_id, 0x080);
    assert_int_equal(can_bus_read(c[0], &in), 0);    /* no echo to the sender */
    /* error frames reach only clients that asked for them, and set bus-off */
    assert_int_equal(can_bus_set_err_mask(c[1], CAN_ERR_MASK), 0);
    struct can_frame off = frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, CAN_ERR_DLC, 0);
    can_emubus_inject(e.bus, &off);
    assert_int_equal(can_bus_read(c[1], &in), 1);
    assert_true(in.can_id & CAN_ERR_FLAG);
    assert_int_equal(can_bus_health(c[1]), CAN_BUS_BUS_OFF);
    assert_int_equal(can_bus_stats(c[1])->bus_off, 1);
    assert_int_equal(can_bus_read(c[2], &in), 0);
    assert_int_equal(can_bus_health(c[2]), CAN_BUS_ACTIVE);
    /* recovery: a data frame gets through again */
    assert_int_equal(can_bus_write(c[0], &out), 0);
    pump(e.loop);
    assert_int_equal(can_bus_read(c[1], &in), 1);
    assert_int_equal(can_bus_health(c[1]), CAN_BUS_ACTIVE);
    assert_int_equal(can_bus_restart(c[1]), 0);
    /* garbage to the daemon is counted there and not relayed */
    uint8_t junk[3] = { 0 };
    assert_int_equal(send(can_bus_fd(c[0]), junk, 3, 0), 3);
    pump(e.loop);
    assert_int_equal(can_emubus_stats(e.bus)->bad, 1);
    assert_int_equal(can_bus_read(c[2], &in), 1);    /* the earlier frame */
    assert_int_equal(can_bus_read(c[2], &in), 0);
    /* a client that leaves is dropped */
    can_bus_close(c[2]);
    pump(e.loop);
    assert_int_equal(can_emubus_nclients(e.bus), 2);
    can_bus_close(c[0]);
    can_bus_close(c[1]);
    emu_close(&e);
    assert_int_equal(access(e.path, F_OK), -1);
}

/* Raw packets waiting on a client's socket, read past its own filtering: what the server sent. */
static int raw_ids(can_bus_t *c, canid_t *ids, int max)
{
    int n = 0;
    struct can_frame f;
    while (n < max && recv(can_bus_fd(c), &f, sizeof f, MSG_DONTWAIT) == CAN_MTU)
        ids[n++] = f.can_id;
    return n;
}

/* The server sends each client only what the filters it told take, as the kernel would for a
 * SocketCAN socket: a gyro driver on the bus is not sent the drives' SYNC and PDOs. Error
 * frames go by the error mask; a client that told nothing gets everything; a malformed filter
 * packet is counted bad and changes nothing. */
static void emulated_bus_sends_each_client_what_its_filters_take(void **state)
{
    emu_t e;
    emu_open(&e, "-f");
    can_bus_t *tx = can_bus_open(e.url), *gyro = can_bus_open(e.url), *all = can_bus_open(e.url);
    assert_non_null(tx);
    assert_non_null(gyro);
    assert_non_null(all);
    struct can_filter f[2] = { { 0x1A0, CAN_SFF_MASK }, { 0x720, CAN_SFF_MASK } };
    assert_int_equal(can_bus_set_filters(gyro, f, 2), 0);
    assert_int_equal(can_bus_set_err_mask(gyro, CAN_ERR_BUSOFF), 0);
    pump(e.loop);
    const canid_t sent[] = { 0x080, 0x201, 0x1A0, 0x181, 0x720, 0x77F };
    for (size_t i = 0; i < sizeof sent / sizeof sent[0]; i++) {
        struct can_frame fr = frame(sent[i], 1, (uint8_t)i);
        assert_int_equal(can_bus_write(tx, &fr), 0);
    }
    pump(e.loop);
    struct can_frame crtl = frame(CAN_ERR_FLAG | CAN_ERR_CRTL, CAN_ERR_DLC, 0);
    struct can_frame off = frame(CAN_ERR_FLAG | CAN_ERR_BUSOFF, CAN_ERR_DLC, 0);
    can_emubus_inject(e.bus, &crtl);
    can_emubus_inject(e.bus, &off);
    pump(e.loop);
    canid_t ids[16];
    assert_int_equal(raw_ids(gyro, ids, 16), 3);
    assert_int_equal(ids[0], 0x1A0);
    assert_int_equal(ids[1], 0x720);
    assert_int_equal(ids[2], CAN_ERR_FLAG | CAN_ERR_BUSOFF);
    assert_int_equal(raw_ids(all, ids, 16), 8);
    assert_int_equal(can_emubus_stats(e.bus)->filtered, 5);
    /* n = 65 filters, or a length that does not match n: bad, the old filters stay */
    uint8_t junk[CAN_EMU_FILTER_HDR + 8] = "MFLT";
    uint32_t n = 65;
    memcpy(junk + 4, &n, 4);
    assert_int_equal(send(can_bus_fd(gyro), junk, CAN_EMU_FILTER_HDR, 0), CAN_EMU_FILTER_HDR);
    n = 2;
    memcpy(junk + 4, &n, 4);
    assert_int_equal(send(can_bus_fd(gyro), junk, sizeof junk, 0), (ssize_t)sizeof junk);
    pump(e.loop);
    assert_int_equal(can_emubus_stats(e.bus)->bad, 2);
    struct can_frame sync = frame(0x080, 0, 0);
    assert_int_equal(can_bus_write(tx, &sync), 0);
    pump(e.loop);
    assert_int_equal(raw_ids(gyro, ids, 16), 0);
    /* no filters again: everything */
    assert_int_equal(can_bus_set_filters(gyro, NULL, 0), 0);
    pump(e.loop);
    assert_int_equal(can_bus_write(tx, &sync), 0);
    pump(e.loop);
    assert_int_equal(raw_ids(gyro, ids, 16), 1);
    can_bus_close(tx);
    can_bus_close(gyro);
    can_bus_close(all);
    emu_close(&e);
}

/* A sender faster than the bus server (its socket takes what fits in its send buffer) loses
 * nothing and is never blocked: the rest is held and goes out, in order, once the server has run. */
static void emulated_bus_holds_frames_the_server_has_no_room_for(void **state)
{
    emu_t e;
    emu_open(&e, "-q");
    can_bus_t *tx = can_bus_open(e.url), *rx = can_bus_open(e.url);
    assert_non_null(tx);
    assert_non_null(rx);
    pump(e.loop);
    /* fill the server's socket behind the API's back: K frames */
    int k = 0;
    for (;; k++) {
        struct can_frame f = frame(0x100 + (canid_t)k, 1, (uint8_t)k);
        if (send(can_bus_fd(tx), &f, CAN_MTU, MSG_DONTWAIT) != CAN_MTU)
            break;
    }
    assert_true(errno == EAGAIN || errno == EWOULDBLOCK);
    enum { N = 40 };
    for (int i = 0; i < N; i++) {
        struct can_frame f = frame(0x100 + (canid_t)(k + i), 1, (uint8_t)(k + i));
        assert_int_equal(can_bus_write(tx, &f), 0);
    }
    assert_int_equal(can_bus_stats(tx)->tx, 0);
    assert_true(can_bus_events(tx) & POLLOUT);
    int got = 0;
    struct can_frame in;
    for (int round = 0; round < 200 && got < k + N; round++) {
        can_bus_flush(tx);
        marie_loop_run_once(e.loop, 10);
        while (can_bus_read(rx, &in) == 1) {
            assert_int_equal(in.can_id, 0x100 + (canid_t)got);
            assert_int_equal(in.data[0], (uint8_t)got);
            got++;
        }
    }
    assert_int_equal(got, k + N);
    assert_int_equal(can_bus_stats(tx)->tx, N);
    assert_int_equal(can_bus_stats(tx)->tx_errors, 0);
    assert_int_equal(can_bus_events(tx), POLLIN);
    can_bus_close(tx);
    can_bus_close(rx);
    emu_close(&e);
}

static void can_fd_frames_when_enabled(void **state)
{
    int sv[2];
    assert_int_equal(socketpair(AF_UNIX, SOCK_SEQPACKET, 0, sv), 0);
    can_bus_t *a = can_bus_from_fd(sv[0]), *b = can_bus_from_fd(sv[1]);
    struct canfd_frame fd = { .can_id = 0x123, .len = 64, .flags = CANFD_BRS }, in;
    for (int i = 0; i < 64; i++)
        fd.data[i] = (uint8_t)i;
    assert_fails(can_bus_write_fd(a, &fd), EPROTONOSUPPORT);
    assert_int_equal(can_bus_enable_fd(a, true), 0);
    assert_int_equal(can_bus_write_fd(a, &fd), 0);
    /* b has FD off: the frame is not delivered */
    struct can_frame cf;
    assert_int_equal(can_bus_read(b, &cf), 0);
    assert_int_equal(can_bus_stats(b)->rx_filtered, 1);
    assert_int_equal(can_bus_enable_fd(b, true), 0);
    assert_int_equal(can_bus_write_fd(a, &fd), 0);
    struct can_frame classic = { .can_id = 0x80, .len = 0 };
    assert_int_equal(can_bus_write(a, &classic), 0);
    bool is_fd;
    assert_int_equal(can_bus_read_fd(b, &in, &is_fd), 1);
    assert_true(is_fd);
    assert_int_equal(in.len, 64);
    assert_memory_equal(in.data, fd.data, 64);
    assert_int_equal(can_bus_read_fd(b, &in, &is_fd), 1);
    assert_false(is_fd);
    assert_int_equal(in.can_id, 0x80);
    can_bus_close(a);
    can_bus_close(b);
}

static void urls_are_checked(void **state)
{
    assert_null(can_bus_open("serial:/dev/ttyS0"));
    assert_int_equal(errno, EINVAL);
    assert_null(can_bus_open("emu:/nonexistent/dir/bus.sock"));
    /* This kernel may lack PF_CAN; either way a missing interface fails cleanly. */
    assert_null(can_bus_open("can:nosuchcan0"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(filter_semantics),
        cmocka_unit_test(error_frames_decode_and_change_health),
        cmocka_unit_test(socketpair_roundtrip_counts_bad_packets),
        cmocka_unit_test(emulated_bus_relays_to_others),
        cmocka_unit_test(emulated_bus_holds_frames_the_server_has_no_room_for),
        cmocka_unit_test(emulated_bus_sends_each_client_what_its_filters_take),
        cmocka_unit_test(can_fd_frames_when_enabled),
        cmocka_unit_test(urls_are_checked),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
