/* lcm: marie's reader and sender of LCM's UDP multicast protocol (core/lcm.h). */
#include "core/lcm.h"

#include <arpa/inet.h>
#include <errno.h>
#include <linux/filter.h>
#include <netinet/in.h>
#include <pthread.h>
#include <regex.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include "core/config.h"
#include "core/err.h"
#include "core/log.h"
#include "core/time.h"
#include "lcmtypes/marie_types.h"

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
#define RECV_BUF_DEFAULT (2 << 20)  /* bytes of kernel buffer when the URL names none */
/* Fragmented messages being put together: at most this many senders at once, this many bytes
 * each (liblcm's own bound on all of them is 16 MB). */
#define FRAG_SLOTS 16
#define FRAG_MAX_BYTES (64u << 20)
#define SPARE_MAX (16u << 20)
/* Datagrams read per call at most, whole messages or not (fragments, strangers' garbage). */
#define DATAGRAMS_PER_CALL 256

struct marie_lcm_sub {
    struct marie_lcm_sub *next;
    lcm_msg_handler_t handler;
    void *user;
    char *channel;
    bool literal;           /* no regular expression character: compared as a string */
    bool removed;           /* unsubscribed during a dispatch: freed after it */
    regex_t re;
};

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

typedef struct bus {
    struct bus *next;
    lcm_t *lcm;
    int fd;                 /* -1: liblcm reads this bus */
    marie_lcm_sub_t *subs;
    int depth;              /* dispatches running (a handler may read the bus again) */
    bool any_removed;
    uint8_t *buf;           /* DATAGRAM_MAX, for the outermost read */
    uint8_t *spare;         /* the last large message's buffer, for the next one */
    size_t spare_cap;
    frag_t frags[FRAG_SLOTS];
    int64_t clock;
    uint32_t ovfl;          /* the kernel's drop count at the last datagram */
    bool filtered;          /* a socket filter is attached (refilter()) */
    bool peek;              /* the last datagram was not a short message taken: peek the next */
    marie_lcm_stats_t st;
    /* Sending (marie_lcm_publish), from any thread: tx_lock keeps a message's fragments
     * together and its sequence number its own, as liblcm's transmit lock does. */
    int tx_fd;              /* -1: liblcm sends on this bus */
    struct sockaddr_in tx_to;
    uint32_t tx_seqno;
    pthread_mutex_t tx_lock;
} bus_t;

/* The buses marie_lcm_create() made. Guarded, since a bus may be published on from any thread;
 * it is still made, read and destroyed by one. */
static bus_t *buses;
static pthread_mutex_t buses_lock = PTHREAD_MUTEX_INITIALIZER;

static void refilter(bus_t *b);

static bus_t *find(const lcm_t *lcm)
{
    pthread_mutex_lock(&buses_lock);
    bus_t *b = buses;
    while (b && b->lcm != lcm)
        b = b->next;
    pthread_mutex_unlock(&buses_lock);
    return b;
}

typedef struct {
    struct in_addr group;
    uint16_t port;
    int rcvbuf;
    int ttl;                /* -1: not one liblcm would read the same (left to liblcm) */
} udpm_t;

/* "udpm://ADDR:PORT?opt=v&..." into u; false when marie should leave the bus to liblcm (another
 * provider, transmit_only, not understood). */
static bool parse_udpm(const char *url, udpm_t *u)
{
    const char *p = url;
    if (strncmp(p, "udpm://", 7) != 0)
        return false;
    p += 7;
    char addr[64];
    size_t n = strcspn(p, ":?");
    if (n == 0 || n >= sizeof addr)
        return false;
    memcpy(addr, p, n);
    addr[n] = '\0';
    if (inet_pton(AF_INET, addr, &u->group) != 1 || !IN_MULTICAST(ntohl(u->group.s_addr)))
        return false;
    p += n;
    u->port = 7667;
    if (*p == ':') {
        char *end;
        unsigned long v = strtoul(p + 1, &end, 10);
        if (end == p + 1 || v == 0 || v > 65535)
            return false;
        u->port = (uint16_t)v;
        p = end;
    }
    u->rcvbuf = RECV_BUF_DEFAULT;
    u->ttl = 0;             /* liblcm's default: nothing leaves the host */
    if (*p == '\0')
        return true;
    if (*p != '?')
        return false;
    for (p++; *p; p += *p == '&') {
        size_t len = strcspn(p, "&");
        if (strncmp(p, "recv_buf_size=", 14) == 0) {
            long v = atol(p + 14);
            if (v > 0 && v <= (1 << 30))
                u->rcvbuf = (int)v;
        } else if (strncmp(p, "ttl=", 4) == 0) {
            char *end;
            long v = strtol(p + 4, &end, 0);    /* liblcm's reading: base 0 */
            u->ttl = end > p + 4 && end == p + len && v >= 0 && v <= 255 ? (int)v : -1;
        } else if (strncmp(p, "transmit_only=", 14) == 0 &&
                   (strncmp(p + 14, "true", 4) == 0 || p[14] == '1')) {
            return false;
        }
        p += len;
    }
    return true;
}

