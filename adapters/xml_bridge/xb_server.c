/* xb_server: TCP clients speaking XML documents, bridged to LCM. Clients live in one epoll set
 * watched by the marie loop, so hundreds of them cost one fd in the loop and O(1) per event. */
#include "adapters/xml_bridge/xb_server.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/epoll.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include "adapters/xml_bridge/xb_codec.h"
#include "adapters/xml_bridge/xb_doc.h"
#include "core/typeinfo.h"
#include "core/log.h"
#include "core/time.h"

#define XB_PROTOCOL 1
#define CLOSE_GRACE_US 1000000      /* a closing client gets this long to take its last reply */

/* One outgoing document, shared by every client it goes to. */
typedef struct {
    int refs;
    size_t len;
    char data[];
} msgbuf_t;

typedef struct {
    msgbuf_t *b;
    int notice;                 /* a <dropped> notice, written out when it is sent */
    uint64_t told;              /* the total that notice states */
} qent_t;

#define NOTICE_MAX 96

typedef struct sub sub_t;
typedef struct client client_t;

typedef struct {
    sub_t *sub;
    int stream;                 /* deliver every message (else only keep the latest) */
} csub_t;

struct client {
    xb_server_t *s;
    int fd;
    xb_doc_parser_t *parser;
    client_t *prev, *next;
    qent_t *q;                  /* ring, grown on demand up to queue_docs + 2 entries */
    int qhead, qlen, qcap;
    size_t qbytes;              /* bytes in the ring */
    qent_t cur;                 /* the document being written, and how much of it is */
    size_t off;
    uint64_t dropped_total;     /* documents lost to this client */
    uint64_t dropped_told;      /* the total in the last notice written to it */
    int notices;                /* notices queued, not yet being written */
    csub_t *subs;
    int nsubs, capsubs;
    int64_t partial_since;      /* monotonic us when an unfinished document began, or 0 */
    size_t mem;                 /* parser memory charged to the budget */
    int64_t closing_since;      /* nonzero: close once the queue is written */
    int want_out;
    int dead;                   /* close at the next safe point */
};

struct sub {
    xb_server_t *s;
    char *channel;
    const marie_typeinfo_t *type;
    lcm_subscription_t *ls;
    client_t **clients;         /* subscribed clients; csub says whether they stream */
    int *stream;
    int nclients, capclients, nstream;
    char *latest;               /* newest raw payload */
    size_t latest_len;
    int64_t latest_utime;       /* wall clock at receipt */
    int has_latest;
    sub_t *next;
};

struct xb_server {
    xb_server_cfg_t cfg;
    char bind[64];
    lcm_t *lcm;
    marie_loop_t *loop;
    xb_server_hooks_t hooks;
    int lfd, efd, port;
    marie_timer_t *sweep;
    client_t *clients;
    sub_t *subs;
    xb_server_stats_t st;
    xb_buf_t out;               /* scratch for one outgoing document */
    xb_buf_t enc;               /* scratch for one encoded LCM payload */
};

void xb_server_cfg_defaults(xb_server_cfg_t *cfg)
{
    memset(cfg, 0, sizeof *cfg);
    cfg->bind = "127.0.0.1";
    cfg->port = 7670;
    cfg->max_doc_bytes = 1 << 20;
    cfg->max_depth = 32;
    cfg->queue_docs = 1024;
    cfg->queue_bytes = 8u << 20;
    cfg->max_clients = 512;
    cfg->stall_ms = 10000;
    cfg->max_message = 4u << 20;
    cfg->max_memory = 256u << 20;
}

static void bad_input(xb_server_t *s, const char *counter, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void bad_input(xb_server_t *s, const char *counter, const char *fmt, ...)
{
    char reason[320];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(reason, sizeof reason, fmt, ap);
    va_end(ap);
    if (s->hooks.bad_input)
        s->hooks.bad_input(s->hooks.user, counter, reason);
    else
        marie_warn_ratelimited(5, "xml bridge: %s: %s", counter, reason);
}

static msgbuf_t *msgbuf_new(const char *data, size_t len)
{
    msgbuf_t *b = malloc(sizeof *b + len);
    if (!b)
        return NULL;
    b->refs = 1;
    b->len = len;
    memcpy(b->data, data, len);
    return b;
}

static void msgbuf_unref(msgbuf_t *b)
{
    if (b && --b->refs == 0)
        free(b);
}

/* ---- client output ---- */

static void set_out(client_t *c, int on)
{
    if (c->want_out == on || c->fd < 0)
        return;
    struct epoll_event ev = { .events = (c->closing_since ? 0 : EPOLLIN) | (on ? EPOLLOUT : 0),
                              .data.ptr = c };
    if (epoll_ctl(c->s->efd, EPOLL_CTL_MOD, c->fd, &ev) == 0)
        c->want_out = on;
}

static void flush(client_t *c);

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
    msgbuf_unref(e.b);
}

