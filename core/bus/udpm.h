/* udpm: marie's reader and sender of LCM's UDP multicast protocol, the provider of udpm:// buses
 * (docs/transport.md, "Reading the bus" and "Sending the bus"). The parts' shared state; only
 * core/bus/udpm*.c use it. */
#ifndef MARIE_BUS_UDPM_H
#define MARIE_BUS_UDPM_H

#include <netinet/in.h>
#include <pthread.h>
#include <regex.h>
#include <stdbool.h>
#include <stdint.h>
#include <sys/socket.h>

#include "core/bus/provider.h"

/* LCM's wire format (lcm/udpm_util.h): big-endian headers, then the channel and its NUL in a
 * short message or in the first fragment of a long one. */
#define MAGIC_SHORT 0x4c433032u     /* "LC02" */
#define MAGIC_LONG 0x4c433033u      /* "LC03" */
#define SHORT_HDR 8                 /* magic, sequence number */
#define LONG_HDR 20                 /* magic, seqno, size, fragment offset, fragment no, count */
#define DATAGRAM_MAX 65536
/* What liblcm 1.3.1 sends on Linux (udpm_util.h): a message whose channel, its NUL and payload
 * take at most SHORT_MAX bytes goes in one LC02 datagram, a larger one in LC03 fragments of at
 * most FRAG_PAYLOAD bytes after their header, the channel and its NUL counted in the first. */
#define SHORT_MAX 65499
#define FRAG_PAYLOAD 65487
#define FRAGS_MAX 65535
#define FRAGS_PER_CALL 64           /* fragments handed to one sendmmsg() */
/* Fragmented messages being put together: at most this many senders at once, this many bytes
 * each (liblcm's own bound on all of them is 16 MB). */
#define FRAG_SLOTS 16
#define FRAG_MAX_BYTES (64u << 20)
#define SPARE_MAX (16u << 20)

typedef struct udpm_sub {
    struct udpm_sub *next;
    marie_bus_recv_t rv;
    char *channel;
    bool literal;           /* no regular expression character: compared as a string */
    bool removed;           /* unsubscribed during a dispatch: freed after it */
    regex_t re;
} udpm_sub_t;

typedef struct {
    bool used, ignore;      /* ignore: nobody subscribes to its channel */
    struct sockaddr_in from;
    uint32_t seqno, size;
    uint16_t nfrags, got;
    uint32_t *span;         /* per fragment: its offset and 1 + its length (0: not come) */
    uint8_t *data;
    size_t cap;             /* of data */
    char channel[LCM_MAX_CHANNEL_NAME_LENGTH + 1];
    int64_t touched;        /* order of use, for eviction */
} frag_t;

typedef struct {
    lcm_t *lcm;
    int fd;
    udpm_sub_t *subs;
    int depth;              /* dispatches running (a handler may read the bus again) */
    bool any_removed;
    uint8_t *buf;           /* DATAGRAM_MAX, for the outermost read */
    uint8_t *spare;         /* the last large message's buffer, for the next one */
    size_t spare_cap;
    frag_t frags[FRAG_SLOTS];
    int64_t clock;
    uint32_t ovfl;          /* the kernel's drop count at the last datagram */
    bool filtered;          /* a socket filter is attached (udpm_refilter()) */
    bool peek;              /* the last datagram was not a short message taken: peek the next */
    marie_bus_stats_t st;
    /* Sending, from any thread: tx_lock keeps a message's fragments together and its sequence
     * number its own, as liblcm's transmit lock does. */
    int tx_fd;              /* -1: liblcm sends on this bus (MARIE_LCM_SEND=liblcm, or a TTL
                             * liblcm would read otherwise), through tx_lcm */
    lcm_t *tx_lcm;
    bool tx_lcm_own;        /* tx_lcm made for this bus (the bus's handle is marie's own) */
    struct sockaddr_in tx_to;
    uint32_t tx_seqno;
    pthread_mutex_t tx_lock;
} udpm_t;

/* A datagram being read: its first bytes seen without taking it from the socket (MSG_PEEK), so
 * that what nobody subscribes to is dropped uncopied and a fragment goes straight to its place
 * in the message being put together; or, where short messages for this process come one after
 * the other, read whole at once (data), one system call instead of two. */
typedef struct {
    uint8_t head[LONG_HDR + LCM_MAX_CHANNEL_NAME_LENGTH + 1];
    size_t len;             /* the whole datagram's */
    size_t seen;            /* of it in head */
    const uint8_t *data;    /* the datagram when read whole, else NULL (peeked) */
    struct sockaddr_in from;
    int64_t utime;
} datagram_t;

/* udpm.c */
bool udpm_wanted(const udpm_t *u, const char *channel);
void udpm_dispatch(udpm_t *u, const char *channel, void *data, uint32_t size, int64_t utime);
const char *udpm_channel_at(const uint8_t *p, size_t n);
/* udpm_recv.c: the next datagram, taken from the socket into iov (none: dropped), fragments */
ssize_t udpm_next_datagram(udpm_t *u, datagram_t *g, uint8_t *buf);
bool udpm_take(udpm_t *u, datagram_t *g, struct iovec *iov, int niov);
void udpm_drop_malformed(udpm_t *u, datagram_t *g);
int udpm_on_fragment(udpm_t *u, datagram_t *g);
void udpm_frags_free(udpm_t *u);
uint32_t udpm_be32(const uint8_t *p);
/* udpm_filter.c: the kernel filter, rebuilt whenever the subscriptions change */
size_t udpm_literal_prefix(const char *re, bool *whole);
void udpm_refilter(udpm_t *u);
/* udpm_send.c */
int udpm_publish(void *st, const char *channel, const void *data, size_t len);
int udpm_publish_batch(void *st, const marie_bus_msg_t *m, int n, int *rc);

#endif
