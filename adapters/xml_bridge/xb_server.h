/* xb_server: the XML bridge's TCP server: clients, documents, LCM subscriptions and the
 * per-channel latest values, all driven from one marie loop. */
#ifndef XB_SERVER_H
#define XB_SERVER_H

#include <stddef.h>
#include <stdint.h>

#include <lcm/lcm.h>

#include "core/loop.h"
#include "adapters/xml_bridge/xb_server_params.h"

#ifdef __cplusplus
extern "C" {
#endif

/* xb_server_cfg_t: the server's parameters, declared in xb_server.params.yaml (bind, port, the
 * limits per document, client and message, the memory budget), and handle_lcm, set by a program
 * that has no component's loop; xb_server_cfg_defaults() gives their defaults. */

void xb_server_cfg_defaults(xb_server_cfg_t *cfg);
/* -1 with the reason in why[0..len) (EINVAL) for values the server cannot work with: a port
 * outside 0..65535, max_depth, max_clients or stall_ms below 1, queue below 2, max_document below
 * 64 or above max_memory, queue_bytes or max_message below 1, a negative sndbuf. */
int xb_server_cfg_check(const xb_server_cfg_t *cfg, char *why, size_t len);

/* Where bad input and drops are reported (the component's counters); any may be NULL. */
typedef struct {
    void (*bad_input)(void *user, const char *counter, const char *reason);
    void (*drop)(void *user, int64_t n);
    void (*count)(void *user, const char *counter, int64_t delta);
    void *user;
} xb_server_hooks_t;

typedef struct {
    uint64_t clients;           /* connected now */
    uint64_t accepted, refused;
    uint64_t documents;         /* requests parsed */
    uint64_t errors;            /* error replies sent */
    uint64_t published;         /* LCM messages published for clients */
    uint64_t received;          /* LCM messages received on subscribed channels */
    uint64_t delivered;         /* message documents queued to clients */
    uint64_t dropped;           /* documents lost to full client queues */
    uint64_t closed_bad;        /* clients closed for bad streams or stalls */
    uint64_t subscriptions;     /* distinct (channel, type) subscriptions now */
    uint64_t doc_bytes;         /* bytes held now for incoming documents (all clients) */
    uint64_t closed_memory;     /* clients closed for the memory budget */
} xb_server_stats_t;

typedef struct xb_server xb_server_t;

/* NULL with errno set on failure (EINVAL: xb_server_cfg_check refuses cfg; the address is in
 * use). cfg NULL takes the defaults. */
xb_server_t *xb_server_create(const xb_server_cfg_t *cfg, lcm_t *lcm, marie_loop_t *loop,
                              const xb_server_hooks_t *hooks);
void xb_server_destroy(xb_server_t *s);         /* closes every client; NULL is a no-op */
int xb_server_port(const xb_server_t *s);
void xb_server_stats(const xb_server_t *s, xb_server_stats_t *st);

#ifdef __cplusplus
}
#endif
#endif