static int push_entry(client_t *c, msgbuf_t *b, int notice)
{
    if (c->qlen >= c->qcap) {
        /* An idle client holds a small ring; it grows only when documents pile up. */
        int max = c->s->cfg.queue_docs + 2, ncap = c->qcap ? c->qcap * 2 : 8;
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
    set_out(c, 1);
    return 0;
}

/* Queues a document; a full queue loses its oldest documents, and the client is told how many
 * with a <dropped> notice ahead of the new document (one notice queued at a time: it counts
 * every loss up to when it is sent). */
static void enqueue(client_t *c, msgbuf_t *b)
{
    if (c->dead || c->fd < 0)
        return;
    xb_server_t *s = c->s;
#define XB_QUEUE_FULL (c->qlen > 0 && (c->qlen + 2 > s->cfg.queue_docs || c->qbytes + b->len > s->cfg.queue_bytes))
    if (XB_QUEUE_FULL)
        flush(c);               /* only a client whose socket is full is slow */
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
            msgbuf_unref(nb);
        }
    }
    if (push_entry(c, b, 0) < 0)
        count_drop(c);
}

static void enqueue_text(client_t *c, const char *data, size_t len)
{
    msgbuf_t *b = msgbuf_new(data, len);
    if (!b) {
        c->dead = 1;
        return;
    }
    enqueue(c, b);
    msgbuf_unref(b);
}

static void client_close(client_t *c);

static void flush(client_t *c)
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
            msgbuf_unref(c->cur.b);
            c->cur.b = NULL;
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
            msgbuf_unref(e.b);
        }
    }
    set_out(c, 0);
    if (c->closing_since)
        c->dead = 1;
}

/* ---- replies ---- */

static void put_attr(xb_buf_t *b, const char *name, const char *value)
{
    if (!value)
        return;
    xb_buf_printf(b, " %s=\"", name);
    xb_buf_escape(b, value, strlen(value));
    xb_buf_put(b, "\"", 1);
}

static void reply_error(client_t *c, const xb_node_t *req, const char *code, const char *reason)
{
    xb_server_t *s = c->s;
    xb_buf_t *b = &s->out;
    b->len = 0;
    xb_buf_puts(b, "<error");
    put_attr(b, "code", code);
    put_attr(b, "reason", reason);
    if (req) {
        put_attr(b, "to", req->name);
        put_attr(b, "id", xb_node_attr(req, "id"));
        put_attr(b, "channel", xb_node_attr(req, "channel"));
    }
    xb_buf_puts(b, "/>\n");
    s->st.errors++;
    enqueue_text(c, b->data, b->len);
}

static void reply_ok(client_t *c, const xb_node_t *req, const char *extra_name, const char *extra)
{
    xb_buf_t *b = &c->s->out;
    b->len = 0;
    xb_buf_puts(b, "<ok");
    put_attr(b, "to", req->name);
    put_attr(b, "id", xb_node_attr(req, "id"));
    put_attr(b, "channel", xb_node_attr(req, "channel"));
    put_attr(b, "type", xb_node_attr(req, "type"));
    put_attr(b, extra_name, extra);
    xb_buf_puts(b, "/>\n");
    enqueue_text(c, b->data, b->len);
}

/* Writes <message ...>fields</message> of a raw payload into s->out; -1 if it does not decode. */
static int format_message(xb_server_t *s, const sub_t *sub, const char *channel, const void *data,
                          size_t len, int64_t recv_utime, const xb_node_t *req, xb_error_t *err)
{
    xb_buf_t *b = &s->out;
    b->len = 0;
    b->full = 0;
    xb_buf_puts(b, "<message");
    put_attr(b, "channel", channel);
    put_attr(b, "type", sub->type->name);
    xb_buf_printf(b, " recv_utime=\"%lld\"", (long long)recv_utime);
    if (req) {
        put_attr(b, "to", req->name);
        put_attr(b, "id", xb_node_attr(req, "id"));
        xb_buf_printf(b, " age_us=\"%lld\"", (long long)(marie_wall_us() - recv_utime));
    }
    xb_buf_puts(b, ">");
    if (xb_decode(sub->type, data, len, b, err) < 0)
        return -1;
    if (xb_buf_puts(b, "</message>\n") < 0) {
        xb_error_set(err, "too-large", "message document over %zu bytes", b->max);
        return -1;
    }
    return 0;
}