static int open_socket(struct in_addr group, uint16_t port, int rcvbuf)
{
    int fd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return -1;
    int one = 1;
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons(port), .sin_addr.s_addr = htonl(INADDR_ANY)};
    struct ip_mreq m = {.imr_multiaddr = group, .imr_interface.s_addr = htonl(INADDR_ANY)};
    if (setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) < 0 ||
        bind(fd, (struct sockaddr *)&a, sizeof a) < 0 ||
        setsockopt(fd, IPPROTO_IP, IP_ADD_MEMBERSHIP, &m, sizeof m) < 0 ||
        setsockopt(fd, SOL_SOCKET, SO_TIMESTAMP, &one, sizeof one) < 0 ||
        setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof one) < 0) {
        MARIE_KEEP_ERRNO(close(fd));
        return -1;
    }
    /* No receive thread empties this buffer while the loop is busy: it must hold a burst. Past
     * net.core.rmem_max only a privileged process may ask (docs/transport.md). */
    if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &rcvbuf, sizeof rcvbuf) < 0)
        (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    return fd;
}

/* The socket marie sends on: its own port (receivers put fragments together per sender), the
 * URL's TTL, and multicast loopback on, so this process and this host hear what it sends. */
static int open_sender(const udpm_t *u)
{
    int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd < 0)
        return -1;
    int ttl = u->ttl, loop = 1;
    if (setsockopt(fd, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof ttl) < 0 ||
        setsockopt(fd, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof loop) < 0) {
        MARIE_KEEP_ERRNO(close(fd));
        return -1;
    }
    return fd;
}

static bool env_is(const char *name, const char *value)
{
    const char *v = getenv(name);
    return v && strcmp(v, value) == 0;
}

lcm_t *marie_lcm_create(const char *url)
{
    if (!url)
        url = marie_default_url();
    lcm_t *lcm = lcm_create(url);
    if (!lcm)
        return NULL;
    bus_t *b = calloc(1, sizeof *b);
    if (!b) {
        lcm_destroy(lcm);
        return marie_fail_null(ENOMEM);
    }
    b->lcm = lcm;
    b->fd = -1;
    b->tx_fd = -1;
    pthread_mutex_init(&b->tx_lock, NULL);
    udpm_t u;
    if (!env_is("MARIE_LCM_RECEIVE", "liblcm") && parse_udpm(url, &u)) {
        b->fd = open_socket(u.group, u.port, u.rcvbuf);
        if (b->fd < 0)      /* liblcm will say what is wrong when it is asked to read */
            marie_warn("%s: marie cannot read this bus itself (%s); liblcm reads it", url, strerror(errno));
        else if (!(b->buf = malloc(DATAGRAM_MAX))) {
            close(b->fd);
            b->fd = -1;
        }
        if (b->fd >= 0)
            refilter(b);        /* nothing subscribed yet: no short message is read */
        /* Sent by marie only where it reads too, and with a TTL liblcm would read the same. */
        if (b->fd >= 0 && u.ttl >= 0 && !env_is("MARIE_LCM_SEND", "liblcm")) {
            b->tx_to = (struct sockaddr_in){.sin_family = AF_INET, .sin_port = htons(u.port), .sin_addr = u.group};
            if ((b->tx_fd = open_sender(&u)) < 0)
                marie_warn("%s: marie cannot send on this bus itself (%s); liblcm sends", url, strerror(errno));
        }
    }
    pthread_mutex_lock(&buses_lock);
    b->next = buses;
    buses = b;
    pthread_mutex_unlock(&buses_lock);
    return lcm;
}

static void frag_drop(frag_t *f)
{
    free(f->data);
    free(f->span);
    memset(f, 0, sizeof *f);
}

static void sub_free(marie_lcm_sub_t *s)
{
    if (!s->literal)
        regfree(&s->re);
    free(s->channel);
    free(s);
}

void marie_lcm_destroy(lcm_t *lcm)
{
    if (!lcm)
        return;
    bus_t *b = NULL;
    pthread_mutex_lock(&buses_lock);
    for (bus_t **pp = &buses; *pp; pp = &(*pp)->next) {
        if ((*pp)->lcm == lcm) {
            b = *pp;
            *pp = b->next;
            break;
        }
    }
    pthread_mutex_unlock(&buses_lock);
    if (b) {
        while (b->subs) {
            marie_lcm_sub_t *n = b->subs->next;
            sub_free(b->subs);
            b->subs = n;
        }
        for (int i = 0; i < FRAG_SLOTS; i++)
            frag_drop(&b->frags[i]);
        if (b->fd >= 0)
            close(b->fd);
        if (b->tx_fd >= 0)
            close(b->tx_fd);
        pthread_mutex_destroy(&b->tx_lock);
        free(b->buf);
        free(b->spare);
        free(b);
    }
    lcm_destroy(lcm);
}

