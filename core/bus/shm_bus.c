/* shm_bus: shared-memory publishers and subscribers: notices on CHANNEL.SHM, LCM copies on request. */
#include "core/bus/shm_bus.h"

#include <errno.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/err.h"
#include "core/bus/provider.h"
#include "core/loop.h"
#include "core/new.h"
#include "core/shm.h"
#include "core/time.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_shm_notice_t.h"
#include "lcmtypes/marie_shm_want_t.h"

#define WANT_HOLD_US 2000000        /* a request keeps the LCM copies flowing this long */
#define WANT_EVERY_US 1000000       /* a remote subscriber repeats its request this often */
#define CH_MAX 256
#define RINGLESS_MAX 16             /* ringless notices whose message has not come yet */

/* The machine: only there can a segment be mapped. MARIE_SHM_HOST overrides the host name
 * (machines that share one, such as containers; tests playing another host). */
void marie_shm_host(char *out, size_t cap)
{
    const char *env = getenv("MARIE_SHM_HOST");
    if (env && *env) {
        snprintf(out, cap, "%s", env);
        return;
    }
    if (gethostname(out, cap) < 0 || !out[0])
        snprintf(out, cap, "localhost");
    out[cap - 1] = '\0';
}

/* A notice or a request, on the bus's own provider (the channel's transport is this one). */
static int publish_notice(lcm_t *bus, const char *channel, const marie_type_t *t, const void *msg)
{
    uint8_t buf[1024];
    int size = t->encoded_size(msg);
    if (size < 0 || size > (int)sizeof buf || t->encode(buf, 0, size, msg) != size)
        return marie_fail(EINVAL);
    return marie_bus_publish_own(bus, channel, buf, (size_t)size);
}

/* ---- publisher ---- */

struct marie_shm_pub {
    lcm_t *lcm;
    char channel[CH_MAX], notice_ch[CH_MAX + 8], want_ch[CH_MAX + 12];
    char host[64];
    marie_shm_writer_t *w;
    marie_bus_sub_t *want_sub;
    int64_t wanted_until;       /* mono us */
    int64_t notice_every_us;    /* 0: a notice per message */
    int64_t last_notice;        /* mono us */
    void (*after_ring)(void *); /* run between the ring and LCM (the fast path's doorbells) */
    void *after_user;
    marie_shm_pub_stats_t st;
};

static void on_want(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    marie_shm_pub_t *p = user;
    marie_shm_want_t m;
    if (marie_decode_checked(&marie_type_shm_want_t, rb->data, rb->data_size, &m) < 0)
        return;
    marie_shm_want_t_decode_cleanup(&m);
    p->st.wants++;
    p->wanted_until = marie_mono_us() + WANT_HOLD_US;
}

marie_shm_pub_t *marie_shm_pub_create(lcm_t *lcm, const char *channel, size_t max_size, int nslots)
{
    if (!lcm || !channel || strlen(channel) >= CH_MAX)
        return marie_fail_null(EINVAL);
    marie_shm_pub_t *p = calloc(1, sizeof *p);
    if (!p)
        return NULL;
    p->lcm = lcm;
    snprintf(p->channel, sizeof p->channel, "%s", channel);
    snprintf(p->notice_ch, sizeof p->notice_ch, "%s.SHM", channel);
    snprintf(p->want_ch, sizeof p->want_ch, "%s.SHMWANT", channel);
    marie_shm_host(p->host, sizeof p->host);
    p->w = marie_shm_writer_create(channel, max_size, nslots);
    if (!p->w)
        goto err;
    p->want_sub = marie_bus_subscribe_own(lcm, p->want_ch, on_want, p);
    if (!p->want_sub) {
        errno = EIO;
        goto err;
    }
    return p;
err:
    MARIE_KEEP_ERRNO(marie_shm_writer_destroy(p->w); free(p));
    return NULL;
}

void marie_shm_pub_destroy(marie_shm_pub_t *p)
{
    if (!p)
        return;
    marie_bus_unsubscribe(p->lcm, p->want_sub);
    marie_shm_writer_destroy(p->w);
    free(p);
}

