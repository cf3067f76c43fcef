/* marie-canbus: the emulated CAN bus daemon (this machine's kernel has no PF_CAN).
 *   marie-canbus PATH      clients connect with the URL emu:PATH
 * SIGUSR1 puts a bus-off error frame on the bus and SIGUSR2 a "restarted" one, to exercise
 * the drivers' recovery. */
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "core/cli.h"
#include "core/log.h"
#include "core/loop.h"
#include "hw/can/canbus.h"
#include "core/version.h"

#define PROG "marie-canbus PATH"

static void on_quit(marie_loop_t *loop, int signo, void *user)
{
    marie_loop_quit(loop);
}

/* SIGUSR1 / SIGUSR2, from the loop: the error frame goes out. */
static void on_usr(marie_loop_t *loop, int signo, void *user)
{
    struct can_frame f;
    memset(&f, 0, sizeof f);
    f.can_id = CAN_ERR_FLAG | (signo == SIGUSR1 ? CAN_ERR_BUSOFF : CAN_ERR_RESTARTED);
    f.len = CAN_ERR_DLC;
    can_emubus_inject(user, &f);
}

int main(int argc, char **argv)
{
    marie_version_exit("marie-canbus", argc, argv);
    static const marie_cli_opt_t opts[] = {{NULL}};
    int status = marie_cli_parse(PROG, opts, argc, argv);
    if (status >= 0)
        return status;
    if (optind != argc - 1) {
        marie_cli_usage(PROG, opts, stderr);
        return 2;
    }
    const char *path = argv[optind];
    marie_loop_t *loop = marie_loop_create();
    if (!loop || marie_loop_catch_signals(loop, on_quit, NULL) < 0) {
        marie_error("cannot set up the loop: %s", strerror(errno));
        return 1;
    }
    can_emubus_t *b = can_emubus_create(loop, path);
    if (!b) {
        marie_error("cannot listen on %s: %s", path, strerror(errno));
        return 1;
    }
    int rc = marie_loop_watch_signals(loop, (const int[]){ SIGUSR1, SIGUSR2 }, 2, on_usr, b);
    if (rc < 0)
        marie_error("cannot watch SIGUSR1/SIGUSR2: %s", strerror(errno));
    else
        marie_info("emulated CAN bus on %s", path);
    if (rc == 0)
        rc = marie_loop_run(loop);
    const can_emubus_stats_t *s = can_emubus_stats(b);
    marie_info("bus closed: %llu clients, %llu frames, %llu delivered, %llu filtered out, %llu overflow, %llu bad",
               (unsigned long long)s->clients, (unsigned long long)s->frames,
               (unsigned long long)s->delivered, (unsigned long long)s->filtered,
               (unsigned long long)s->overflow, (unsigned long long)s->bad);
    can_emubus_destroy(b);
    marie_loop_destroy(loop);
    return rc < 0 ? 1 : 0;
}