int marie_lcm_native(const lcm_t *lcm)
{
    const bus_t *b = find(lcm);
    return b && b->fd >= 0;
}

void marie_lcm_stats(const lcm_t *lcm, marie_lcm_stats_t *st)
{
    const bus_t *b = find(lcm);
    *st = b ? b->st : (marie_lcm_stats_t){0};
}

/* The literal start every channel a subscription matches begins with (its length), and whether
 * the pattern is that literal whole. 0 and not whole: it may match any channel. */
static size_t literal_prefix(const char *re, bool *whole)
{
    *whole = false;
    if (strchr(re, '|'))
        return 0;
    size_t n = strcspn(re, ".[]()*+?{}|^$\\");
    *whole = re[n] == '\0';
    if (!*whole && n > 0 && strchr("*?{", re[n]))
        n--;                    /* the character before may be absent */
    return n;
}

#define BPF_MAX 1024
#define UDP_HDR 8               /* a UDP socket's filter sees the UDP header first */

static size_t bpf_add(struct sock_filter *p, size_t n, uint16_t code, uint8_t jt, uint8_t jf, uint32_t k)
{
    if (n < BPF_MAX)
        p[n] = (struct sock_filter){code, jt, jf, k};
    return n + 1;
}

/* The kernel drops, before they wake anyone, short messages on channels no subscription can
 * match (at 500 components every process otherwise woke for every heartbeat): a classic BPF
 * filter on the socket, a block per subscription comparing the channel's literal start.
 * Fragments and what is not LCM's pass (to be put together, or counted). Rebuilt whenever the
 * subscriptions change; none when one of them may match anything. */
static void refilter(bus_t *b)
{
    struct sock_filter p[BPF_MAX];
    size_t n = 0;
    const uint32_t ACCEPT = 0xffffffffu;
    n = bpf_add(p, n, BPF_LD | BPF_W | BPF_LEN, 0, 0, 0);
    n = bpf_add(p, n, BPF_JMP | BPF_JGE | BPF_K, 1, 0, UDP_HDR + SHORT_HDR + 1);
    n = bpf_add(p, n, BPF_RET | BPF_K, 0, 0, ACCEPT);
    n = bpf_add(p, n, BPF_LD | BPF_W | BPF_ABS, 0, 0, UDP_HDR);
    n = bpf_add(p, n, BPF_JMP | BPF_JEQ | BPF_K, 1, 0, MAGIC_SHORT);
    n = bpf_add(p, n, BPF_RET | BPF_K, 0, 0, ACCEPT);
    bool open = false;
    for (const marie_lcm_sub_t *s = b->subs; s && !open; s = s->next) {
        if (s->removed)
            continue;
        bool whole;
        size_t len = literal_prefix(s->channel, &whole);
        if (len == 0) {
            open = true;
            break;
        }
        /* ld len; jge need; then per 4, 2 or 1 bytes: ld; jeq; then (whole) ld the NUL; jeq 0;
         * ret accept. A mismatch jumps to the next block: at most 3 + 2*(63/4+2) + 2 ahead. */
        size_t chunks = 0;
        for (size_t i = 0; i < len; i += len - i >= 4 ? 4 : len - i >= 2 ? 2 : 1)
            chunks++;
        size_t block = 2 + 2 * chunks + (whole ? 2 : 0) + 1, k = 0;
        const size_t at = UDP_HDR + SHORT_HDR;
#define NEXT ((uint8_t)(block - k - 1))
        n = bpf_add(p, n, BPF_LD | BPF_W | BPF_LEN, 0, 0, 0), k++;
        n = bpf_add(p, n, BPF_JMP | BPF_JGE | BPF_K, 0, NEXT, (uint32_t)(at + len + whole)), k++;
        for (size_t i = 0; i < len;) {
            size_t w = len - i >= 4 ? 4 : len - i >= 2 ? 2 : 1;
            uint32_t v = 0;
            for (size_t j = 0; j < w; j++)
                v = v << 8 | (uint8_t)s->channel[i + j];
            n = bpf_add(p, n, BPF_LD | (w == 4 ? BPF_W : w == 2 ? BPF_H : BPF_B) | BPF_ABS, 0, 0, (uint32_t)(at + i)), k++;
            n = bpf_add(p, n, BPF_JMP | BPF_JEQ | BPF_K, 0, NEXT, v), k++;
            i += w;
        }
        if (whole) {
            n = bpf_add(p, n, BPF_LD | BPF_B | BPF_ABS, 0, 0, (uint32_t)(at + len)), k++;
            n = bpf_add(p, n, BPF_JMP | BPF_JEQ | BPF_K, 0, NEXT, 0), k++;
        }
#undef NEXT
        n = bpf_add(p, n, BPF_RET | BPF_K, 0, 0, ACCEPT);
    }
    n = bpf_add(p, n, BPF_RET | BPF_K, 0, 0, 0);
    struct sock_fprog prog = {(unsigned short)n, p};
    if (open || n > BPF_MAX) {
        int zero = 0;
        (void)setsockopt(b->fd, SOL_SOCKET, SO_DETACH_FILTER, &zero, sizeof zero);
        b->filtered = false;
    } else if (setsockopt(b->fd, SOL_SOCKET, SO_ATTACH_FILTER, &prog, sizeof prog) < 0) {
        marie_warn_ratelimited(60, "cannot filter the LCM bus in the kernel (%s): every message is read", strerror(errno));
        b->filtered = false;
    } else {
        b->filtered = true;
    }
}