void *marie_shm_pub_loan(marie_shm_pub_t *p) { return marie_shm_begin(p->w); }

/* 0 when len bytes make a message a slot holds, else what publishing them returns (counted). */
static int refused(marie_shm_pub_t *p, size_t len)
{
    if (len < 8)
        return marie_fail(EINVAL);
    if (len <= marie_shm_slot_size(p->w))
        return 0;
    p->st.too_big++;
    return marie_fail(EMSGSIZE);
}

int marie_shm_pub_commit(marie_shm_pub_t *p, size_t len)
{
    const uint8_t *at = marie_shm_begun(p->w);     /* only this writer ever writes the slot */
    if (!at)
        return marie_fail(EINVAL);
    int rc = refused(p, len);
    marie_shm_ref_t ref;
    MARIE_KEEP_ERRNO(marie_shm_commit(p->w, rc ? 0 : len, rc ? NULL : &ref));
    if (rc)
        return -1;
    if (p->after_ring)
        p->after_ring(p->after_user);
    p->st.published++;
    int64_t now = p->notice_every_us ? marie_mono_us() : 0;
    if (!p->notice_every_us || now - p->last_notice >= p->notice_every_us) {
        p->last_notice = now;
        marie_shm_notice_t n = { .utime = marie_wall_us(), .host = p->host, .segment = ref.segment, .seq = ref.seq,
                                 .size = (int32_t)ref.size, .fingerprint = marie_payload_fingerprint(at, len) };
        if (publish_notice(p->lcm, p->notice_ch, &marie_type_shm_notice_t, &n) != 0)
            return marie_fail(EIO);
    }
    if (p->wanted_until && marie_mono_us() < p->wanted_until) {
        if (marie_bus_publish_own(p->lcm, p->channel, at, len) != 0)
            return marie_fail(EIO);
        p->st.lcm_copies++;
    }
    return 0;
}

int marie_shm_pub_publish_with(marie_shm_pub_t *p, size_t len, marie_shm_fill_t fill, void *user)
{
    int rc = refused(p, len);
    if (rc)
        return rc;
    if (fill(marie_shm_pub_loan(p), len, user) < 0)
        len = 0;                    /* committed empty: no notice */
    return marie_shm_pub_commit(p, len);
}

int marie_shm_pub_publish(marie_shm_pub_t *p, const void *data, size_t len)
{
    return marie_shm_pub_publish_with(p, len, marie_shm_fill_copy, (void *)data);
}

const marie_shm_pub_stats_t *marie_shm_pub_stats(const marie_shm_pub_t *p) { return &p->st; }

const char *marie_shm_pub_segment(const marie_shm_pub_t *p) { return marie_shm_writer_segment(p->w); }

void marie_shm_pub_pace(marie_shm_pub_t *p, int64_t notice_every_us, void (*after_ring)(void *), void *user)
{
    p->notice_every_us = notice_every_us;
    p->after_ring = after_ring;
    p->after_user = user;
}

/* ---- subscriber ---- */

typedef struct {
    int32_t size;
    int64_t fp;
} ringless_t;

struct marie_shm_sub {
    lcm_t *lcm;
    char channel[CH_MAX], want_ch[CH_MAX + 12];
    char host[64];
    marie_shm_reader_t *r;
    uint8_t *buf;
    size_t cap;
    marie_shm_msg_cb_t cb;
    marie_shm_verdict_cb_t verdict;     /* in place: NULL means copy first */
    marie_shm_msg_cb_t held;            /* in place and held (large messages), or NULL */
    void *user;
    marie_bus_sub_t *notice_sub, *copy_sub;
    bool remote_only;           /* this host's writers are read another way (the fast path) */
    int depth;                  /* callbacks running */
    bool dead;                  /* destroyed from one: freed once it returns */
    bool remote;                /* a writer elsewhere: every message on CHANNEL is one */
    int64_t last_want;          /* mono us */
    ringless_t ringless[RINGLESS_MAX];  /* announced by ringless notices, not yet come */
    int nringless;
    marie_shm_sub_stats_t st;
};

static void sub_free(marie_shm_sub_t *s)
{
    marie_shm_reader_destroy(s->r);
    free(s->buf);
    free(s);
}

