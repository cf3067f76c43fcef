/* udpm: the provider of udpm:// buses: marie reads LCM's UDP multicast itself, on the loop's
 * thread (liblcm's receive thread and its pipe cost two wake-ups per message), and sends it. */
#include "core/bus/udpm.h"

#include <arpa/inet.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/err.h"
#include "core/log.h"

#define RECV_BUF_DEFAULT (2 << 20)  /* bytes of kernel buffer when the URL names none */
/* Datagrams read per call at most, whole messages or not (fragments, strangers' garbage). */
#define DATAGRAMS_PER_CALL 256

typedef struct {
    struct in_addr group;
    uint16_t port;
    int rcvbuf;
    int ttl;                /* -1: not one liblcm would read the same (left to liblcm) */
} url_t;

/* "udpm://ADDR:PORT?opt=v&..." into u; false when marie should leave the bus to liblcm (another
 * provider, transmit_only, not understood). */
static bool parse_url(const char *url, url_t *u)
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
static int open_sender(const url_t *u)
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

static void udpm_close(void *st);

/* liblcm sends for marie: on the bus's own handle when liblcm made it (its sequence numbers go
 * on from the program's own sends), else on an instance of its own, loaded now. */
static int open_liblcm_sender(udpm_t *u, const char *url)
{
    if (marie_bus_handle_is_liblcm(u->lcm)) {
        u->tx_lcm = u->lcm;
        return 0;
    }
    const marie_liblcm_t *l = marie_liblcm();
    if (!l || !(u->tx_lcm = l->create(url)))
        return -1;
    u->tx_lcm_own = true;
    return 0;
}

/* A udpm:// URL that marie reads the same as liblcm; anything else (and every bus when
 * MARIE_LCM_RECEIVE=liblcm is set) is left to liblcm: EPROTONOSUPPORT. */
static void *udpm_open(lcm_t *lcm, const char *url)
{
    url_t a;
    if (env_is("MARIE_LCM_RECEIVE", "liblcm") || !parse_url(url, &a))
        return marie_fail_null(EPROTONOSUPPORT);
    udpm_t *u = calloc(1, sizeof *u);
    if (!u)
        return NULL;
    u->lcm = lcm;
    u->tx_fd = -1;
    pthread_mutex_init(&u->tx_lock, NULL);
    if ((u->fd = open_socket(a.group, a.port, a.rcvbuf)) < 0 || !(u->buf = malloc(DATAGRAM_MAX))) {
        /* liblcm will say what is wrong when it is asked to read */
        marie_warn("%s: marie cannot read this bus itself (%s); liblcm reads it", url, strerror(errno));
        if (u->fd >= 0)
            close(u->fd);
        pthread_mutex_destroy(&u->tx_lock);
        free(u);
        return marie_fail_null(EPROTONOSUPPORT);
    }
    udpm_refilter(u);       /* nothing subscribed yet: no short message is read */
    /* Sent by marie with a TTL liblcm would read the same. */
    if (a.ttl >= 0 && !env_is("MARIE_LCM_SEND", "liblcm")) {
        u->tx_to = (struct sockaddr_in){.sin_family = AF_INET, .sin_port = htons(a.port), .sin_addr = a.group};
        if ((u->tx_fd = open_sender(&a)) < 0)
            marie_warn("%s: marie cannot send on this bus itself (%s); liblcm sends", url, strerror(errno));
    }
    if (u->tx_fd < 0 && open_liblcm_sender(u, url) < 0) {
        udpm_close(u);
        return marie_fail_null(EIO);
    }
    return u;
}

static void sub_free(udpm_sub_t *s)
{
    if (!s->literal)
        regfree(&s->re);
    free(s->channel);
    free(s);
}

static void udpm_close(void *st)
{
    udpm_t *u = st;
    while (u->subs) {
        udpm_sub_t *n = u->subs->next;
        sub_free(u->subs);
        u->subs = n;
    }
    udpm_frags_free(u);
    close(u->fd);
    if (u->tx_fd >= 0)
        close(u->tx_fd);
    if (u->tx_lcm_own)
        marie_liblcm()->destroy(u->tx_lcm);
    pthread_mutex_destroy(&u->tx_lock);
    free(u->buf);
    free(u->spare);
    free(u);
}

static void *udpm_subscribe(void *st, const char *channel, const marie_bus_recv_t *rv)
{
    udpm_t *u = st;
    udpm_sub_t *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->rv = *rv;
    udpm_literal_prefix(channel, &s->literal);  /* a plain name is compared as a string */
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
    udpm_sub_t **pp = &u->subs;     /* in subscription order, as liblcm calls them */
    while (*pp)
        pp = &(*pp)->next;
    *pp = s;
    udpm_refilter(u);
    return s;
}

static void sweep_removed(udpm_t *u)
{
    for (udpm_sub_t **pp = &u->subs; *pp;) {
        udpm_sub_t *s = *pp;
        if (s->removed) {
            *pp = s->next;
            sub_free(s);
        } else {
            pp = &s->next;
        }
    }
    u->any_removed = false;
}