/* ---- subscriptions ---- */

static void on_lcm(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    sub_t *sub = user;
    xb_server_t *s = sub->s;
    if (sub->nclients == 0)
        return;
    s->st.received++;
    if ((size_t)rbuf->data_size > s->cfg.max_message) {
        bad_input(s, "oversized_message", "%s: %u bytes over the limit", channel, rbuf->data_size);
        return;
    }
    char *copy = realloc(sub->latest, rbuf->data_size ? rbuf->data_size : 1);
    if (!copy)
        return;
    memcpy(copy, rbuf->data, rbuf->data_size);
    sub->latest = copy;
    sub->latest_len = rbuf->data_size;
    sub->latest_utime = rbuf->recv_utime;
    sub->has_latest = 1;
    if (sub->nstream == 0)
        return;
    xb_error_t err;
    if (format_message(s, sub, channel, rbuf->data, rbuf->data_size, rbuf->recv_utime, NULL, &err) < 0) {
        bad_input(s, "bad_lcm_message", "%s: %s", channel, err.reason);
        sub->has_latest = 0;
        xb_buf_t *b = &s->out;
        b->len = 0;
        xb_buf_puts(b, "<error");
        put_attr(b, "code", err.code);
        put_attr(b, "reason", err.reason);
        put_attr(b, "channel", channel);
        xb_buf_puts(b, "/>\n");
    }
    msgbuf_t *mb = msgbuf_new(s->out.data, s->out.len);
    if (!mb)
        return;
    for (int i = 0; i < sub->nclients; i++)
        if (sub->stream[i]) {
            enqueue(sub->clients[i], mb);
            s->st.delivered++;
        }
    msgbuf_unref(mb);
}

static sub_t *sub_find(xb_server_t *s, const char *channel, const marie_typeinfo_t *t)
{
    for (sub_t *u = s->subs; u; u = u->next)
        if (u->type == t && strcmp(u->channel, channel) == 0)
            return u;
    return NULL;
}

static sub_t *sub_get(xb_server_t *s, const char *channel, const marie_typeinfo_t *t)
{
    sub_t *u = sub_find(s, channel, t);
    if (u)
        return u;
    u = calloc(1, sizeof *u);
    if (!u || !(u->channel = strdup(channel)))
        goto fail;
    u->type = t;
    u->s = s;
    /* LCM matches channels as regular expressions; bridge channels are literal names. */
    char re[2 * LCM_MAX_CHANNEL_NAME_LENGTH + 2];
    size_t k = 0;
    for (const char *p = channel; *p; p++) {
        if (strchr(".[]()*+?{}|^$\\", *p))
            re[k++] = '\\';
        re[k++] = *p;
    }
    re[k] = '\0';
    u->ls = lcm_subscribe(s->lcm, re, on_lcm, u);
    if (!u->ls)
        goto fail;
    lcm_subscription_set_queue_capacity(u->ls, 1000);
    u->next = s->subs;
    s->subs = u;
    s->st.subscriptions++;
    return u;
fail:
    if (u)
        free(u->channel);
    free(u);
    return NULL;
}

static void sub_release(xb_server_t *s, sub_t *u)
{
    if (u->nclients > 0)
        return;
    for (sub_t **pp = &s->subs; *pp; pp = &(*pp)->next)
        if (*pp == u) {
            *pp = u->next;
            break;
        }
    lcm_unsubscribe(s->lcm, u->ls);
    free(u->channel);
    free(u->clients);
    free(u->stream);
    free(u->latest);
    free(u);
    s->st.subscriptions--;
}

static int sub_add_client(sub_t *u, client_t *c, int stream)
{
    for (int i = 0; i < u->nclients; i++)
        if (u->clients[i] == c) {
            u->nstream += stream - u->stream[i];
            u->stream[i] = stream;
            return 0;
        }
    if (u->nclients == u->capclients) {
        int cap = u->capclients ? u->capclients * 2 : 4;
        client_t **nc = realloc(u->clients, (size_t)cap * sizeof *nc);
        if (!nc)
            return -1;
        u->clients = nc;
        int *ns = realloc(u->stream, (size_t)cap * sizeof *ns);
        if (!ns)
            return -1;
        u->stream = ns;
        u->capclients = cap;
    }
    u->clients[u->nclients] = c;
    u->stream[u->nclients] = stream;
    u->nclients++;
    u->nstream += stream;
    return 0;
}

static void sub_remove_client(xb_server_t *s, sub_t *u, client_t *c)
{
    for (int i = 0; i < u->nclients; i++)
        if (u->clients[i] == c) {
            u->nstream -= u->stream[i];
            u->clients[i] = u->clients[u->nclients - 1];
            u->stream[i] = u->stream[u->nclients - 1];
            u->nclients--;
            break;
        }
    sub_release(s, u);
}

