/* marie-candump: prints every frame on a CAN bus in candump's log format, for the emulated
 * bus (which can-utils cannot reach) as well as SocketCAN.
 *   marie-candump URL [--count N]      e.g. marie-candump emu:/tmp/marie-can.sock */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>
#include <unistd.h>

#include "core/cli.h"
#include "core/loop.h"
#include "hw/can/can.h"
#include "core/version.h"

#define PROG "marie-candump URL"

typedef struct {
    can_bus_t *bus;
    const char *name;
    long count;                 /* frames still to print; -1: no limit */
    int rc;
} dump_t;

static void on_quit(marie_loop_t *loop, int signo, void *user)
{
    marie_loop_quit(loop);
}

static void on_readable(marie_loop_t *loop, int fd, short revents, void *user)
{
    dump_t *d = user;
    struct can_frame f;
    int r = 0;
    while (d->count != 0 && (r = can_bus_read(d->bus, &f)) == 1) {
        struct timeval tv;
        gettimeofday(&tv, NULL);
        char buf[64];
        printf("(%ld.%06ld) %s %s\n", (long)tv.tv_sec, (long)tv.tv_usec, d->name, can_frame_str(&f, buf, sizeof buf));
        if (d->count > 0)
            d->count--;
    }
    int err = errno;
    fflush(stdout);
    if (r < 0) {
        fprintf(stderr, "marie-candump: %s\n", strerror(err));
        d->rc = 1;
    }
    if (r < 0 || d->count == 0)
        marie_loop_quit(loop);
}

int main(int argc, char **argv)
{
    marie_version_exit("marie-candump", argc, argv);
    int64_t count = -1;
    const marie_cli_opt_t opts[] = {
        { "count", MARIE_CLI_INT, &count, 1, 1e15, "N    stop after N frames (default: never)" },
        { NULL },
    };
    int rc = marie_cli_parse(PROG, opts, argc, argv);
    if (rc >= 0)
        return rc;
    if (optind != argc - 1) {
        marie_cli_usage(PROG, opts, stderr);
        return 2;
    }
    const char *url = argv[optind];
    dump_t d = { .count = (long)count };
    d.bus = can_bus_open(url);
    if (!d.bus) {
        fprintf(stderr, "marie-candump: %s: %s\n", url, strerror(errno));
        return 1;
    }
    can_bus_set_err_mask(d.bus, CAN_ERR_MASK);
    d.name = strncmp(url, "emu:", 4) == 0 ? "emu" : strchr(url, ':') + 1;
    marie_loop_t *loop = marie_loop_create();
    int r = loop ? marie_loop_catch_signals(loop, on_quit, NULL) : -1;
    if (r == 0)
        r = marie_loop_add_fd(loop, can_bus_fd(d.bus), POLLIN, on_readable, &d);
    if (r < 0) {
        fprintf(stderr, "marie-candump: cannot set up the loop: %s\n", strerror(errno));
        d.rc = 1;
    } else if (d.count != 0 && marie_loop_run(loop) < 0) {
        d.rc = 1;
    }
    marie_loop_destroy(loop);
    can_bus_close(d.bus);
    return d.rc;
}