marie_lcm_sub_t *marie_lcm_subscribe(lcm_t *lcm, const char *channel, lcm_msg_handler_t handler, void *user)
{
    if (!lcm || !channel || !handler)
        return marie_fail_null(EINVAL);
    bus_t *b = find(lcm);
    if (!b || b->fd < 0) {      /* liblcm's own subscription stands for it */
        lcm_subscription_t *ls = lcm_subscribe(lcm, channel, handler, user);
        if (!ls)
            return marie_fail_null(EIO);
        lcm_subscription_set_queue_capacity(ls, MARIE_LCM_QUEUE);
        return (marie_lcm_sub_t *)ls;
    }
    marie_lcm_sub_t *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->handler = handler;
    s->user = user;
    literal_prefix(channel, &s->literal);  /* a plain name is compared as a string */
    char *anchored = NULL;
    if (!(s->channel = strdup(channel)) ||
        (!s->literal && (asprintf(&anchored, "^(%s)$", channel) < 0 ||
                         regcomp(&s->re, anchored, REG_EXTENDED | REG_NOSUB) != 0))) {
        if (!s->literal && anchored)
            marie_warn("cannot subscribe to '%s': not a regular expression", channel);
        free(anchored);
        s->literal = true;
        sub_free(s);
        return marie_fail_null(EINVAL);
    }
    free(anchored);
    marie_lcm_sub_t **pp = &b->subs;    /* in subscription order, as liblcm calls them */
    while (*pp)
        pp = &(*pp)->next;
    *pp = s;
    refilter(b);
    return s;
}

static void sweep_removed(bus_t *b)
{
    for (marie_lcm_sub_t **pp = &b->subs; *pp;) {
        marie_lcm_sub_t *s = *pp;
        if (s->removed) {
            *pp = s->next;
            sub_free(s);
        } else {
            pp = &s->next;
        }
    }
    b->any_removed = false;
}

void marie_lcm_unsubscribe(lcm_t *lcm, marie_lcm_sub_t *s)
{
    if (!s)
        return;
    bus_t *b = find(lcm);
    if (!b || b->fd < 0) {
        lcm_unsubscribe(lcm, (lcm_subscription_t *)s);
        return;
    }
    s->removed = true;
    b->any_removed = true;
    refilter(b);
    if (b->depth == 0)
        sweep_removed(b);
}

static bool matches(const marie_lcm_sub_t *s, const char *channel)
{
    return s->literal ? strcmp(s->channel, channel) == 0 : regexec(&s->re, channel, 0, NULL, 0) == 0;
}

static bool wanted(const bus_t *b, const char *channel)
{
    for (const marie_lcm_sub_t *s = b->subs; s; s = s->next)
        if (!s->removed && matches(s, channel))
            return true;
    return false;
}

static void dispatch(bus_t *b, const char *channel, void *data, uint32_t size, int64_t utime)
{
    b->st.messages++;
    lcm_recv_buf_t rb = {data, size, utime, b->lcm};
    b->depth++;
    for (marie_lcm_sub_t *s = b->subs; s; s = s->next)
        if (!s->removed && matches(s, channel))
            s->handler(&rb, channel, s->user);
    if (--b->depth == 0 && b->any_removed)
        sweep_removed(b);
}

/* The channel at p (at most n bytes, NUL included), or NULL when there is none. */
static const char *channel_at(const uint8_t *p, size_t n)
{
    const uint8_t *nul = memchr(p, '\0', n < LCM_MAX_CHANNEL_NAME_LENGTH + 1 ? n : LCM_MAX_CHANNEL_NAME_LENGTH + 1);
    return nul && nul > p ? (const char *)p : NULL;
}

static uint32_t be32(const uint8_t *p) { return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]; }
static uint16_t be16(const uint8_t *p) { return (uint16_t)(p[0] << 8 | p[1]); }