static csub_t *client_sub(client_t *c, const char *channel, const marie_typeinfo_t *t)
{
    for (int i = 0; i < c->nsubs; i++)
        if (c->subs[i].sub->type == t && strcmp(c->subs[i].sub->channel, channel) == 0)
            return &c->subs[i];
    return NULL;
}

/* ---- requests ---- */

static const char *need_channel(client_t *c, const xb_node_t *req)
{
    const char *ch = xb_node_attr(req, "channel");
    if (!ch || !ch[0]) {
        reply_error(c, req, "bad-request", "missing channel attribute");
        return NULL;
    }
    if (strlen(ch) > LCM_MAX_CHANNEL_NAME_LENGTH) {
        reply_error(c, req, "bad-channel", "channel name longer than 63 bytes");
        return NULL;
    }
    return ch;
}

static const marie_typeinfo_t *need_type(client_t *c, const xb_node_t *req)
{
    const char *tn = xb_node_attr(req, "type");
    if (!tn) {
        reply_error(c, req, "bad-request", "missing type attribute");
        return NULL;
    }
    const marie_typeinfo_t *t = marie_typeinfo_find(tn);
    if (!t) {
        char why[160];
        snprintf(why, sizeof why, "no type named '%.100s' (see <types/>)", tn);
        reply_error(c, req, "unknown-type", why);
    }
    return t;
}

static void do_subscribe(client_t *c, const xb_node_t *req)
{
    const char *ch = need_channel(c, req);
    const marie_typeinfo_t *t = ch ? need_type(c, req) : NULL;
    if (!t)
        return;
    const char *mode = xb_node_attr(req, "mode");
    if (mode && strcmp(mode, "stream") != 0 && strcmp(mode, "latest") != 0) {
        reply_error(c, req, "bad-request", "mode must be stream or latest");
        return;
    }
    int stream = !mode || strcmp(mode, "stream") == 0;
    csub_t *cs = client_sub(c, ch, t);
    if (!cs) {
        if (c->nsubs == c->capsubs) {
            int cap = c->capsubs ? c->capsubs * 2 : 4;
            csub_t *n = realloc(c->subs, (size_t)cap * sizeof *n);
            if (!n) {
                reply_error(c, req, "subscribe-failed", "out of memory");
                return;
            }
            c->subs = n;
            c->capsubs = cap;
        }
        sub_t *u = sub_get(c->s, ch, t);
        if (!u || sub_add_client(u, c, stream) < 0) {
            if (u)
                sub_release(c->s, u);
            reply_error(c, req, "subscribe-failed", "cannot subscribe on the bus");
            return;
        }
        c->subs[c->nsubs++] = (csub_t){ u, stream };
    } else {
        sub_add_client(cs->sub, c, stream);
        cs->stream = stream;
    }
    reply_ok(c, req, "mode", stream ? "stream" : "latest");
}

static void do_unsubscribe(client_t *c, const xb_node_t *req)
{
    const char *ch = need_channel(c, req);
    if (!ch)
        return;
    const char *tn = xb_node_attr(req, "type");
    const marie_typeinfo_t *t = tn ? need_type(c, req) : NULL;
    if (tn && !t)
        return;
    int removed = 0;
    for (int i = 0; i < c->nsubs;) {
        sub_t *u = c->subs[i].sub;
        if (strcmp(u->channel, ch) == 0 && (!t || u->type == t)) {
            c->subs[i] = c->subs[--c->nsubs];
            sub_remove_client(c->s, u, c);
            removed++;
        } else {
            i++;
        }
    }
    if (!removed)
        reply_error(c, req, "not-subscribed", "no such subscription");
    else
        reply_ok(c, req, NULL, NULL);
}

static void do_publish(client_t *c, const xb_node_t *req)
{
    xb_server_t *s = c->s;
    const char *ch = need_channel(c, req);
    const marie_typeinfo_t *t = ch ? need_type(c, req) : NULL;
    if (!t)
        return;
    xb_error_t err;
    s->enc.len = 0;
    s->enc.full = 0;
    if (xb_encode(t, req, &s->enc, &err) < 0) {
        if (strcmp(err.code, "no-memory") == 0) {   /* the bridge's fault, not the document's */
            reply_error(c, req, "publish-failed", err.reason);
            return;
        }
        bad_input(s, "bad_document", "%s: %s", err.code, err.reason);
        reply_error(c, req, err.code, err.reason);
        return;
    }
    if (lcm_publish(s->lcm, ch, s->enc.data, (unsigned)s->enc.len) < 0) {
        if (s->hooks.drop)
            s->hooks.drop(s->hooks.user, 1);
        reply_error(c, req, "publish-failed", "the bus refused the message");
        return;
    }
    s->st.published++;
    const char *ack = xb_node_attr(req, "ack");
    if (!ack || strcmp(ack, "false") != 0)
        reply_ok(c, req, NULL, NULL);
}

