/* am_settings: a system file's `manager:` and `balance:` sections, checked (libmarie_managers):
 * marie-am applies them, marie up checks them before it sends the file. */
#ifndef MARIE_MANAGERS_AM_SETTINGS_H
#define MARIE_MANAGERS_AM_SETTINGS_H

#include <stdint.h>

#include "core/config.h"
#include "managers/balance.h"

/* Manager settings of a system file (its `manager:` section). */
typedef struct {
    double status_hz;           /* status messages per second (default 2) */
    double log_rate;            /* captured lines per second per component (default 200; burst 2x) */
    int64_t log_max_bytes;      /* rotate a component's log past this size (default 1 MiB) */
    int log_keep;               /* rotated files kept (default 3) */
    balance_cfg_t balance;      /* the `balance:` section */
} marie_am_settings_t;

/* What the managers check beyond marie_system_load (which refuses cycles): the `manager:`
 * section. Fills settings (defaults for absent keys). 0 or -1
 * with file:line:col messages in errs. */
int marie_am_check_system(const marie_system_t *sys, marie_am_settings_t *settings, marie_errors_t *errs);

#endif
