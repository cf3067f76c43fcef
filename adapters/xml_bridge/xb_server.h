/* xb_server: the XML bridge's TCP server: clients, documents, LCM subscriptions and the
 * per-channel latest values, all driven from one marie loop. */
#ifndef XB_SERVER_H
#define XB_SERVER_H

#include <stddef.h>
#include <stdint.h>

#include <lcm/lcm.h>

#include "core/loop.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    const char *bind;           /* address to listen on; default "127.0.0.1" */
    int port;                   /* 0: any free port (see xb_server_port) */
    size_t max_doc_bytes;       /* per incoming document */
    int max_depth;              /* element nesting per incoming document */
    int queue_docs;             /* per-client outgoing documents before the oldest is dropped */
    size_t queue_bytes;         /* per-client outgoing bytes before the oldest is dropped */
    int max_clients;            /* more are told "busy" and closed */
    int stall_ms;               /* a document left unfinished this long closes the client */
    size_t max_message;         /* largest LCM payload published or delivered */
    int handle_lcm;             /* nonzero: the server watches the LCM fd itself */
    int sndbuf;                 /* per-client SO_SNDBUF in bytes; 0: the kernel's autotuning */
    size_t max_memory;          /* bytes held for incoming documents of all clients; over it,
                                 * the largest holders are closed with "no-memory" */
    int idle_s;                 /* a client without subscription that sent no complete document
                                 * this long is closed ("idle"); 0: never */
    int evict_idle_ms;          /* when full, the client idle longest, if idle this long, makes
                                 * room for a new one ("idle"); 0: never */
    int max_per_address;        /* clients from one address at once; 0: no cap */
} xb_server_cfg_t;

void xb_server_cfg_defaults(xb_server_cfg_t *cfg);

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
    uint64_t closed_idle;       /* clients closed after idle_s without a request */
    uint64_t evicted;           /* idle clients closed to make room for a new one */
} xb_server_stats_t;

typedef struct xb_server xb_server_t;

/* NULL with errno set on failure (e.g. the address is in use). */
xb_server_t *xb_server_create(const xb_server_cfg_t *cfg, lcm_t *lcm, marie_loop_t *loop,
                              const xb_server_hooks_t *hooks);
void xb_server_destroy(xb_server_t *s);         /* closes every client; NULL is a no-op */
int xb_server_port(const xb_server_t *s);
void xb_server_stats(const xb_server_t *s, xb_server_stats_t *st);

#ifdef __cplusplus
}
#endif
#endif