static void do_pull(client_t *c, const xb_node_t *req)
{
    const char *ch = need_channel(c, req);
    if (!ch)
        return;
    const char *tn = xb_node_attr(req, "type");
    const marie_typeinfo_t *t = tn ? need_type(c, req) : NULL;
    if (tn && !t)
        return;
    /* The bridge is a Mailbox for every channel some client subscribed to. */
    sub_t *u = NULL;
    for (sub_t *v = c->s->subs; v; v = v->next)
        if (strcmp(v->channel, ch) == 0 && (!t || v->type == t) && (!u || (v->has_latest &&
            (!u->has_latest || v->latest_utime > u->latest_utime))))
            u = v;
    if (!u) {
        reply_error(c, req, "not-subscribed", "subscribe to the channel (mode stream or latest) first");
        return;
    }
    if (!u->has_latest) {
        reply_error(c, req, "no-data", "nothing received on the channel yet");
        return;
    }
    xb_error_t err;
    if (format_message(c->s, u, u->channel, u->latest, u->latest_len, u->latest_utime, req, &err) < 0) {
        reply_error(c, req, err.code, err.reason);
        return;
    }
    enqueue_text(c, c->s->out.data, c->s->out.len);
}

static const char *dims_text(const marie_tfield_t *f, const marie_typeinfo_t *t, char *buf, size_t size)
{
    size_t n = 0;
    buf[0] = '\0';
    for (int d = 0; d < f->ndims && n < size; d++) {
        if (f->dims[d].len_field < 0)
            n += (size_t)snprintf(buf + n, size - n, "[%d]", (int)f->dims[d].size);
        else
            n += (size_t)snprintf(buf + n, size - n, "[%s]", t->fields[f->dims[d].len_field].name);
    }
    return buf;
}

static void do_types(client_t *c, const xb_node_t *req)
{
    xb_buf_t *b = &c->s->out;
    b->len = 0;
    xb_buf_puts(b, "<types");
    put_attr(b, "id", xb_node_attr(req, "id"));
    xb_buf_puts(b, ">");
    for (size_t i = 0; marie_typeinfos[i]; i++)
        xb_buf_printf(b, "<type name=\"%s\" fingerprint=\"%016llx\"/>", marie_typeinfos[i]->name,
                      (unsigned long long)marie_typeinfos[i]->fingerprint);
    xb_buf_puts(b, "</types>\n");
    enqueue_text(c, b->data, b->len);
}

static void do_describe(client_t *c, const xb_node_t *req)
{
    const marie_typeinfo_t *t = need_type(c, req);
    if (!t)
        return;
    xb_buf_t *b = &c->s->out;
    b->len = 0;
    xb_buf_printf(b, "<type name=\"%s\" fingerprint=\"%016llx\"", t->name,
                  (unsigned long long)t->fingerprint);
    put_attr(b, "id", xb_node_attr(req, "id"));
    xb_buf_puts(b, ">");
    for (int i = 0; i < t->nfields; i++) {
        const marie_tfield_t *f = &t->fields[i];
        char dims[128];
        xb_buf_printf(b, "<field name=\"%s\" type=\"%s\"", f->name,
                      f->prim == MARIE_PRIM_STRUCT ? f->sub->name : marie_prim_name(f->prim));
        if (f->ndims)
            xb_buf_printf(b, " dims=\"%s\"", dims_text(f, t, dims, sizeof dims));
        xb_buf_puts(b, "/>");
    }
    for (int i = 0; i < t->nconsts; i++) {
        xb_buf_printf(b, "<const name=\"%s\" type=\"%s\"", t->consts[i].name,
                      marie_prim_name(t->consts[i].prim));
        put_attr(b, "value", t->consts[i].value);
        xb_buf_puts(b, "/>");
    }
    xb_buf_puts(b, "</type>\n");
    enqueue_text(c, b->data, b->len);
}

