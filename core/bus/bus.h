/* bus: marie's one interface to the bus: open it, publish, subscribe, and a descriptor for the
 * loop. Each way of moving bytes is a provider behind it (core/bus/provider.h), a static table
 * of functions as LCM's own providers are: marie's reader and sender of LCM's UDP multicast
 * (udpm://), liblcm (every other URL, or every bus when MARIE_LCM_RECEIVE=liblcm), the
 * same-host shared-memory ring (`kind: shm`) and the same-host fast path (`kind: local`). The
 * URL chooses the bus's provider; the system file's `transports:` moves single channels to
 * another (docs/transport.md). A bus is named by its lcm_t, so lcm-gen's code and LCM's tools
 * take it as they are. A bus is made, read and destroyed by one thread (the loop's); any thread
 * may publish. */
#ifndef MARIE_BUS_H
#define MARIE_BUS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <lcm/lcm.h>

#ifdef __cplusplus
extern "C" {
#endif

struct marie_type;
struct marie_system;

/* Opens the bus at url (NULL: marie_default_url()). NULL with errno when no provider can. */
lcm_t *marie_bus_create(const char *url);
/* Whether url is one liblcm opens: PROVIDER://TARGET?OPTIONS with a provider it has; for udpm
 * (and mpudpm) a multicast IPv4 group, a port 1-65535 and only the options ttl (0-255),
 * recv_buf_size (1 to 1 GiB) and transmit_only. 0, or -1 with the reason in why (url_check.c). */
int marie_bus_url_check(const char *url, char *why, size_t len);
void marie_bus_destroy(lcm_t *bus);                 /* NULL is a no-op */

/* ---- per-channel transports ---- */

/* One channel moved to a provider of its own, as a system file's `transports:` entry says:
 * `kind` is a provider's name ("shm", "local"; "lcm" leaves the channel on the bus's own). */
typedef struct {
    const char *channel;
    const char *kind;
    size_t max_size;        /* bytes the largest encoded message may take */
    int slots;              /* messages the ring holds */
} marie_bus_transport_t;

/* Subscriptions and publishers made after it use it. 0, or -1 with errno (EINVAL: no provider of
 * that kind; EEXIST: the channel has subscribers or a publisher already). */
int marie_bus_set_transport(lcm_t *bus, const marie_bus_transport_t *t);
/* Every entry of a system file's `transports:` (NULL: none). 0, or -1 as above. */
int marie_bus_set_transports(lcm_t *bus, const struct marie_system *sys);

/* ---- publishing ---- */

/* Sends one message on channel, through whichever provider carries it; keeps nothing of its
 * arguments. 0, or -1 with errno: EINVAL (a channel over 63 characters), EMSGSIZE (past the
 * channel's max_size, or over 65535 LCM fragments), EIO (the provider refused). */
int marie_bus_publish(lcm_t *bus, const char *channel, const void *data, size_t len);
/* fill(dst, len, user) writes the len bytes of the message (an encoder), straight into shared
 * memory where the channel is on it, else into a buffer that is then sent; it returns 0, or -1 to
 * give the message up (then EINVAL). */
typedef int (*marie_bus_fill_t)(void *dst, size_t len, void *user);
int marie_bus_publish_with(lcm_t *bus, const char *channel, size_t len, marie_bus_fill_t fill, void *user);
/* lcm-gen's TYPE_publish() through marie_bus_publish(): encodes msg, of type t (lcmtypes'
 * marie_type_TYPE), and sends it. 0, or -1 with errno (EINVAL: t cannot encode it). */
int marie_bus_publish_msg(lcm_t *bus, const char *channel, const struct marie_type *t, const void *msg);
/* Several messages at once, in their order: where marie sends them on LCM, a run of those that
 * fit one datagram each goes to the kernel in one system call. rc[i] gets message i's result (0,
 * or -1 with errno). Returns how many were sent. */
typedef struct {
    const char *channel;
    const void *data;
    unsigned len;
} marie_bus_msg_t;
int marie_bus_publish_batch(lcm_t *bus, const marie_bus_msg_t *m, int n, int *rc);
/* A loan: room for the channel's next message where its readers will read it (max_size bytes),
 * for a producer that makes the message in place; marie_bus_commit() publishes its first len
 * bytes. NULL with ENOTSUP where the channel's provider lends nothing (it copies). A loan lasts
 * until the channel's next commit or publish, which takes it up. */
void *marie_bus_loan(lcm_t *bus, const char *channel);
int marie_bus_commit(lcm_t *bus, const char *channel, size_t len);
/* Gets the channel's publisher ready (a shared-memory ring, made now): so a start-up can say
 * what is wrong before the first message. 0, or -1 with errno. */
int marie_bus_prepare(lcm_t *bus, const char *channel);

/* ---- subscribing ---- */

/* `channel` is a regular expression matched against the whole channel name, as in LCM; a plain
 * name (or one whose special characters are escaped) that a transport moved is read from that
 * transport. Handlers get lcm_recv_buf_t as LCM's do. NULL with errno on failure. A handler may
 * unsubscribe (itself included), subscribe, and read the bus again from a nested loop. Messages
 * wait in the provider until read: for marie's reader in the socket's kernel buffer, which marie
 * enlarges; liblcm's subscriptions hold MARIE_BUS_QUEUE (its own default of 30 drops a bring-up's
 * heartbeats without a word). */
#define MARIE_BUS_QUEUE 4096
typedef struct marie_bus_sub marie_bus_sub_t;
marie_bus_sub_t *marie_bus_subscribe(lcm_t *bus, const char *channel, lcm_msg_handler_t handler, void *user);
/* The same for a handler that only decodes the bytes where they lie (a typed port): in shared
 * memory a writer may overwrite them while it reads, and `verdict(intact, user)` then says
 * whether they stayed intact throughout; when not, whatever was made of them must be dropped
 * (the loss is counted). From other providers verdict is always 1, right after the handler. */
typedef void (*marie_bus_verdict_t)(bool intact, void *user);
/* `held` (may be NULL) is called instead of handler when the provider holds the bytes until
 * verdict returns (a shared-memory slot the writer skips meanwhile, docs/transport.md): what
 * is made of them may then point into them and be used from verdict. */
marie_bus_sub_t *marie_bus_subscribe_in_place(lcm_t *bus, const char *channel, lcm_msg_handler_t handler,
                                              lcm_msg_handler_t held, marie_bus_verdict_t verdict, void *user);
void marie_bus_unsubscribe(lcm_t *bus, marie_bus_sub_t *s);     /* NULL is a no-op */

/* What a subscription's provider lost or refused since it was made (zero where the provider
 * counts on the bus instead, below). */
typedef struct {
    int64_t received;       /* from this host's shared memory */
    int64_t remote;         /* from LCM, the writer being on another host */
    int64_t lost;           /* overwritten before they were read (a slow reader) */
    int64_t bad;            /* malformed notices, or a size or type that does not match */
} marie_bus_sub_stats_t;
marie_bus_sub_stats_t marie_bus_sub_stats(const lcm_t *bus, const marie_bus_sub_t *s);

/* ---- the loop's side ---- */

/* The descriptor to poll, and the handling of at most `max` messages that are ready, without
 * waiting. Returns how many were handled. */
int marie_bus_fd(lcm_t *bus);
int marie_bus_handle(lcm_t *bus, int max);

/* The same-host fast path has a descriptor of its own, a doorbell, from the bus's first
 * subscription on a `local` channel (-1 before): the loop polls it too, and hands what it
 * signals to marie_bus_handle_wake() (at most max messages; how many were handled). A fast
 * path's publisher rings a reader's doorbell only while the reader sleeps: the loop says so,
 * marie_bus_sleep(bus, 1) before it sleeps (1: messages wait already, do not sleep) and
 * marie_bus_sleep(bus, 0) once it wakes. marie_bus_pending() says whether messages wait on the
 * fast path without a system call (the loop's spinning looks at it). marie_bus_waking() says
 * whether a reader that the bus's last fast-path publish had to wake has not run yet: the loop
 * does not spin past a moment then, as that reader may be waiting for the loop's CPU. */
int marie_bus_wake_fd(lcm_t *bus);
int marie_bus_handle_wake(lcm_t *bus, int max);
int marie_bus_sleep(lcm_t *bus, bool on);
bool marie_bus_pending(lcm_t *bus);
bool marie_bus_waking(lcm_t *bus);

/* What marie's reader saw on the bus (all zero where liblcm reads it). */
typedef struct {
    int64_t messages;       /* whole messages received (delivered or not subscribed) */
    int64_t malformed;      /* datagrams that are not LCM's or contradict themselves */
    int64_t incomplete;     /* fragmented messages given up with fragments missing */
    int64_t dropped;        /* datagrams the kernel dropped, the socket's buffer full: counted
                             * only while a subscription may match any channel (the kernel
                             * counts what its filter refuses with them, docs/transport.md) */
} marie_bus_stats_t;
void marie_bus_stats(const lcm_t *bus, marie_bus_stats_t *st);
/* 1 when marie reads (sends) this bus itself, 0 when liblcm does. */
int marie_bus_native(const lcm_t *bus);
int marie_bus_sends(const lcm_t *bus);

#ifdef __cplusplus
}
#endif
#endif
