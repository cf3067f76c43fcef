/* fuzz_local: a channel's registry on the same-host fast path is bytes other processes write
 * (every process of the robot's user may): whatever its entries hold (names without their end,
 * strangers' pids, counters), a publisher ringing doorbells and a reader following rings stay
 * within bounds and refuse what makes no sense. The input is the registry's entries, after a
 * valid header. */
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/bus/bus.h"
#include "core/bus/local.h"

static void on_message(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    volatile uint8_t sum = 0;
    for (uint32_t i = 0; i < rb->data_size; i++)
        sum ^= ((const uint8_t *)rb->data)[i];   /* every byte handed over must be mapped */
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static lcm_t *bus;
    static char path[320];
    if (!bus) {
        char host[64];
        snprintf(host, sizeof host, "fuzz-%d", (int)getpid());
        setenv("MARIE_SHM_HOST", host, 1);      /* a registry of its own */
        bus = marie_bus_create("memq://");
        marie_bus_transport_t t = {"FZ", "local", 4096, 2};
        if (!bus || marie_bus_set_transport(bus, &t) < 0 || !marie_bus_subscribe(bus, "FZ", on_message, NULL))
            abort();
        local_reg_path(path, sizeof path, "FZ");
    }
    local_registry_t reg;
    int fd = open(path, O_RDWR | O_CLOEXEC);
    if (fd < 0 || pread(fd, &reg, sizeof reg, 0) != (ssize_t)sizeof reg)
        abort();
    size_t body = sizeof reg - offsetof(local_registry_t, tickets);
    memset((char *)&reg + offsetof(local_registry_t, tickets), 0, body);
    memcpy((char *)&reg + offsetof(local_registry_t, tickets), data, size < body ? size : body);
    if (pwrite(fd, &reg, sizeof reg, 0) != (ssize_t)sizeof reg)
        abort();
    close(fd);
    uint8_t msg[64] = {0};
    marie_bus_publish(bus, "FZ", msg, size % (sizeof msg - 8) + 8); /* rings what the table names */
    marie_bus_waking(bus);                                          /* looks at whom it rang */
    marie_bus_sleep(bus, 1);
    marie_bus_pending(bus);
    marie_bus_handle_wake(bus, 16);                                 /* follows what it names */
    marie_bus_sleep(bus, 0);
    return 0;
}
