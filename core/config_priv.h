/* config_priv: the system file's checks that config.c runs once a file is read (config_check.c);
 * private to core/config*.c. */
#ifndef MARIE_CONFIG_PRIV_H
#define MARIE_CONFIG_PRIV_H

#include "core/config.h"

/* A duration `key` read as `value` seconds: within what the managers can count (a day at most;
 * heartbeat_timeout 0, or 0.15 s and more). -1 with "file:line:col: ..." at n. */
int marie_config_seconds_ok(const marie_node_t *n, const char *key, double value, marie_errors_t *errs);

/* Everything about a loaded file that reading it does not already refuse, so that a file that
 * passes never crash-loops its components: names (components, groups, hosts: printable words of
 * at most 63 bytes), hosts listed once and at least one, channels LCM can carry, bus URLs, args as
 * a list, every profile's `extends` chain (applied or not), dependency cycles. 0 or -1 with
 * "file:line:col: ..." in errs. */
int marie_config_check(const marie_system_t *sys, marie_errors_t *errs);

#endif
