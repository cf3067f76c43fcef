/* xb_out: the XML bridge's outgoing side: shared documents, each client's bounded queue that
 * drops the oldest and tells the client so, and non-blocking writes. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/uio.h>

#include "adapters/xml_bridge/xb_server_int.h"
#include "core/clear.h"

msgbuf_t *xb_msgbuf_new(const char *data, size_t len)
{
    msgbuf_t *b = malloc(sizeof *b + len);
    if (!b)
        return NULL;
    b->refs = 1;
    b->len = len;
    memcpy(b->data, data, len);
    return b;
}

void xb_msgbuf_unref(msgbuf_t *b)
{
    if (b && --b->refs == 0)
        free(b);
}

/* ---- client output ---- */

void xb_client_set_out(client_t *c, int on)
{
    if (c->want_out == on || c->fd < 0)
        return;
    short events = (short)((c->closing_since ? 0 : POLLIN) | (on ? POLLOUT : 0));
    if (marie_loop_set_events(c->s->loop, c->fd, events) == 0)
        c->want_out = on;
}

static void count_drop(client_t *c)
{
    c->dropped_total++;
    c->s->st.dropped++;
    if (c->s->hooks.drop)
        c->s->hooks.drop(c->s->hooks.user, 1);
}

/* Writes a queued notice's text for what was lost since the last notice the client got. Done
 * when it is about to be sent, so later losses join it and a lost notice loses no count. */
static void render_notice(client_t *c, qent_t *e)
{
    uint64_t count = c->dropped_total - c->dropped_told;
    size_t len = 0;
    if (count > 0)
        len = (size_t)snprintf(e->b->data, NOTICE_MAX, "<dropped count=\"%llu\" total=\"%llu\"/>\n",
                               (unsigned long long)count, (unsigned long long)c->dropped_total);
    c->qbytes += len - e->b->len;       /* modular: a shorter text subtracts */
    e->b->len = len;
    e->told = c->dropped_total;
}

/* Drops the oldest queued document (never the one being written). */
static void drop_oldest(client_t *c)
{
    int cap = c->qcap;
    qent_t e = c->q[c->qhead];
    c->qhead = (c->qhead + 1) % cap;
    c->qlen--;
    c->qbytes -= e.b->len;
    if (e.notice)
        c->notices--;           /* nothing lost: the next notice states the same losses */
    else
        count_drop(c);
    xb_msgbuf_unref(e.b);
}

static int push_entry(client_t *c, msgbuf_t *b, int notice)
{
    if (c->qlen >= c->qcap) {
        /* An idle client holds a small ring; it grows only when documents pile up. */
        int max = c->s->cfg.queue + 2, ncap = c->qcap ? c->qcap * 2 : 8;
        if (c->qlen >= max)
            return -1;
        if (ncap > max)
            ncap = max;
        qent_t *nq = malloc((size_t)ncap * sizeof *nq);
        if (!nq)
            return -1;
        for (int i = 0; i < c->qlen; i++)
            nq[i] = c->q[(c->qhead + i) % c->qcap];
        free(c->q);
        c->q = nq;
        c->qhead = 0;
        c->qcap = ncap;
    }
    int cap = c->qcap;
    c->q[(c->qhead + c->qlen) % cap] = (qent_t){ b, notice, 0 };
    c->qlen++;
    c->qbytes += b->len;
    b->refs++;
    xb_client_set_out(c, 1);
    return 0;
}

/* Queues a document; a full queue loses its oldest documents, and the client is told how many
 * with a <dropped> notice ahead of the new document (one notice queued at a time: it counts
 * every loss up to when it is sent). */
void xb_client_enqueue(client_t *c, msgbuf_t *b)
{
    if (c->dead || c->fd < 0)
        return;
    xb_server_t *s = c->s;
#define XB_QUEUE_FULL (c->qlen > 0 && (c->qlen + 2 > s->cfg.queue || c->qbytes + b->len > (size_t)s->cfg.queue_bytes))
    if (XB_QUEUE_FULL)
        xb_client_flush(c);               /* only a client whose socket is full is slow */
    while (XB_QUEUE_FULL && !c->dead)
        drop_oldest(c);
#undef XB_QUEUE_FULL
    if (c->dropped_total > c->dropped_told && c->notices == 0) {
        msgbuf_t *nb = malloc(sizeof *nb + NOTICE_MAX);
        if (nb) {
            nb->refs = 1;
            nb->len = 0;
            if (push_entry(c, nb, 1) == 0)
                c->notices++;
            xb_msgbuf_unref(nb);
        }
    }
    if (push_entry(c, b, 0) < 0)
        count_drop(c);
}

void xb_client_enqueue_text(client_t *c, const char *data, size_t len)
{
    msgbuf_t *b = xb_msgbuf_new(data, len);
    if (!b) {
        c->dead = 1;
        return;
    }
    xb_client_enqueue(c, b);
    xb_msgbuf_unref(b);
}

void xb_client_flush(client_t *c)
{
    while (c->cur.b || c->qlen > 0) {
        struct iovec iov[64];
        int n = 0;
        if (c->cur.b) {
            iov[n].iov_base = c->cur.b->data + c->off;
            iov[n].iov_len = c->cur.b->len - c->off;
            n++;
        }
        for (int i = 0; i < c->qlen && n < 64; i++) {
            qent_t *e = &c->q[(c->qhead + i) % c->qcap];
            if (e->notice)
                render_notice(c, e);
            iov[n].iov_base = e->b->data;
            iov[n].iov_len = e->b->len;
            n++;
        }
        /* sendmsg with MSG_NOSIGNAL: a peer gone away is an error return, not SIGPIPE. */
        struct msghdr mh = { .msg_iov = iov, .msg_iovlen = (size_t)n };
        ssize_t w = sendmsg(c->fd, &mh, MSG_NOSIGNAL);
        if (w < 0) {
            if (errno == EINTR)
                continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK)
                return;
            c->dead = 1;
            return;
        }
        size_t left = (size_t)w;
        if (c->cur.b) {
            size_t rem = c->cur.b->len - c->off;
            if (left < rem) {
                c->off += left;
                continue;
            }
            left -= rem;
            MARIE_CLEAR(c->cur.b, xb_msgbuf_unref);
            c->off = 0;
        }
        while (c->qlen > 0 && (left > 0 || c->q[c->qhead].b->len == 0)) {
            qent_t e = c->q[c->qhead];
            c->qhead = (c->qhead + 1) % c->qcap;
            c->qlen--;
            c->qbytes -= e.b->len;
            if (e.notice) {
                c->notices--;
                c->dropped_told = e.told;
            }
            if (left < e.b->len) {
                c->cur = e;         /* partly written: it can no longer be dropped */
                c->off = left;
                break;
            }
            left -= e.b->len;
            xb_msgbuf_unref(e.b);
        }
    }
    xb_client_set_out(c, 0);
    if (c->closing_since)
        c->dead = 1;
}
