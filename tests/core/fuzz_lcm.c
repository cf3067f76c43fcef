/* fuzz_lcm: datagrams on the bus are bytes from anyone on the network. The input is a series of
 * datagrams (each a 2-byte big-endian length and its bytes, at most 64 of them) sent to the LCM
 * group from one socket, read by marie's receiver (core/bus/udpm*.c) with "F.*" subscribed: whatever
 * they are, nothing is read out of bounds, every delivery holds the bytes of one datagram's
 * worth or of a message put together from fragments, and a good message sent after them from
 * another socket is still delivered (abort otherwise). Needs its own network namespace. */
#include <poll.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/bus/bus.h"
#include "core/time.h"
#include "tests/udp.h"

#define URL "udpm://239.255.76.67:7667?ttl=0"

static int good;

static void on_any(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    volatile uint8_t sum = 0;
    for (uint32_t i = 0; i < rb->data_size; i++)
        sum ^= ((const uint8_t *)rb->data)[i];      /* every delivered byte must be readable */
    if (strlen(channel) > LCM_MAX_CHANNEL_NAME_LENGTH)
        abort();
    if (strcmp(channel, "FUZZ_GOOD") == 0 && rb->data_size == 4 && memcmp(rb->data, "good", 4) == 0)
        good++;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static lcm_t *rx;
    static int fuzz_fd = -1, good_fd = -1;
    if (!rx) {
        rx = marie_bus_create(URL);
        if (!rx || !marie_bus_native(rx) || !marie_bus_subscribe(rx, "F.*", on_any, NULL))
            abort();
        fuzz_fd = test_udp_socket();
        good_fd = test_udp_socket();
    }
    for (int k = 0; k < 64 && size >= 2; k++) {
        size_t n = (size_t)data[0] << 8 | data[1];
        data += 2;
        size -= 2;
        if (n > size)
            n = size;
        test_udp_send(fuzz_fd, data, n);
        data += n;
        size -= n;
    }
    static const uint8_t msg[] = {'L', 'C', '0', '2', 0, 0, 0, 1, 'F', 'U', 'Z', 'Z', '_', 'G', 'O', 'O', 'D', 0,
                                  'g', 'o', 'o', 'd'};
    int before = good;
    test_udp_send(good_fd, msg, sizeof msg);
    for (int64_t end = marie_mono_us() + 2000000; good == before && marie_mono_us() < end;) {
        struct pollfd p = {marie_bus_fd(rx), POLLIN, 0};
        if (poll(&p, 1, 10) > 0)
            marie_bus_handle(rx, 64);
    }
    if (good != before + 1)
        abort();
    return 0;
}
