/* marie-canbus: the emulated CAN bus daemon (this machine's kernel has no PF_CAN).
 *   marie-canbus PATH      clients connect with the URL emu:PATH
 * SIGUSR1 puts a bus-off error frame on the bus and SIGUSR2 a "restarted" one, to exercise
 * the drivers' recovery. */
#include <errno.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>

#include "core/log.h"
#include "hw/can/canbus.h"

static volatile sig_atomic_t quit, inject_busoff, inject_restart;

static void on_signal(int s)
{
    if (s == SIGUSR1)
        inject_busoff = 1;
    else if (s == SIGUSR2)
        inject_restart = 1;
    else
        quit = 1;
}

int main(int argc, char **argv)
{
    if (argc != 2 || argv[1][0] == '-') {
        fprintf(stderr, "usage: marie-canbus PATH   (clients use emu:PATH)\n");
        return 2;
    }
    can_emubus_t *b = can_emubus_create(argv[1]);
    if (!b) {
        marie_error("cannot listen on %s: %s", argv[1], strerror(errno));
        return 1;
    }
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigaction(SIGTERM, &sa, NULL);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGUSR1, &sa, NULL);
    sigaction(SIGUSR2, &sa, NULL);
    marie_info("emulated CAN bus on %s", argv[1]);
    while (!quit) {
        struct pollfd p = { .fd = can_emubus_fd(b), .events = POLLIN };
        int r = poll(&p, 1, 1000);
        if (r < 0 && errno != EINTR) {
            marie_error("poll: %s", strerror(errno));
            break;
        }
        if (inject_busoff || inject_restart) {
            struct can_frame f;
            memset(&f, 0, sizeof f);
            f.can_id = CAN_ERR_FLAG | (inject_busoff ? CAN_ERR_BUSOFF : CAN_ERR_RESTARTED);
            f.len = CAN_ERR_DLC;
            can_emubus_inject(b, &f);
            inject_busoff = inject_restart = 0;
        }
        if (r > 0)
            can_emubus_process(b);
    }
    const can_emubus_stats_t *s = can_emubus_stats(b);
    marie_info("bus closed: %llu clients, %llu frames, %llu delivered, %llu overflow, %llu bad",
               (unsigned long long)s->clients, (unsigned long long)s->frames,
               (unsigned long long)s->delivered, (unsigned long long)s->overflow,
               (unsigned long long)s->bad);
    can_emubus_destroy(b);
    return 0;
}