static void udpm_unsubscribe(void *st, void *sub)
{
    udpm_t *u = st;
    udpm_sub_t *s = sub;
    s->removed = true;
    u->any_removed = true;
    udpm_refilter(u);
    if (u->depth == 0)
        sweep_removed(u);
}

static bool matches(const udpm_sub_t *s, const char *channel)
{
    return s->literal ? strcmp(s->channel, channel) == 0 : regexec(&s->re, channel, 0, NULL, 0) == 0;
}

bool udpm_wanted(const udpm_t *u, const char *channel)
{
    for (const udpm_sub_t *s = u->subs; s; s = s->next)
        if (!s->removed && matches(s, channel))
            return true;
    return false;
}

void udpm_dispatch(udpm_t *u, const char *channel, void *data, uint32_t size, int64_t utime)
{
    u->st.messages++;
    lcm_recv_buf_t rb = {data, size, utime, u->lcm};
    u->depth++;
    for (udpm_sub_t *s = u->subs; s; s = s->next)
        if (!s->removed && matches(s, channel)) {
            s->rv.handler(&rb, channel, s->rv.user);
            if (s->rv.verdict)
                s->rv.verdict(true, s->rv.user);    /* the bytes are the reader's own */
        }
    if (--u->depth == 0 && u->any_removed)
        sweep_removed(u);
}

/* The channel at p (at most n bytes, NUL included), or NULL when there is none. */
const char *udpm_channel_at(const uint8_t *p, size_t n)
{
    const uint8_t *nul = memchr(p, '\0', n < LCM_MAX_CHANNEL_NAME_LENGTH + 1 ? n : LCM_MAX_CHANNEL_NAME_LENGTH + 1);
    return nul && nul > p ? (const char *)p : NULL;
}

/* One LC02 message: read whole into buf when someone subscribes to it. */
static int on_short(udpm_t *u, datagram_t *g, uint8_t *buf)
{
    const char *ch = udpm_channel_at(g->head + SHORT_HDR, g->seen - SHORT_HDR);
    if (!ch) {
        udpm_drop_malformed(u, g);
        return 0;
    }
    if (!udpm_wanted(u, ch)) {
        u->st.messages++;
        udpm_take(u, g, NULL, 0);
        return 0;
    }
    struct iovec iov = {buf, DATAGRAM_MAX};
    if (!g->data && !udpm_take(u, g, &iov, 1)) {
        u->st.malformed++;
        return 0;
    }
    size_t cl = strlen((const char *)buf + SHORT_HDR) + 1;
    udpm_dispatch(u, (const char *)buf + SHORT_HDR, buf + SHORT_HDR + cl, (uint32_t)(g->len - SHORT_HDR - cl), g->utime);
    return 1;
}

static int udpm_handle(void *st, int max)
{
    udpm_t *u = st;
    /* A handler that reads the bus again (a nested loop waiting for a reply) gets a buffer of
     * its own: the outer message is still being delivered from u->buf. */
    uint8_t *buf = u->depth == 0 ? u->buf : malloc(DATAGRAM_MAX);
    if (!buf)
        return 0;
    int handled = 0;
    /* A datagram is read whole after a short message someone here took (a flood of them costs
     * one system call each); after anything else it is peeked first. */
    for (int i = 0; i < DATAGRAMS_PER_CALL && handled < max; i++) {
        datagram_t g;
        if (udpm_next_datagram(u, &g, u->peek ? NULL : buf) < 0) {
            if (errno == EINTR)
                continue;
            if (errno != EAGAIN && errno != EWOULDBLOCK)
                marie_warn_ratelimited(10, "reading the LCM bus: %s", strerror(errno));
            break;
        }
        uint32_t magic = g.seen >= 4 ? udpm_be32(g.head) : 0;
        u->peek = true;
        if (magic == MAGIC_SHORT && g.len >= SHORT_HDR && g.len <= DATAGRAM_MAX) {
            int taken = on_short(u, &g, buf);
            handled += taken;
            u->peek = !taken;
        } else if (magic == MAGIC_LONG && g.len >= LONG_HDR) {
            handled += udpm_on_fragment(u, &g);
        } else {
            udpm_drop_malformed(u, &g);
        }
    }
    if (buf != u->buf)
        free(buf);
    return handled;
}

static int udpm_fd(void *st) { return ((udpm_t *)st)->fd; }
static void udpm_stats(const void *st, marie_bus_stats_t *out) { *out = ((const udpm_t *)st)->st; }
static int udpm_sends(const void *st) { return ((const udpm_t *)st)->tx_fd >= 0; }

const marie_bus_provider_t marie_bus_udpm = {
    .name = "udpm",
    .open = udpm_open,
    .close = udpm_close,
    .subscribe = udpm_subscribe,
    .unsubscribe = udpm_unsubscribe,
    .publish = udpm_publish,
    .publish_batch = udpm_publish_batch,
    .fd = udpm_fd,
    .handle = udpm_handle,
    .stats = udpm_stats,
    .sends = udpm_sends,
};