static void on_document(void *user, xb_node_t *req)
{
    client_t *c = user;
    xb_server_t *s = c->s;
    s->st.documents++;
    if (c->dead || c->closing_since)
        return;
    const char *op = req->name;
    if (strcmp(op, "publish") == 0)
        do_publish(c, req);
    else if (strcmp(op, "subscribe") == 0)
        do_subscribe(c, req);
    else if (strcmp(op, "unsubscribe") == 0)
        do_unsubscribe(c, req);
    else if (strcmp(op, "pull") == 0)
        do_pull(c, req);
    else if (strcmp(op, "ping") == 0)
        reply_ok(c, req, NULL, NULL);
    else if (strcmp(op, "types") == 0)
        do_types(c, req);
    else if (strcmp(op, "describe") == 0)
        do_describe(c, req);
    else {
        char why[128];
        snprintf(why, sizeof why, "unknown request <%.64s>", op);
        bad_input(s, "bad_document", "%s", why);
        reply_error(c, req, "unknown-request", why);
    }
}

/* ---- client lifecycle ---- */

/* Charges the client's parser memory to the bridge's document budget. */
static void charge(client_t *c)
{
    size_t now = c->parser ? xb_doc_parser_memory(c->parser) : 0;
    c->s->st.doc_bytes += now - c->mem;     /* modular: a decrease subtracts */
    c->mem = now;
}

static void client_close(client_t *c)
{
    xb_server_t *s = c->s;
    while (c->nsubs > 0) {
        sub_t *u = c->subs[--c->nsubs].sub;
        sub_remove_client(s, u, c);
    }
    free(c->subs);
    if (c->fd >= 0) {
        epoll_ctl(s->efd, EPOLL_CTL_DEL, c->fd, NULL);
        close(c->fd);
    }
    for (int i = 0; i < c->qlen; i++)
        msgbuf_unref(c->q[(c->qhead + i) % c->qcap].b);
    msgbuf_unref(c->cur.b);
    free(c->q);
    xb_doc_parser_destroy(c->parser);
    c->parser = NULL;
    charge(c);
    if (c->prev)
        c->prev->next = c->next;
    else
        s->clients = c->next;
    if (c->next)
        c->next->prev = c->prev;
    s->st.clients--;
    free(c);
}

/* Tells the client why, stops reading, and closes once the reply is written (or soon). */
static void client_fail(client_t *c, const char *code, const char *reason)
{
    if (c->closing_since)
        return;
    /* Nothing more will be parsed: what the unfinished document held goes back at once. */
    xb_doc_parser_destroy(c->parser);
    c->parser = NULL;
    charge(c);
    reply_error(c, NULL, code, reason);
    c->closing_since = marie_mono_us();
    c->s->st.closed_bad++;
    c->want_out = -1;           /* force the epoll update */
    set_out(c, 1);
}

/* Over budget, the clients holding the most for unfinished documents are closed, largest
 * first, until the rest fits: whoever sends the big document pays, not whoever comes next. */
static void enforce_budget(xb_server_t *s)
{
    while (s->st.doc_bytes > s->cfg.max_memory) {
        client_t *big = NULL;
        for (client_t *c = s->clients; c; c = c->next)
            if (!c->closing_since && c->parser && xb_doc_parser_partial(c->parser) &&
                (!big || c->mem > big->mem))
                big = c;
        if (!big)
            return;
        char why[200];
        snprintf(why, sizeof why, "unfinished document holds %zu bytes, over its share (%zu) of "
                 "the bridge's %zu-byte document memory", big->mem,
                 s->cfg.max_memory / (size_t)(s->st.clients ? s->st.clients : 1), s->cfg.max_memory);
        bad_input(s, "memory_budget", "%s", why);
        s->st.closed_memory++;
        client_fail(big, "no-memory", why);
    }
}

static void client_read(client_t *c)
{
    xb_server_t *s = c->s;
    char buf[65536];
    /* Bounded per wake-up so one busy client cannot starve the others. */
    for (int round = 0; round < 4 && !c->dead && !c->closing_since; round++) {
        ssize_t n = read(c->fd, buf, sizeof buf);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            if (errno != EAGAIN && errno != EWOULDBLOCK)
                c->dead = 1;
            break;
        }
        if (n == 0) {
            if (xb_doc_parser_partial(c->parser))
                bad_input(s, "truncated_document", "client closed in the middle of a document");
            c->dead = 1;
            break;
        }
        int rc = xb_doc_parser_feed(c->parser, buf, (size_t)n);
        if (rc < 0) {
            const xb_error_t *e = xb_doc_parser_error(c->parser);
            bad_input(s, "bad_document", "%s: %s", e->code, e->reason);
            client_fail(c, e->code, e->reason);
            break;
        }
        if (xb_doc_parser_partial(c->parser)) {
            if (!c->partial_since)
                c->partial_since = marie_mono_us();
        } else {
            c->partial_since = 0;
        }
        charge(c);
        if (s->st.doc_bytes > s->cfg.max_memory)
            enforce_budget(s);
        if ((size_t)n < sizeof buf)
            break;
    }
}