static frag_t *frag_slot(bus_t *b, const struct sockaddr_in *from)
{
    frag_t *free_slot = NULL, *oldest = NULL;
    for (int i = 0; i < FRAG_SLOTS; i++) {
        frag_t *f = &b->frags[i];
        if (!f->used) {
            if (!free_slot)
                free_slot = f;
        } else if (f->from.sin_addr.s_addr == from->sin_addr.s_addr && f->from.sin_port == from->sin_port) {
            return f;
        } else if (!oldest || f->touched < oldest->touched) {
            oldest = f;
        }
    }
    if (free_slot)
        return free_slot;
    if (!oldest->ignore)
        b->st.incomplete++;
    frag_drop(oldest);
    return oldest;
}

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

typedef union {
    char space[CMSG_SPACE(sizeof(struct timeval)) + CMSG_SPACE(sizeof(uint32_t))];
    struct cmsghdr align;
} arrival_ctl_t;

/* The datagram's time of arrival and the kernel's drop count, from what recvmsg gave with it. */
static void arrival(bus_t *b, datagram_t *g, struct msghdr *msg)
{
    g->utime = 0;
    for (struct cmsghdr *c = CMSG_FIRSTHDR(msg); c; c = CMSG_NXTHDR(msg, c)) {
        if (c->cmsg_level != SOL_SOCKET)
            continue;
        if (c->cmsg_type == SO_TIMESTAMP) {
            struct timeval tv;
            memcpy(&tv, CMSG_DATA(c), sizeof tv);
            g->utime = (int64_t)tv.tv_sec * 1000000 + tv.tv_usec;
        } else if (c->cmsg_type == SO_RXQ_OVFL) {
            uint32_t total;
            memcpy(&total, CMSG_DATA(c), sizeof total);
            /* The kernel counts what the filter refused with what the buffer could not hold:
             * only a bus without a filter can tell its losses. */
            if (total != b->ovfl && !b->filtered) {
                b->st.dropped += (uint32_t)(total - b->ovfl);
                marie_warn_ratelimited(10, "the LCM bus's receive buffer overflowed: %lld datagrams lost so far",
                                       (long long)b->st.dropped);
            }
            b->ovfl = total;
        }
    }
    if (!g->utime)
        g->utime = marie_wall_us();
}

/* Takes the datagram from the socket into the iov (none: dropped), with its time of arrival and
 * the kernel's drop count; false when the socket gave something else than was peeked. A datagram
 * read whole is copied from where it was read. */
static bool take(bus_t *b, datagram_t *g, struct iovec *iov, int niov)
{
    if (g->data) {
        size_t have = g->len < DATAGRAM_MAX ? g->len : DATAGRAM_MAX, at = 0;
        for (int i = 0; i < niov && at < have; i++) {
            size_t n = have - at < iov[i].iov_len ? have - at : iov[i].iov_len;
            memcpy(iov[i].iov_base, g->data + at, n);
            at += n;
        }
        return have == g->len;
    }
    uint8_t none;
    struct iovec discard = {&none, 1};
    arrival_ctl_t ctl;
    struct msghdr msg = {.msg_iov = niov ? iov : &discard, .msg_iovlen = niov ? (size_t)niov : 1,
                         .msg_control = ctl.space, .msg_controllen = sizeof ctl.space};
    ssize_t n;
    do
        n = recvmsg(b->fd, &msg, MSG_DONTWAIT | MSG_TRUNC);
    while (n < 0 && errno == EINTR);
    arrival(b, g, &msg);
    return n == (ssize_t)g->len;
}

/* The next datagram: peeked (its head), or read whole into buf (DATAGRAM_MAX bytes). The
 * datagram's length, or -1 with errno. */
static ssize_t next_datagram(bus_t *b, datagram_t *g, uint8_t *buf)
{
    struct iovec iov = buf ? (struct iovec){buf, DATAGRAM_MAX} : (struct iovec){g->head, sizeof g->head};
    arrival_ctl_t ctl;
    struct msghdr msg = {.msg_name = &g->from, .msg_namelen = sizeof g->from, .msg_iov = &iov, .msg_iovlen = 1};
    if (buf) {
        msg.msg_control = ctl.space;
        msg.msg_controllen = sizeof ctl.space;
    }
    ssize_t n = recvmsg(b->fd, &msg, (buf ? 0 : MSG_PEEK) | MSG_DONTWAIT | MSG_TRUNC);
    if (n < 0)
        return -1;
    g->len = (size_t)n;
    g->seen = g->len < sizeof g->head ? g->len : sizeof g->head;
    g->data = NULL;
    if (buf) {
        memcpy(g->head, buf, g->seen);
        g->data = buf;
        arrival(b, g, &msg);
    }
    return n;
}

static void drop_malformed(bus_t *b, datagram_t *g)
{
    b->st.malformed++;
    take(b, g, NULL, 0);
}

/* A buffer for a large message: the spare when it is large enough. Images at 30 Hz would
 * otherwise map, fault in and unmap a megabyte per message. */
