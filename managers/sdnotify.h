/* sdnotify: systemd's service notification protocol (sd_notify(3)) without libsystemd: one
 * datagram of "KEY=VALUE" lines to the AF_UNIX socket named by $NOTIFY_SOCKET (a path, or
 * "@name" in the abstract namespace). Only marie-am speaks it; linking libsystemd for this put
 * libsystemd and its five compression and crypto libraries into every marie process. */
#ifndef MARIE_SDNOTIFY_H
#define MARIE_SDNOTIFY_H

#include <stdint.h>

/* Sends state. 1 when sent, 0 when $NOTIFY_SOCKET is unset (not under systemd), -1 with errno. */
int marie_sd_notify(const char *state);

/* The watchdog interval systemd asks for, in microseconds ($WATCHDOG_USEC, when $WATCHDOG_PID
 * is unset or names this process), or 0. */
uint64_t marie_sd_watchdog_usec(void);

#endif