static void accept_clients(xb_server_t *s)
{
    for (int i = 0; i < 64; i++) {
        int fd = accept4(s->lfd, NULL, NULL, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
            if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)
                marie_warn_ratelimited(5, "xml bridge: accept: %s", strerror(errno));
            return;
        }
        if ((int)s->st.clients >= s->cfg.max_clients) {
            char msg[160];
            int n = snprintf(msg, sizeof msg, "<error code=\"busy\" reason=\"%d clients already connected\"/>\n",
                             s->cfg.max_clients);
            ssize_t w = send(fd, msg, (size_t)n, MSG_NOSIGNAL);
            (void)w;
            close(fd);
            s->st.refused++;
            bad_input(s, "refused_client", "more than %d clients", s->cfg.max_clients);
            continue;
        }
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        if (s->cfg.sndbuf > 0)
            setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &s->cfg.sndbuf, sizeof s->cfg.sndbuf);
        client_t *c = calloc(1, sizeof *c);
        xb_doc_limits_t lim = { s->cfg.max_doc_bytes, s->cfg.max_depth };
        if (!c || !(c->parser = xb_doc_parser_create(&lim, on_document, c))) {
            free(c);
            close(fd);
            continue;
        }
        c->s = s;
        c->fd = fd;
        struct epoll_event ev = { .events = EPOLLIN, .data.ptr = c };
        if (epoll_ctl(s->efd, EPOLL_CTL_ADD, fd, &ev) < 0) {
            xb_doc_parser_destroy(c->parser);
            free(c->q);
            free(c);
            close(fd);
            continue;
        }
        charge(c);
        c->next = s->clients;
        if (s->clients)
            s->clients->prev = c;
        s->clients = c;
        s->st.clients++;
        s->st.accepted++;
        char hello[256];
        int n = snprintf(hello, sizeof hello,
                         "<hello protocol=\"%d\" max_document=\"%zu\" max_depth=\"%d\" queue=\"%d\"/>\n",
                         XB_PROTOCOL, s->cfg.max_doc_bytes, s->cfg.max_depth, s->cfg.queue_docs);
        enqueue_text(c, hello, (size_t)n);
    }
}

static void on_epoll(marie_loop_t *loop, int fd, short revents, void *user)
{
    xb_server_t *s = user;
    struct epoll_event evs[128];
    int n = epoll_wait(s->efd, evs, 128, 0);
    for (int i = 0; i < n; i++) {
        if (evs[i].data.ptr == NULL) {
            accept_clients(s);
            continue;
        }
        client_t *c = evs[i].data.ptr;
        if (c->dead)
            continue;
        if (c->closing_since && (evs[i].events & (EPOLLHUP | EPOLLERR)))
            c->dead = 1;
        else if (evs[i].events & (EPOLLIN | EPOLLHUP | EPOLLERR))
            client_read(c);
        if (!c->dead && (evs[i].events & EPOLLOUT))
            flush(c);
    }
    /* Closing is deferred to here so no event of this batch refers to a freed client. */
    for (client_t *c = s->clients, *next; c; c = next) {
        next = c->next;
        if (c->dead)
            client_close(c);
    }
}

static void on_sweep(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    xb_server_t *s = user;
    int64_t now = marie_mono_us();
    for (client_t *c = s->clients, *next; c; c = next) {
        next = c->next;
        if (c->closing_since && now - c->closing_since > CLOSE_GRACE_US)
            c->dead = 1;
        else if (!c->closing_since && c->partial_since &&
                 now - c->partial_since > (int64_t)s->cfg.stall_ms * 1000) {
            bad_input(s, "stalled_client", "document unfinished for %d ms", s->cfg.stall_ms);
            client_fail(c, "stalled", "document left unfinished too long");
        }
        if (c->dead)
            client_close(c);
    }
}

static void on_lcm_fd(marie_loop_t *loop, int fd, short revents, void *user)
{
    xb_server_t *s = user;
    for (int i = 0; i < 256; i++)
        if (lcm_handle_timeout(s->lcm, 0) <= 0)
            break;
}

