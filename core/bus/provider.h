/* provider: what a way of moving bytes offers the bus (core/bus/bus.c): a static table of
 * functions private to its file, as LCM's providers are. Only core/bus uses it. */
#ifndef MARIE_BUS_PROVIDER_H
#define MARIE_BUS_PROVIDER_H

#include "core/bus/bus.h"

/* Who gets a subscription's messages: handler(rb, channel, user), then, for a subscription in
 * place, verdict(intact, user). A provider that holds the bytes until verdict returns (a ring
 * slot the writer skips meanwhile) calls held instead of handler, when it is not NULL. */
typedef struct {
    lcm_msg_handler_t handler;
    marie_bus_verdict_t verdict;    /* NULL: the handler gets bytes of its own (copied) */
    void *user;
    lcm_msg_handler_t held;
} marie_bus_recv_t;

typedef struct marie_bus_provider {
    const char *name;
    /* A bus's own provider: its state for the bus at url, or NULL with errno (EPROTONOSUPPORT:
     * not a URL it reads; the bus then asks the next). */
    void *(*open)(lcm_t *bus, const char *url);
    /* A channel's provider: its state for one channel a transport moved to it. *bus_st is the
     * provider's state for the whole bus (NULL until a channel makes it; close_bus lets it go
     * with the bus). */
    void *(*open_channel)(lcm_t *bus, const marie_bus_transport_t *t, void **bus_st);
    void (*close)(void *st);
    void *(*subscribe)(void *st, const char *channel, const marie_bus_recv_t *r);
    void (*unsubscribe)(void *st, void *sub);
    int (*publish)(void *st, const char *channel, const void *data, size_t len);
    /* Optional (NULL: the bus fills a buffer and publishes it, or has no loans). */
    int (*publish_with)(void *st, size_t len, marie_bus_fill_t fill, void *user);
    void *(*loan)(void *st);
    int (*commit)(void *st, size_t len);
    int (*prepare)(void *st);
    marie_bus_sub_stats_t (*sub_stats)(const void *sub);
    /* A bus's own provider only. */
    int (*publish_batch)(void *st, const marie_bus_msg_t *m, int n, int *rc);
    int (*fd)(void *st);
    int (*handle)(void *st, int max);
    void (*stats)(const void *st, marie_bus_stats_t *out);
    int (*sends)(const void *st);
    /* A channel provider's state for the whole bus: a descriptor of its own for the loop (-1:
     * none yet), the handling of what it signalled, the loop going to sleep (on: 1 when messages
     * wait already) or waking, whether messages wait, seen without a system call, and whether a
     * reader the last publish woke has not run yet. */
    void (*close_bus)(void *bus_st);
    int (*bus_fd)(void *bus_st);
    int (*bus_handle)(void *bus_st, int max);
    int (*bus_sleep)(void *bus_st, bool on);
    bool (*bus_pending)(void *bus_st);
    bool (*bus_waking)(void *bus_st);
} marie_bus_provider_t;

extern const marie_bus_provider_t marie_bus_udpm;      /* core/bus/udpm.c */
extern const marie_bus_provider_t marie_bus_liblcm;    /* core/bus/liblcm.c */
extern const marie_bus_provider_t marie_bus_shm;       /* core/bus/shm_bus.c */
extern const marie_bus_provider_t marie_bus_local;     /* core/bus/local.c */

/* liblcm's functions marie calls, opened at first use (core/bus/liblcm.c): a program that
 * does not ask for liblcm does not load it. marie_liblcm(): the table, or NULL with errno
 * (ENOENT: not installed, said in the log). Every bus liblcm made was made through it, or by a
 * program that links liblcm, so the provider's calls on such a bus need no check.
 * marie_liblcm_in_process(): whether liblcm is loaded already (the program links it). */
#define MARIE_LIBLCM_FUNCS(X)                                                                   \
    X(create) X(destroy) X(publish) X(subscribe) X(unsubscribe) X(get_fileno) X(handle)         \
    X(handle_timeout) X(subscription_set_queue_capacity)
typedef struct {
#define MARIE_LIBLCM_FIELD(f) __typeof__(lcm_##f) *f;
    MARIE_LIBLCM_FUNCS(MARIE_LIBLCM_FIELD)
#undef MARIE_LIBLCM_FIELD
} marie_liblcm_t;
const marie_liblcm_t *marie_liblcm(void);
bool marie_liblcm_in_process(void);
/* Whether a bus's handle (one being opened included) is liblcm's, not marie's own address. */
bool marie_bus_handle_is_liblcm(const lcm_t *lcm);
/* What lcm-gen's generated functions call in libmarie (core/bus/bus.c). */
int marie_lcm_publish(lcm_t *lcm, const char *channel, const void *data, unsigned int len);
lcm_subscription_t *marie_lcm_subscribe(lcm_t *lcm, const char *channel, lcm_msg_handler_t handler, void *user);
int marie_lcm_unsubscribe(lcm_t *lcm, lcm_subscription_t *s);
int marie_lcm_subscription_set_queue_capacity(lcm_subscription_t *s, int n);

/* For channel providers, which carry their notices and copies on the bus's own provider: a
 * publish and a subscription that no transport reroutes. */
int marie_bus_publish_own(lcm_t *bus, const char *channel, const void *data, size_t len);
marie_bus_sub_t *marie_bus_subscribe_own(lcm_t *bus, const char *channel, lcm_msg_handler_t handler, void *user);

#endif
