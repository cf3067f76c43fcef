/* marie-candump: prints every frame on a CAN bus in candump's log format, for the emulated
 * bus (which can-utils cannot reach) as well as SocketCAN.
 *   marie-candump URL [-n COUNT]       e.g. marie-candump emu:/tmp/marie-can.sock */
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>

#include "hw/can/can.h"

static volatile sig_atomic_t quit;
static void on_signal(int s) { quit = 1; }

int main(int argc, char **argv)
{
    if (argc < 2 || argv[1][0] == '-') {
        fprintf(stderr, "usage: marie-candump URL [-n COUNT]   (URL: can:IFNAME or emu:PATH)\n");
        return 2;
    }
    long count = argc >= 4 && strcmp(argv[2], "-n") == 0 ? atol(argv[3]) : -1;
    can_bus_t *bus = can_bus_open(argv[1]);
    if (!bus) {
        fprintf(stderr, "marie-candump: %s: %s\n", argv[1], strerror(errno));
        return 1;
    }
    can_bus_set_err_mask(bus, CAN_ERR_MASK);
    const char *name = strchr(argv[1], ':') + 1;
    if (strncmp(argv[1], "emu:", 4) == 0)
        name = "emu";
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    int rc = 0;
    while (!quit && count != 0) {
        struct pollfd p = { .fd = can_bus_fd(bus), .events = POLLIN };
        if (poll(&p, 1, 500) < 0 && errno != EINTR)
            break;
        struct can_frame f;
        int r = 0;
        while (count != 0 && (r = can_bus_read(bus, &f)) == 1) {
            struct timeval tv;
            gettimeofday(&tv, NULL);
            char buf[64];
            printf("(%ld.%06ld) %s %s\n", (long)tv.tv_sec, (long)tv.tv_usec, name, can_frame_str(&f, buf, sizeof buf));
            if (count > 0)
                count--;
        }
        fflush(stdout);
        if (r < 0) {
            fprintf(stderr, "marie-candump: %s\n", strerror(-r));
            rc = 1;
            break;
        }
    }
    can_bus_close(bus);
    return rc;
}