static uint8_t *buffer(bus_t *b, size_t size, size_t *cap)
{
    if (b->spare && b->spare_cap >= size) {
        uint8_t *p = b->spare;
        *cap = b->spare_cap;
        b->spare = NULL;
        return p;
    }
    *cap = size ? size : 1;
    return malloc(*cap);
}

/* Keeps the larger of the spare and p (at most SPARE_MAX bytes), frees the other. */
static void give_back(bus_t *b, uint8_t *p, size_t cap)
{
    if (cap > SPARE_MAX || (b->spare && b->spare_cap >= cap)) {
        free(p);
        return;
    }
    free(b->spare);
    b->spare = p;
    b->spare_cap = cap;
}

/* The fragments, in their order, cover the message from its first byte to its last once each. */
static bool contiguous(const frag_t *f)
{
    uint64_t at = 0;
    for (uint32_t i = 0; i < f->nfrags; i++) {
        if (f->span[2 * i] != at)
            return false;
        at += f->span[2 * i + 1] - 1;
    }
    return at == f->size;
}

/* One LC03 fragment; returns 1 when it completed a message (then dispatched). */
static int on_fragment(bus_t *b, datagram_t *g)
{
    const uint8_t *d = g->head;
    uint32_t seqno = be32(d + 4), size = be32(d + 8), offset = be32(d + 12);
    uint16_t no = be16(d + 16), count = be16(d + 18);
    size_t len = g->len - LONG_HDR, cl = 0;
    const char *ch = NULL;
    if (no == 0 && (!(ch = channel_at(d + LONG_HDR, g->seen - LONG_HDR)) || offset != 0)) {
        drop_malformed(b, g);
        return 0;
    }
    if (ch) {
        cl = strlen(ch) + 1;
        len -= cl;
    }
    if (count == 0 || no >= count || size > FRAG_MAX_BYTES || (uint64_t)offset + len > size) {
        drop_malformed(b, g);
        return 0;
    }
    frag_t *f = frag_slot(b, &g->from);
    if (f->used && (f->seqno != seqno || f->size != size || f->nfrags != count)) {
        if (!f->ignore)
            b->st.incomplete++;     /* the sender moved on: what it sent before is lost */
        frag_drop(f);
    }
    bool unwanted = ch && !wanted(b, ch);  /* nobody listens: counted whole, never copied */
    if (!f->used) {
        f->used = true;
        f->from = g->from;
        f->seqno = seqno;
        f->size = size;
        f->nfrags = count;
        if (!(f->span = calloc(2 * (size_t)count, sizeof *f->span)) || (!unwanted && !(f->data = buffer(b, size, &f->cap)))) {
            frag_drop(f);
            take(b, g, NULL, 0);
            return 0;
        }
    }
    f->touched = ++b->clock;
    if (ch)
        memcpy(f->channel, ch, cl);
    if (unwanted) {
        f->ignore = true;
        free(f->data);
        f->data = NULL;
    }
    uint8_t hdr[LONG_HDR + LCM_MAX_CHANNEL_NAME_LENGTH + 1];
    struct iovec iov[2] = {{hdr, LONG_HDR + cl}, {f->data ? f->data + offset : NULL, len}};
    bool dup = f->span[2 * no + 1] != 0;
    if (!take(b, g, iov, f->data && !dup ? 2 : 0)) {
        b->st.malformed++;          /* the datagram changed under the peek: cannot be */
        frag_drop(f);
        return 0;
    }
    if (dup)
        return 0;
    f->span[2 * no] = offset;
    f->span[2 * no + 1] = (uint32_t)len + 1;
    if (++f->got < f->nfrags)
        return 0;
    if (!contiguous(f)) {
        b->st.malformed++;              /* every fragment came, and yet they overlap or leave a hole */
    } else if (f->ignore) {
        b->st.messages++;
    } else {
        char channel[sizeof f->channel];
        memcpy(channel, f->channel, sizeof channel);
        uint8_t *data = f->data;
        size_t cap = f->cap;
        f->data = NULL;
        frag_drop(f);                   /* before the handlers: they may read the bus again */
        dispatch(b, channel, data, size, g->utime);
        give_back(b, data, cap);
        return 1;
    }
    frag_drop(f);
    return 0;
}

/* One LC02 message: read whole into buf when someone subscribes to it. */
static int on_short(bus_t *b, datagram_t *g, uint8_t *buf)
{
    const char *ch = channel_at(g->head + SHORT_HDR, g->seen - SHORT_HDR);
    if (!ch) {
        drop_malformed(b, g);
        return 0;
    }
    if (!wanted(b, ch)) {
        b->st.messages++;
        take(b, g, NULL, 0);
        return 0;
    }
    struct iovec iov = {buf, DATAGRAM_MAX};
    if (!g->data && !take(b, g, &iov, 1)) {
        b->st.malformed++;
        return 0;
    }
    size_t cl = strlen((const char *)buf + SHORT_HDR) + 1;
    dispatch(b, (const char *)buf + SHORT_HDR, buf + SHORT_HDR + cl, (uint32_t)(g->len - SHORT_HDR - cl), g->utime);
    return 1;
}