/* A callback may destroy the subscriber (a handler unsubscribing): it is freed after. */
static void enter(marie_shm_sub_t *s) { s->depth++; }
static void leave(marie_shm_sub_t *s)
{
    if (--s->depth == 0 && s->dead)
        sub_free(s);
}

/* A publisher without a ring (a Python component's port) announced a message of this size and
 * type: true when it is one, taken off the list with the ones before it (lost on the way). */
static bool announced(marie_shm_sub_t *s, size_t len, int64_t fp)
{
    for (int i = 0; i < s->nringless; i++)
        if ((size_t)s->ringless[i].size == len && s->ringless[i].fp == fp) {
            s->nringless -= i + 1;
            memmove(s->ringless, s->ringless + i + 1, (size_t)s->nringless * sizeof s->ringless[0]);
            return true;
        }
    return false;
}

static void announce(marie_shm_sub_t *s, int32_t size, int64_t fp)
{
    if (s->nringless == RINGLESS_MAX)       /* the oldest's message never came */
        memmove(s->ringless, s->ringless + 1, (size_t)--s->nringless * sizeof s->ringless[0]);
    s->ringless[s->nringless++] = (ringless_t){size, fp};
}

/* A message on CHANNEL over LCM: a writer elsewhere's (asked for), or one a ringless publisher
 * announced; otherwise a copy of a ring this host reads, sent for someone else, and left. */
static void on_copy(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    marie_shm_sub_t *s = user;
    if (!s->remote && !announced(s, rb->data_size, marie_payload_fingerprint(rb->data, rb->data_size)))
        return;
    s->st.remote++;
    enter(s);
    s->cb(rb->data, rb->data_size, s->user);
    if (s->verdict && !s->dead)
        s->verdict(true, s->user);      /* LCM's copy is the subscriber's own */
    leave(s);
}

/* The writer is not on this host: ask for the messages on LCM (repeated while they come). */
static void want_remote(marie_shm_sub_t *s)
{
    int64_t now = marie_mono_us();
    s->remote = true;
    s->nringless = 0;
    if (now - s->last_want < WANT_EVERY_US)
        return;
    s->last_want = now;
    marie_shm_want_t w = { .utime = marie_wall_us(), .host = s->host, .requester = s->host };
    publish_notice(s->lcm, s->want_ch, &marie_type_shm_want_t, &w);
}

static void deliver_in_place(marie_shm_sub_t *s, const marie_shm_ref_t *ref, int64_t fp)
{
    const void *p = s->held && ref->size >= MARIE_SHM_HOLD_MIN ? marie_shm_hold(s->r, ref) : NULL;
    bool holding = p != NULL;
    if (!p)
        p = marie_shm_peek(s->r, ref);
    if (!p) {
        if (errno == ENOENT)
            want_remote(s);
        else if (errno == ESTALE || errno == EAGAIN)
            s->st.lost++;
        else
            s->st.bad++;
        return;
    }
    if (marie_payload_fingerprint(p, ref->size) != fp) {
        s->st.bad++;
        if (holding)
            marie_shm_release(s->r, ref);
        return;
    }
    enter(s);
    (holding ? s->held : s->cb)(p, ref->size, s->user);
    bool ok = marie_shm_still_valid(s->r, ref);
    if (ok)
        s->st.received++;
    else
        s->st.lost++;
    if (!s->dead)
        s->verdict(ok, s->user);
    if (holding)
        marie_shm_release(s->r, ref);
    leave(s);
}

