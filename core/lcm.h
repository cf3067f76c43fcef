/* lcm: marie's LCM buses. A bus opened with marie_lcm_create() on a UDP multicast URL is read by
 * marie itself, from the loop's thread (docs/transport.md, "Reading the bus"): liblcm's receive
 * thread and its pipe cost two wake-ups per message. marie_lcm_publish() sends on such a bus
 * from a socket of marie's own ("Sending"). The wire protocol is LCM's (LC02 datagrams, LC03
 * fragments), so lcm-spy, lcm-logger and every other LCM program share the bus. Other URLs
 * (file://, memq://), a bus made by lcm_create(), and every bus when MARIE_LCM_RECEIVE=liblcm is
 * set, are read and sent on by liblcm as before. Subscriptions to a bus a loop reads go through
 * marie_lcm_subscribe(). */
#ifndef MARIE_LCM_H
#define MARIE_LCM_H

#include <stdint.h>

#include <lcm/lcm.h>

#ifdef __cplusplus
extern "C" {
#endif

/* lcm_create(url) (NULL: marie_default_url()), read by marie when it is UDP multicast. A bus is
 * made, read and destroyed by one thread (the loop's), as marie_loop is. */
lcm_t *marie_lcm_create(const char *url);
/* Whether url is one liblcm opens: PROVIDER://TARGET?OPTIONS with a provider it has; for udpm
 * (and mpudpm) a multicast IPv4 group, a port 1-65535 and only the options ttl (0-255),
 * recv_buf_size (1 to 1 GiB) and transmit_only. 0, or -1 with the reason in why. */
int marie_lcm_url_check(const char *url, char *why, size_t len);
void marie_lcm_destroy(lcm_t *lcm);                 /* NULL is a no-op */
int marie_lcm_native(const lcm_t *lcm);             /* 1: marie reads it, 0: liblcm does */

/* lcm_publish() for a bus made by marie_lcm_create(): on a bus marie reads, the message goes out
 * on marie's own socket as liblcm would send it (one LC02 datagram when the channel, its NUL and
 * the payload take at most 65499 bytes, LC03 fragments otherwise), to the URL's group and port
 * with its ttl (0 when it names none) and multicast loopback on, so this process and this host
 * receive it. Elsewhere (another provider, a bus made by lcm_create(), MARIE_LCM_RECEIVE=liblcm,
 * or MARIE_LCM_SEND=liblcm, which leaves only the sending to liblcm) it is lcm_publish(). Any
 * thread may call it. Keeps nothing of its arguments. 0, or -1 with errno (EINVAL: a channel
 * over 63 characters; EMSGSIZE: over 65535 fragments; EIO: liblcm refused). */
int marie_lcm_publish(lcm_t *lcm, const char *channel, const void *data, unsigned len);
/* Several messages at once, in their order: on a bus marie sends on, a run of messages that fit
 * one datagram each goes to the kernel in one system call (sendmmsg); anything else as
 * marie_lcm_publish() sends it. rc[i] gets message i's result (0, or -1 with errno set as
 * marie_lcm_publish() sets it). Returns how many were sent. */
typedef struct {
    const char *channel;
    const void *data;
    unsigned len;
} marie_lcm_msg_t;
int marie_lcm_publish_batch(lcm_t *lcm, const marie_lcm_msg_t *m, int n, int *rc);
int marie_lcm_sends(const lcm_t *lcm);              /* 1: marie sends on it, 0: liblcm does */

/* lcm-gen's TYPE_publish() through marie_lcm_publish(): encodes msg, of type t (lcmtypes'
 * marie_type_TYPE), and sends it. 0, or -1 with errno (EINVAL: t cannot encode it). */
struct marie_type;
int marie_lcm_publish_msg(lcm_t *lcm, const char *channel, const struct marie_type *t, const void *msg);

/* A subscription: `channel` is a regular expression matched against the whole channel name, as
 * in LCM. liblcm's subscriptions hold MARIE_LCM_QUEUE messages until read (its own default is
 * 30, dropped without a word: a bring-up of 45 components sends ~135 heartbeats while the
 * managers spawn); marie's are held by the socket's kernel buffer, which marie enlarges. NULL
 * with errno on failure. Unsubscribing from a handler, the handler's own included, is allowed.
 * On a bus liblcm reads, the pointer is liblcm's subscription (lcm_subscription_t). */
#define MARIE_LCM_QUEUE 4096
typedef struct marie_lcm_sub marie_lcm_sub_t;
marie_lcm_sub_t *marie_lcm_subscribe(lcm_t *lcm, const char *channel, lcm_msg_handler_t handler, void *user);
void marie_lcm_unsubscribe(lcm_t *lcm, marie_lcm_sub_t *s);    /* NULL is a no-op */

/* What marie's receiver saw on a bus (all zero for a bus liblcm reads). */
typedef struct {
    int64_t messages;       /* whole messages received (delivered or not subscribed) */
    int64_t malformed;      /* datagrams that are not LCM's or contradict themselves */
    int64_t incomplete;     /* fragmented messages given up with fragments missing */
    int64_t dropped;        /* datagrams the kernel dropped, the socket's buffer full: counted
                             * only while a subscription may match any channel (the kernel
                             * counts what its filter refuses with them, docs/transport.md) */
} marie_lcm_stats_t;
void marie_lcm_stats(const lcm_t *lcm, marie_lcm_stats_t *st);

/* For the loop: the descriptor to poll (marie's socket, or liblcm's pipe), and the handling of
 * at most `max` messages that are ready, without waiting. Returns how many were handled. */
int marie_lcm_fd(lcm_t *lcm);
int marie_lcm_handle(lcm_t *lcm, int max);

#ifdef __cplusplus
}
#endif
#endif