int marie_lcm_fd(lcm_t *lcm)
{
    const bus_t *b = find(lcm);
    return b && b->fd >= 0 ? b->fd : lcm_get_fileno(lcm);
}

int marie_lcm_handle(lcm_t *lcm, int max)
{
    bus_t *b = find(lcm);
    if (!b || b->fd < 0) {
        int n = lcm_handle(lcm) == 0;    /* the pipe was readable: this does not block */
        while (n < max && lcm_handle_timeout(lcm, 0) > 0)
            n++;
        return n;
    }
    /* A handler that reads the bus again (a nested loop waiting for a reply) gets a buffer of
     * its own: the outer message is still being delivered from b->buf. */
    uint8_t *buf = b->depth == 0 ? b->buf : malloc(DATAGRAM_MAX);
    if (!buf)
        return 0;
    int handled = 0;
    /* A datagram is read whole after a short message someone here took (a flood of them costs
     * one system call each); after anything else it is peeked first. */
    for (int i = 0; i < DATAGRAMS_PER_CALL && handled < max; i++) {
        datagram_t g;
        if (next_datagram(b, &g, b->peek ? NULL : buf) < 0) {
            if (errno == EINTR)
                continue;
            if (errno != EAGAIN && errno != EWOULDBLOCK)
                marie_warn_ratelimited(10, "reading the LCM bus: %s", strerror(errno));
            break;
        }
        uint32_t magic = g.seen >= 4 ? be32(g.head) : 0;
        b->peek = true;
        if (magic == MAGIC_SHORT && g.len >= SHORT_HDR && g.len <= DATAGRAM_MAX) {
            int taken = on_short(b, &g, buf);
            handled += taken;
            b->peek = !taken;
        } else if (magic == MAGIC_LONG && g.len >= LONG_HDR) {
            handled += on_fragment(b, &g);
        } else {
            drop_malformed(b, &g);
        }
    }
    if (buf != b->buf)
        free(buf);
    return handled;
}

/* ---- sending ---- */

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v >> 24), p[1] = (uint8_t)(v >> 16), p[2] = (uint8_t)(v >> 8), p[3] = (uint8_t)v;
}

/* A message that goes in one LC02 datagram: its channel, the channel's NUL and payload take at
 * most SHORT_MAX bytes. */
static bool one_datagram(const marie_lcm_msg_t *m)
{
    size_t n = m->channel ? strlen(m->channel) : SIZE_MAX;
    return n <= LCM_MAX_CHANNEL_NAME_LENGTH && (m->data || !m->len) && n + 1 + (uint64_t)m->len <= SHORT_MAX;
}

/* LC02 datagrams (header, channel and its NUL, payload) for m[0..k), one sequence number each,
 * handed to the kernel by sendmmsg; rc[i] for each. Returns how many were sent. */
static int send_shorts(bus_t *b, const marie_lcm_msg_t *m, int k, int *rc)
{
    uint8_t hdr[FRAGS_PER_CALL][SHORT_HDR];
    struct iovec iov[FRAGS_PER_CALL][3];
    struct mmsghdr mm[FRAGS_PER_CALL];
    int sent = 0;
    pthread_mutex_lock(&b->tx_lock);
    for (int i = 0; i < k; i++) {
        put32(hdr[i], MAGIC_SHORT);
        put32(hdr[i] + 4, b->tx_seqno++);
        iov[i][0] = (struct iovec){hdr[i], SHORT_HDR};
        iov[i][1] = (struct iovec){(void *)m[i].channel, strlen(m[i].channel) + 1};
        iov[i][2] = (struct iovec){(void *)m[i].data, m[i].len};
        mm[i] = (struct mmsghdr){.msg_hdr = {.msg_name = &b->tx_to, .msg_namelen = sizeof b->tx_to,
                                             .msg_iov = iov[i], .msg_iovlen = 3}};
    }
    for (int at = 0; at < k;) {
        int n = sendmmsg(b->tx_fd, mm + at, (unsigned)(k - at), 0);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0) {               /* this one is refused; the rest are tried */
            rc[at++] = -1;
            continue;
        }
        for (int j = 0; j < n; j++)
            rc[at + j] = 0;
        at += n;
        sent += n;
    }
    pthread_mutex_unlock(&b->tx_lock);
    return sent;
}

/* LC03 fragments, FRAGS_PER_CALL to a system call: the first carries the channel and as much of
 * the payload as fits beside it, the others FRAG_PAYLOAD bytes each, the last what is left. */