static void on_notice(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    marie_shm_sub_t *s = user;
    marie_shm_notice_t n;
    if (marie_decode_checked(&marie_type_shm_notice_t, rb->data, rb->data_size, &n) < 0) {
        s->st.bad++;
        return;
    }
    if (!n.segment[0]) {
        /* no ring: the message follows on CHANNEL (a publisher that does not write rings) */
        if (n.size < 8 || (size_t)n.size > s->cap)
            s->st.bad++;
        else if (!s->remote)
            announce(s, n.size, n.fingerprint);
    } else if (strcmp(n.host, s->host) != 0) {
        want_remote(s);
    } else if (s->remote_only) {
        /* read from the ring by the fast path */
    } else if (n.size < 8 || (size_t)n.size > s->cap || strlen(n.segment) >= MARIE_SHM_NAME_MAX) {
        s->st.bad++;
    } else {
        marie_shm_ref_t ref = { .seq = n.seq, .size = (uint32_t)n.size };
        snprintf(ref.segment, sizeof ref.segment, "%s", n.segment);
        if (s->verdict) {
            deliver_in_place(s, &ref, n.fingerprint);
            marie_shm_notice_t_decode_cleanup(&n);
            return;
        }
        int64_t got = marie_shm_read(s->r, &ref, s->buf, s->cap);
        if (got == n.size && marie_payload_fingerprint(s->buf, (size_t)got) == n.fingerprint) {
            s->st.received++;
            enter(s);
            s->cb(s->buf, (size_t)got, s->user);
            leave(s);
        } else if (got < 0 && errno == ENOENT) {
            want_remote(s);         /* same name, another machine (containers), or gone */
        } else if (got < 0 && (errno == ESTALE || errno == EAGAIN)) {
            s->st.lost++;
        } else {
            s->st.bad++;
        }
    }
    marie_shm_notice_t_decode_cleanup(&n);
}

marie_shm_sub_t *marie_shm_sub_create(lcm_t *lcm, const char *channel, size_t max_size, marie_shm_msg_cb_t cb,
                                      void *user)
{
    if (!lcm || !channel || strlen(channel) >= CH_MAX || !cb || max_size < 8)
        return marie_fail_null(EINVAL);
    marie_shm_sub_t *s = MARIE_NEW(marie_shm_sub_t, .lcm = lcm, .cb = cb, .user = user, .cap = max_size);
    if (!s)
        return NULL;
    snprintf(s->channel, sizeof s->channel, "%s", channel);
    snprintf(s->want_ch, sizeof s->want_ch, "%s.SHMWANT", channel);
    marie_shm_host(s->host, sizeof s->host);
    char notice_ch[CH_MAX + 8];
    snprintf(notice_ch, sizeof notice_ch, "%s.SHM", channel);
    s->r = marie_shm_reader_create();
    s->buf = malloc(max_size);
    if (!s->r || !s->buf)
        goto err;
    /* Notices come in bursts at high rates; each is small. */
    s->notice_sub = marie_bus_subscribe_own(lcm, notice_ch, on_notice, s);
    /* From the start, so that a message right after its ringless notice is not filtered out. */
    s->copy_sub = marie_bus_subscribe_own(lcm, s->channel, on_copy, s);
    if (!s->notice_sub || !s->copy_sub) {
        errno = EIO;
        goto err;
    }
    return s;
err:;
    int e = errno ? errno : ENOMEM;
    marie_bus_unsubscribe(lcm, s->notice_sub);
    marie_bus_unsubscribe(lcm, s->copy_sub);
    marie_shm_reader_destroy(s->r);
    free(s->buf);
    free(s);
    errno = e;
    return NULL;
}

void marie_shm_sub_destroy(marie_shm_sub_t *s)
{
    if (!s)
        return;
    marie_bus_unsubscribe(s->lcm, s->notice_sub);
    marie_bus_unsubscribe(s->lcm, s->copy_sub);
    s->notice_sub = s->copy_sub = NULL;
    if (s->depth > 0)
        s->dead = true;             /* its callback is running: freed when it returns */
    else
        sub_free(s);
}

const marie_shm_sub_stats_t *marie_shm_sub_stats(const marie_shm_sub_t *s) { return &s->st; }

void marie_shm_sub_in_place(marie_shm_sub_t *s, marie_shm_verdict_cb_t verdict) { s->verdict = verdict; }
void marie_shm_sub_held(marie_shm_sub_t *s, marie_shm_msg_cb_t held) { s->held = held; }
void marie_shm_sub_remote_only(marie_shm_sub_t *s) { s->remote_only = true; }

/* ---- the provider: a channel a transport puts on shared memory (`kind: shm`) ---- */

typedef struct {
    lcm_t *bus;
    marie_bus_transport_t t;
    marie_shm_pub_t *pub;       /* made at the first publish or prepare */
} chan_t;

