/* config_transport: the system file's `transports:`, which channels move to a provider of their own. */
#include "core/config.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const marie_transport_cfg_t *marie_system_transport(const marie_system_t *sys, const char *channel)
{
    for (size_t i = 0; sys && channel && i < sys->ntransports; i++)
        if (strcmp(sys->transports[i].channel, channel) == 0)
            return &sys->transports[i];
    return NULL;
}

/* transports: {CHANNEL: {kind: shm|local|lcm, max_size: BYTES, slots: N}, ...} */
int marie_transports_read(const marie_node_t *n, marie_system_t *sys, marie_errors_t *errs)
{
    if (!n)
        return 0;
    if (n->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, n, "transports: expected a mapping of channel: {kind: shm, max_size: BYTES}");
        return -1;
    }
    if (!(sys->transports = calloc(n->n ? n->n : 1, sizeof *sys->transports)))
        return -1;
    int rc = 0;
    for (size_t i = 0; i < n->n; i++) {
        static const char *const keys[] = {"kind", "max_size", "slots", NULL};
        const marie_node_t *t = n->items[i], *v;
        const char *kind = "lcm";
        int64_t max_size = 1 << 20, slots = 8;
        if (t->kind != MARIE_NODE_MAP) {
            marie_node_error(errs, t, "transport of '%s': expected a mapping such as {kind: shm}", t->key);
            rc = -1;
            continue;
        }
        if (marie_node_check_keys(t, keys, "transport", errs) < 0 ||
            ((v = marie_node_get(t, "kind")) && marie_node_str(v, &kind, errs) < 0) ||
            ((v = marie_node_get(t, "max_size")) && marie_node_int(v, &max_size, errs) < 0) ||
            ((v = marie_node_get(t, "slots")) && marie_node_int(v, &slots, errs) < 0)) {
            rc = -1;
            continue;
        }
        if (strcmp(kind, "shm") != 0 && strcmp(kind, "local") != 0 && strcmp(kind, "lcm") != 0) {
            marie_node_error(errs, marie_node_get(t, "kind"), "transport of '%s': kind is shm, local or lcm, not '%s'",
                             t->key, kind);
            rc = -1;
        } else if (max_size < 64 || max_size > (1LL << 30) || slots < 2 || slots > 1024) {
            marie_node_error(errs, t, "transport of '%s': max_size is 64 B to 1 GiB and slots 2 to 1024", t->key);
            rc = -1;
        } else {
            marie_transport_cfg_t *tr = &sys->transports[sys->ntransports++];
            *tr = (marie_transport_cfg_t){.channel = strdup(t->key), .shm = strcmp(kind, "lcm") != 0,
                                          .max_size = (size_t)max_size, .slots = (int)slots, .line = t->line, .col = t->col};
            snprintf(tr->kind, sizeof tr->kind, "%s", kind);
        }
    }
    return rc;
}