static int send_fragments(bus_t *b, const char *channel, size_t cl, const uint8_t *data, unsigned len, unsigned nfrags)
{
    uint8_t hdr[FRAGS_PER_CALL][LONG_HDR];
    struct iovec iov[FRAGS_PER_CALL][3];
    struct mmsghdr mm[FRAGS_PER_CALL];
    uint32_t offset = 0;
    for (unsigned first = 0; first < nfrags; first += FRAGS_PER_CALL) {
        unsigned k = nfrags - first < FRAGS_PER_CALL ? nfrags - first : FRAGS_PER_CALL;
        for (unsigned i = 0; i < k; i++) {
            unsigned no = first + i;
            size_t room = no == 0 ? FRAG_PAYLOAD - cl : FRAG_PAYLOAD;
            size_t n = len - offset < room ? len - offset : room;
            uint8_t *h = hdr[i];
            put32(h, MAGIC_LONG);
            put32(h + 4, b->tx_seqno);
            put32(h + 8, len);
            put32(h + 12, offset);
            h[16] = (uint8_t)(no >> 8), h[17] = (uint8_t)no;
            h[18] = (uint8_t)(nfrags >> 8), h[19] = (uint8_t)nfrags;
            int niov = 0;
            iov[i][niov++] = (struct iovec){h, LONG_HDR};
            if (no == 0)
                iov[i][niov++] = (struct iovec){(void *)channel, cl};
            iov[i][niov++] = (struct iovec){(void *)(data + offset), n};
            mm[i] = (struct mmsghdr){.msg_hdr = {.msg_name = &b->tx_to, .msg_namelen = sizeof b->tx_to,
                                                 .msg_iov = iov[i], .msg_iovlen = (size_t)niov}};
            offset += (uint32_t)n;
        }
        for (unsigned sent = 0; sent < k;) {
            int n = sendmmsg(b->tx_fd, mm + sent, k - sent, 0);
            if (n < 0 && errno == EINTR)
                continue;
            if (n <= 0)
                return -1;      /* the receivers give the message up, as they would a loss */
            sent += (unsigned)n;
        }
    }
    return 0;
}

int marie_lcm_publish(lcm_t *lcm, const char *channel, const void *data, unsigned len)
{
    if (!lcm || !channel || (!data && len))
        return marie_fail(EINVAL);
    bus_t *b = find(lcm);
    if (!b || b->tx_fd < 0) {
        if (lcm_publish(lcm, channel, data, len) == 0)
            return 0;
        return marie_fail(EIO);
    }
    size_t cl = strlen(channel) + 1;
    if (cl > LCM_MAX_CHANNEL_NAME_LENGTH + 1)
        return marie_fail(EINVAL);
    uint64_t payload = cl + (uint64_t)len;
    uint64_t nfrags = (payload + FRAG_PAYLOAD - 1) / FRAG_PAYLOAD;
    if (payload > SHORT_MAX && nfrags > FRAGS_MAX)
        return marie_fail(EMSGSIZE);
    int rc;
    if (payload <= SHORT_MAX) {
        send_shorts(b, &(marie_lcm_msg_t){channel, data, len}, 1, &rc);
        return rc;
    }
    pthread_mutex_lock(&b->tx_lock);
    rc = send_fragments(b, channel, cl, data, len, (unsigned)nfrags);
    b->tx_seqno++;
    pthread_mutex_unlock(&b->tx_lock);
    return rc;
}

int marie_lcm_publish_batch(lcm_t *lcm, const marie_lcm_msg_t *m, int n, int *rc)
{
    bus_t *b = lcm ? find(lcm) : NULL;
    bool own = b && b->tx_fd >= 0;
    int sent = 0;
    for (int i = 0; i < n;) {
        int k = 0;
        while (own && i + k < n && k < FRAGS_PER_CALL && one_datagram(&m[i + k]))
            k++;
        if (k >= 2) {
            sent += send_shorts(b, m + i, k, rc + i);
            i += k;
            continue;
        }
        rc[i] = marie_lcm_publish(lcm, m[i].channel, m[i].data, m[i].len);
        sent += rc[i] == 0;
        i++;
    }
    return sent;
}

int marie_lcm_publish_msg(lcm_t *lcm, const char *channel, const marie_type_t *t, const void *msg)
{
    uint8_t small[2048];    /* heartbeats, events, replies: no allocation */
    int size = t->encoded_size(msg);
    if (size < 0)
        return marie_fail(EINVAL);
    uint8_t *buf = (size_t)size <= sizeof small ? small : malloc((size_t)size);
    if (!buf)
        return -1;
    int rc = t->encode(buf, 0, size, msg) == size ? marie_lcm_publish(lcm, channel, buf, (unsigned)size)
                                                  : marie_fail(EINVAL);
    if (buf != small)
        MARIE_KEEP_ERRNO(free(buf));
    return rc;
}

int marie_lcm_sends(const lcm_t *lcm)
{
    const bus_t *b = find(lcm);
    return b && b->tx_fd >= 0;
}