typedef struct {
    marie_shm_sub_t *sub;
    marie_bus_recv_t rv;
    lcm_t *bus;
    const char *channel;        /* the route's */
} shm_sub_t;

static void *chan_open(lcm_t *bus, const marie_bus_transport_t *t, void **bus_st)
{
    return MARIE_NEW(chan_t, .bus = bus, .t = *t);
}

static void chan_close(void *st)
{
    chan_t *ch = st;
    marie_shm_pub_destroy(ch->pub);
    free(ch);
}

static int chan_prepare(void *st)
{
    chan_t *ch = st;
    if (!ch->pub && !(ch->pub = marie_shm_pub_create(ch->bus, ch->t.channel, ch->t.max_size, ch->t.slots)))
        return -1;
    return 0;
}

static int chan_publish_with(void *st, size_t len, marie_bus_fill_t fill, void *user)
{
    chan_t *ch = st;
    if (chan_prepare(ch) < 0)
        return -1;
    return marie_shm_pub_publish_with(ch->pub, len, fill, user);
}

static int chan_publish(void *st, const char *channel, const void *data, size_t len)
{
    return chan_publish_with(st, len, marie_shm_fill_copy, (void *)data);
}

static void *chan_loan(void *st)
{
    chan_t *ch = st;
    return chan_prepare(ch) < 0 ? NULL : marie_shm_pub_loan(ch->pub);
}

static int chan_commit(void *st, size_t len)
{
    chan_t *ch = st;
    return ch->pub ? marie_shm_pub_commit(ch->pub, len) : marie_fail(EINVAL);
}

static void on_bytes(const void *data, size_t len, void *user)
{
    shm_sub_t *w = user;
    lcm_recv_buf_t rb = {(void *)data, (uint32_t)len, marie_wall_us(), w->bus};
    w->rv.handler(&rb, w->channel, w->rv.user);
}

static void on_held(const void *data, size_t len, void *user)
{
    shm_sub_t *w = user;
    lcm_recv_buf_t rb = {(void *)data, (uint32_t)len, marie_wall_us(), w->bus};
    w->rv.held(&rb, w->channel, w->rv.user);
}

static void on_verdict(bool ok, void *user)
{
    shm_sub_t *w = user;
    w->rv.verdict(ok, w->rv.user);
}

static void *chan_subscribe(void *st, const char *channel, const marie_bus_recv_t *rv)
{
    chan_t *ch = st;
    shm_sub_t *w = MARIE_NEW(shm_sub_t, .rv = *rv, .bus = ch->bus, .channel = ch->t.channel);
    if (!w)
        return NULL;
    if (!(w->sub = marie_shm_sub_create(ch->bus, ch->t.channel, ch->t.max_size, on_bytes, w))) {
        MARIE_KEEP_ERRNO(free(w));
        return NULL;
    }
    if (rv->verdict)
        marie_shm_sub_in_place(w->sub, on_verdict);
    if (rv->verdict && rv->held)
        marie_shm_sub_held(w->sub, on_held);
    return w;
}

/* From a handler too: the subscriber then frees itself once its callback returns, and calls
 * nothing of w's after the handler (on_bytes touches nothing after it). */
static void chan_unsubscribe(void *st, void *sub)
{
    shm_sub_t *w = sub;
    marie_shm_sub_destroy(w->sub);
    free(w);
}

static marie_bus_sub_stats_t chan_sub_stats(const void *sub)
{
    const marie_shm_sub_stats_t *s = marie_shm_sub_stats(((const shm_sub_t *)sub)->sub);
    return (marie_bus_sub_stats_t){s->received, s->remote, s->lost, s->bad};
}

const marie_bus_provider_t marie_bus_shm = {
    .name = "shm",
    .open_channel = chan_open,
    .close = chan_close,
    .subscribe = chan_subscribe,
    .unsubscribe = chan_unsubscribe,
    .publish = chan_publish,
    .publish_with = chan_publish_with,
    .loan = chan_loan,
    .commit = chan_commit,
    .prepare = chan_prepare,
    .sub_stats = chan_sub_stats,
};
