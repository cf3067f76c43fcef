/* vm_socketcan: the CAN layer on real SocketCAN (run inside the VM on vcan0, see
 * tests/hw/vm_can_inner.sh): raw sockets, kernel filters, loopback to other sockets, error
 * mask, CAN FD, restart refused on a virtual interface. */
#include <errno.h>
#include <poll.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <string.h>
#include <cmocka.h>

#include "hw/can/can.h"
#include "tests/fails.h"

static int wait_read(can_bus_t *b, struct can_frame *f)
{
    struct pollfd p = { .fd = can_bus_fd(b), .events = POLLIN };
    if (poll(&p, 1, 1000) <= 0)
        return 0;
    return can_bus_read(b, f);
}

static void raw_sockets_loop_back_to_others(void **state)
{
    can_bus_t *a = can_bus_open("can:vcan0"), *b = can_bus_open("can:vcan0");
    assert_non_null(a);
    assert_non_null(b);
    assert_true(can_bus_is_socketcan(a));
    struct can_frame out = { .can_id = 0x181, .len = 6, .data = { 1, 2, 3, 4, 5, 6 } }, in;
    assert_int_equal(can_bus_write(a, &out), 0);
    assert_int_equal(wait_read(b, &in), 1);
    assert_int_equal(in.can_id, 0x181);
    assert_memory_equal(in.data, out.data, 6);
    assert_int_equal(can_bus_read(a, &in), 0);      /* not to the sender */
    can_bus_close(a);
    can_bus_close(b);
}

static void kernel_filters_apply(void **state)
{
    can_bus_t *a = can_bus_open("can:vcan0"), *b = can_bus_open("can:vcan0");
    struct can_filter flt = { 0x001, 0x07F };       /* node 1, any function code */
    assert_int_equal(can_bus_set_filters(b, &flt, 1), 0);
    struct can_frame f1 = { .can_id = 0x182, .len = 1 }, f2 = { .can_id = 0x701, .len = 1 }, in;
    can_bus_write(a, &f1);
    can_bus_write(a, &f2);
    assert_int_equal(wait_read(b, &in), 1);
    assert_int_equal(in.can_id, 0x701);
    assert_int_equal(can_bus_read(b, &in), 0);
    assert_int_equal(can_bus_stats(b)->rx_filtered, 0);   /* the kernel dropped it, not us */
    can_bus_close(a);
    can_bus_close(b);
}

static void fd_frames_and_restart(void **state)
{
    can_bus_t *a = can_bus_open("can:vcan0"), *b = can_bus_open("can:vcan0");
    assert_int_equal(can_bus_set_err_mask(b, CAN_ERR_MASK), 0);
    assert_int_equal(can_bus_enable_fd(a, true), 0);
    assert_int_equal(can_bus_enable_fd(b, true), 0);
    struct canfd_frame fd = { .can_id = 0x123, .len = 48 }, in;
    memset(fd.data, 0xA5, 48);
    int r = can_bus_write_fd(a, &fd);
    int err = errno;
    if (r == 0) {       /* vcan0 with mtu 72 (the inner script sets it) */
        bool is_fd;
        struct pollfd p = { .fd = can_bus_fd(b), .events = POLLIN };
        assert_true(poll(&p, 1, 1000) > 0);
        assert_int_equal(can_bus_read_fd(b, &in, &is_fd), 1);
        assert_true(is_fd);
        assert_int_equal(in.len, 48);
    } else {
        assert_int_equal(r, -1);
        assert_int_equal(err, EINVAL);
    }
    /* a virtual interface has no controller to restart */
    assert_true(can_bus_restart(a) < 0);
    can_bus_close(a);
    can_bus_close(b);
}

static void missing_interface_fails_cleanly(void **state)
{
    assert_null(can_bus_open("can:nosuchcan7"));
    assert_int_equal(errno, ENODEV);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(raw_sockets_loop_back_to_others),
        cmocka_unit_test(kernel_filters_apply),
        cmocka_unit_test(fd_frames_and_restart),
        cmocka_unit_test(missing_interface_fails_cleanly),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
