/* udpm_send: marie's sender of LCM's UDP multicast, in liblcm 1.3.1's format and with its rules:
 * one LC02 datagram, or LC03 fragments handed to the kernel 64 at a time. */
#include "core/bus/udpm.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)(v >> 24), p[1] = (uint8_t)(v >> 16), p[2] = (uint8_t)(v >> 8), p[3] = (uint8_t)v;
}

/* A message that goes in one LC02 datagram: its channel, the channel's NUL and payload take at
 * most SHORT_MAX bytes. */
static bool one_datagram(const marie_bus_msg_t *m)
{
    size_t n = m->channel ? strlen(m->channel) : SIZE_MAX;
    return n <= LCM_MAX_CHANNEL_NAME_LENGTH && (m->data || !m->len) && n + 1 + (uint64_t)m->len <= SHORT_MAX;
}

/* LC02 datagrams (header, channel and its NUL, payload) for m[0..k), one sequence number each,
 * handed to the kernel by sendmmsg; rc[i] for each. Returns how many were sent. */
static int send_shorts(udpm_t *u, const marie_bus_msg_t *m, int k, int *rc)
{
    uint8_t hdr[FRAGS_PER_CALL][SHORT_HDR];
    struct iovec iov[FRAGS_PER_CALL][3];
    struct mmsghdr mm[FRAGS_PER_CALL];
    int sent = 0;
    pthread_mutex_lock(&u->tx_lock);
    for (int i = 0; i < k; i++) {
        put32(hdr[i], MAGIC_SHORT);
        put32(hdr[i] + 4, u->tx_seqno++);
        iov[i][0] = (struct iovec){hdr[i], SHORT_HDR};
        iov[i][1] = (struct iovec){(void *)m[i].channel, strlen(m[i].channel) + 1};
        iov[i][2] = (struct iovec){(void *)m[i].data, m[i].len};
        mm[i] = (struct mmsghdr){.msg_hdr = {.msg_name = &u->tx_to, .msg_namelen = sizeof u->tx_to,
                                             .msg_iov = iov[i], .msg_iovlen = 3}};
    }
    for (int at = 0; at < k;) {
        int n = sendmmsg(u->tx_fd, mm + at, (unsigned)(k - at), 0);
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
    pthread_mutex_unlock(&u->tx_lock);
    return sent;
}

/* LC03 fragments, FRAGS_PER_CALL to a system call: the first carries the channel and as much of
 * the payload as fits beside it, the others FRAG_PAYLOAD bytes each, the last what is left. */
static int send_fragments(udpm_t *u, const char *channel, size_t cl, const uint8_t *data, unsigned len, unsigned nfrags)
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
            put32(h + 4, u->tx_seqno);
            put32(h + 8, len);
            put32(h + 12, offset);
            h[16] = (uint8_t)(no >> 8), h[17] = (uint8_t)no;
            h[18] = (uint8_t)(nfrags >> 8), h[19] = (uint8_t)nfrags;
            int niov = 0;
            iov[i][niov++] = (struct iovec){h, LONG_HDR};
            if (no == 0)
                iov[i][niov++] = (struct iovec){(void *)channel, cl};
            iov[i][niov++] = (struct iovec){(void *)(data + offset), n};
            mm[i] = (struct mmsghdr){.msg_hdr = {.msg_name = &u->tx_to, .msg_namelen = sizeof u->tx_to,
                                                 .msg_iov = iov[i], .msg_iovlen = (size_t)niov}};
            offset += (uint32_t)n;
        }
        for (unsigned sent = 0; sent < k;) {
            int n = sendmmsg(u->tx_fd, mm + sent, k - sent, 0);
            if (n < 0 && errno == EINTR)
                continue;
            if (n <= 0)
                return -1;      /* the receivers give the message up, as they would a loss */
            sent += (unsigned)n;
        }
    }
    return 0;
}

int udpm_publish(void *st, const char *channel, const void *data, size_t len)
{
    udpm_t *u = st;
    if (len > UINT32_MAX)
        return marie_fail(EMSGSIZE);
    if (u->tx_fd < 0)       /* MARIE_LCM_SEND=liblcm, or a TTL marie does not send with */
        return marie_liblcm()->publish(u->tx_lcm, channel, data, (unsigned)len) == 0 ? 0 : marie_fail(EIO);
    size_t cl = strlen(channel) + 1;
    if (cl > LCM_MAX_CHANNEL_NAME_LENGTH + 1)
        return marie_fail(EINVAL);
    uint64_t payload = cl + (uint64_t)len;
    uint64_t nfrags = (payload + FRAG_PAYLOAD - 1) / FRAG_PAYLOAD;
    if (payload > SHORT_MAX && nfrags > FRAGS_MAX)
        return marie_fail(EMSGSIZE);
    int rc;
    if (payload <= SHORT_MAX) {
        send_shorts(u, &(marie_bus_msg_t){channel, data, (unsigned)len}, 1, &rc);
        return rc;
    }
    pthread_mutex_lock(&u->tx_lock);
    rc = send_fragments(u, channel, cl, data, (unsigned)len, (unsigned)nfrags);
    u->tx_seqno++;
    pthread_mutex_unlock(&u->tx_lock);
    return rc;
}

int udpm_publish_batch(void *st, const marie_bus_msg_t *m, int n, int *rc)
{
    udpm_t *u = st;
    int sent = 0;
    for (int i = 0; i < n;) {
        int k = 0;
        while (u->tx_fd >= 0 && i + k < n && k < FRAGS_PER_CALL && one_datagram(&m[i + k]))
            k++;
        if (k >= 2) {
            sent += send_shorts(u, m + i, k, rc + i);
            i += k;
            continue;
        }
        rc[i] = m[i].channel ? udpm_publish(u, m[i].channel, m[i].data, m[i].len) : marie_fail(EINVAL);
        sent += rc[i] == 0;
        i++;
    }
    return sent;
}