xb_server_t *xb_server_create(const xb_server_cfg_t *cfg, lcm_t *lcm, marie_loop_t *loop,
                              const xb_server_hooks_t *hooks)
{
    xb_server_t *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    if (cfg)
        s->cfg = *cfg;
    else
        xb_server_cfg_defaults(&s->cfg);
    snprintf(s->bind, sizeof s->bind, "%s", s->cfg.bind ? s->cfg.bind : "127.0.0.1");
    s->cfg.bind = s->bind;
    if (s->cfg.queue_docs < 2)
        s->cfg.queue_docs = 2;
    if (s->cfg.max_clients < 1)
        s->cfg.max_clients = 1;
    if (!s->cfg.max_message)
        s->cfg.max_message = 4u << 20;
    if (!s->cfg.queue_bytes)
        s->cfg.queue_bytes = 8u << 20;
    if (!s->cfg.max_memory)
        s->cfg.max_memory = 256u << 20;
    if (hooks)
        s->hooks = *hooks;
    s->lcm = lcm;
    s->loop = loop;
    s->lfd = s->efd = -1;
    /* The largest outgoing document: a max-size payload as base64 XML plus the envelope. */
    xb_buf_init(&s->out, s->cfg.max_message * 4 + 4096);
    xb_buf_init(&s->enc, s->cfg.max_message);

    struct addrinfo hints = { .ai_family = AF_UNSPEC, .ai_socktype = SOCK_STREAM,
                              .ai_flags = AI_PASSIVE | AI_NUMERICSERV };
    struct addrinfo *ai = NULL;
    char port[16];
    snprintf(port, sizeof port, "%d", s->cfg.port);
    int rc = getaddrinfo(s->bind[0] ? s->bind : NULL, port, &hints, &ai);
    if (rc != 0) {
        marie_error("xml bridge: bad bind address '%s': %s", s->bind, gai_strerror(rc));
        errno = EINVAL;
        goto err;
    }
    s->lfd = socket(ai->ai_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    int one = 1;
    if (s->lfd < 0 || setsockopt(s->lfd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) < 0 ||
        bind(s->lfd, ai->ai_addr, ai->ai_addrlen) < 0 || listen(s->lfd, 1024) < 0) {
        int e = errno;
        marie_error("xml bridge: cannot listen on %s:%d: %s", s->bind, s->cfg.port, strerror(e));
        freeaddrinfo(ai);
        errno = e;
        goto err;
    }
    freeaddrinfo(ai);
    struct sockaddr_storage sa;
    socklen_t sl = sizeof sa;
    getsockname(s->lfd, (struct sockaddr *)&sa, &sl);
    s->port = ntohs(sa.ss_family == AF_INET6 ? ((struct sockaddr_in6 *)&sa)->sin6_port
                                             : ((struct sockaddr_in *)&sa)->sin_port);

    s->efd = epoll_create1(EPOLL_CLOEXEC);
    struct epoll_event ev = { .events = EPOLLIN, .data.ptr = NULL };
    if (s->efd < 0 || epoll_ctl(s->efd, EPOLL_CTL_ADD, s->lfd, &ev) < 0)
        goto err;
    if ((rc = marie_loop_add_fd(loop, s->efd, POLLIN, on_epoll, s)) < 0) {
        errno = -rc;
        goto err;
    }
    if (s->cfg.handle_lcm && (rc = marie_loop_add_fd(loop, lcm_get_fileno(lcm), POLLIN, on_lcm_fd, s)) < 0) {
        marie_loop_remove_fd(loop, s->efd);
        errno = -rc;
        goto err;
    }
    s->sweep = marie_loop_add_wall_timer(loop, 100000, on_sweep, s);
    if (!s->sweep) {
        marie_loop_remove_fd(loop, s->efd);
        if (s->cfg.handle_lcm)
            marie_loop_remove_fd(loop, lcm_get_fileno(lcm));
        goto err;
    }
    return s;
err:
    if (s->efd >= 0)
        close(s->efd);
    if (s->lfd >= 0)
        close(s->lfd);
    xb_buf_free(&s->out);
    xb_buf_free(&s->enc);
    free(s);
    return NULL;
}

void xb_server_destroy(xb_server_t *s)
{
    if (!s)
        return;
    while (s->clients)
        client_close(s->clients);
    while (s->subs) {
        sub_t *u = s->subs;
        u->nclients = 0;
        sub_release(s, u);
    }
    marie_loop_remove_timer(s->loop, s->sweep);
    marie_loop_remove_fd(s->loop, s->efd);
    if (s->cfg.handle_lcm)
        marie_loop_remove_fd(s->loop, lcm_get_fileno(s->lcm));
    close(s->efd);
    close(s->lfd);
    xb_buf_free(&s->out);
    xb_buf_free(&s->enc);
    free(s);
}

int xb_server_port(const xb_server_t *s)
{
    return s->port;
}

void xb_server_stats(const xb_server_t *s, xb_server_stats_t *st)
{
    *st = s->st;
}
