/* udpm_recv: marie's reader of LCM's UDP multicast: a datagram peeked or read whole, and
 * fragments put together in place. */
#include "core/bus/udpm.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/time.h>

#include "core/log.h"
#include "core/time.h"

static void frag_drop(frag_t *f)
{
    free(f->data);
    free(f->span);
    memset(f, 0, sizeof *f);
}

uint32_t udpm_be32(const uint8_t *p) { return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]; }
static uint16_t be16(const uint8_t *p) { return (uint16_t)(p[0] << 8 | p[1]); }

static frag_t *frag_slot(udpm_t *u, const struct sockaddr_in *from)
{
    frag_t *free_slot = NULL, *oldest = NULL;
    for (int i = 0; i < FRAG_SLOTS; i++) {
        frag_t *f = &u->frags[i];
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
        u->st.incomplete++;
    frag_drop(oldest);
    return oldest;
}

typedef union {
    char space[CMSG_SPACE(sizeof(struct timeval)) + CMSG_SPACE(sizeof(uint32_t))];
    struct cmsghdr align;
} arrival_ctl_t;

/* The datagram's time of arrival and the kernel's drop count, from what recvmsg gave with it. */
static void arrival(udpm_t *u, datagram_t *g, struct msghdr *msg)
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
            if (total != u->ovfl && !u->filtered) {
                u->st.dropped += (uint32_t)(total - u->ovfl);
                marie_warn_ratelimited(10, "the LCM bus's receive buffer overflowed: %lld datagrams lost so far",
                                       (long long)u->st.dropped);
            }
            u->ovfl = total;
        }
    }
    if (!g->utime)
        g->utime = marie_wall_us();
}

/* Takes the datagram from the socket into the iov (none: dropped), with its time of arrival and
 * the kernel's drop count; false when the socket gave something else than was peeked. A datagram
 * read whole is copied from where it was read. */
bool udpm_take(udpm_t *u, datagram_t *g, struct iovec *iov, int niov)
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
        n = recvmsg(u->fd, &msg, MSG_DONTWAIT | MSG_TRUNC);
    while (n < 0 && errno == EINTR);
    arrival(u, g, &msg);
    return n == (ssize_t)g->len;
}

/* The next datagram: peeked (its head), or read whole into buf (DATAGRAM_MAX bytes). The
 * datagram's length, or -1 with errno. */
ssize_t udpm_next_datagram(udpm_t *u, datagram_t *g, uint8_t *buf)
{
    struct iovec iov = buf ? (struct iovec){buf, DATAGRAM_MAX} : (struct iovec){g->head, sizeof g->head};
    arrival_ctl_t ctl;
    struct msghdr msg = {.msg_name = &g->from, .msg_namelen = sizeof g->from, .msg_iov = &iov, .msg_iovlen = 1};
    if (buf) {
        msg.msg_control = ctl.space;
        msg.msg_controllen = sizeof ctl.space;
    }
    ssize_t n = recvmsg(u->fd, &msg, (buf ? 0 : MSG_PEEK) | MSG_DONTWAIT | MSG_TRUNC);
    if (n < 0)
        return -1;
    g->len = (size_t)n;
    g->seen = g->len < sizeof g->head ? g->len : sizeof g->head;
    g->data = NULL;
    if (buf) {
        memcpy(g->head, buf, g->seen);
        g->data = buf;
        arrival(u, g, &msg);
    }
    return n;
}

void udpm_drop_malformed(udpm_t *u, datagram_t *g)
{
    u->st.malformed++;
    udpm_take(u, g, NULL, 0);
}

/* A buffer for a large message: the spare when it is large enough. Images at 30 Hz would
 * otherwise map, fault in and unmap a megabyte per message. */
static uint8_t *buffer(udpm_t *u, size_t size, size_t *cap)
{
    if (u->spare && u->spare_cap >= size) {
        uint8_t *p = u->spare;
        *cap = u->spare_cap;
        u->spare = NULL;
        return p;
    }
    *cap = size ? size : 1;
    return malloc(*cap);
}

/* Keeps the larger of the spare and p (at most SPARE_MAX bytes), frees the other. */
static void give_back(udpm_t *u, uint8_t *p, size_t cap)
{
    if (cap > SPARE_MAX || (u->spare && u->spare_cap >= cap)) {
        free(p);
        return;
    }
    free(u->spare);
    u->spare = p;
    u->spare_cap = cap;
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
int udpm_on_fragment(udpm_t *u, datagram_t *g)
{
    const uint8_t *d = g->head;
    uint32_t seqno = udpm_be32(d + 4), size = udpm_be32(d + 8), offset = udpm_be32(d + 12);
    uint16_t no = be16(d + 16), count = be16(d + 18);
    size_t len = g->len - LONG_HDR, cl = 0;
    const char *ch = NULL;
    if (no == 0 && (!(ch = udpm_channel_at(d + LONG_HDR, g->seen - LONG_HDR)) || offset != 0)) {
        udpm_drop_malformed(u, g);
        return 0;
    }
    if (ch) {
        cl = strlen(ch) + 1;
        len -= cl;
    }
    if (count == 0 || no >= count || size > FRAG_MAX_BYTES || (uint64_t)offset + len > size) {
        udpm_drop_malformed(u, g);
        return 0;
    }
    frag_t *f = frag_slot(u, &g->from);
    if (f->used && (f->seqno != seqno || f->size != size || f->nfrags != count)) {
        if (!f->ignore)
            u->st.incomplete++;     /* the sender moved on: what it sent before is lost */
        frag_drop(f);
    }
    bool unwanted = ch && !udpm_wanted(u, ch);  /* nobody listens: counted whole, never copied */
    if (!f->used) {
        f->used = true;
        f->from = g->from;
        f->seqno = seqno;
        f->size = size;
        f->nfrags = count;
        if (!(f->span = calloc(2 * (size_t)count, sizeof *f->span)) || (!unwanted && !(f->data = buffer(u, size, &f->cap)))) {
            frag_drop(f);
            udpm_take(u, g, NULL, 0);
            return 0;
        }
    }
    f->touched = ++u->clock;
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
    if (!udpm_take(u, g, iov, f->data && !dup ? 2 : 0)) {
        u->st.malformed++;          /* the datagram changed under the peek: cannot be */
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
        u->st.malformed++;              /* every fragment came, and yet they overlap or leave a hole */
    } else if (f->ignore) {
        u->st.messages++;
    } else {
        char channel[sizeof f->channel];
        memcpy(channel, f->channel, sizeof channel);
        uint8_t *data = f->data;
        size_t cap = f->cap;
        f->data = NULL;
        frag_drop(f);                   /* before the handlers: they may read the bus again */
        udpm_dispatch(u, channel, data, size, g->utime);
        give_back(u, data, cap);
        return 1;
    }
    frag_drop(f);
    return 0;
}


void udpm_frags_free(udpm_t *u)
{
    for (int i = 0; i < FRAG_SLOTS; i++)
        frag_drop(&u->frags[i]);
}
