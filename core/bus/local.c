/* local: the same-host fast path (`kind: local`): each publisher writes into a ring of its own
 * (core/shm.h), readers on the host follow the rings they find in the channel's registry and
 * are woken through their doorbell only when they sleep; LCM carries a notice a second (for
 * lcm-spy and other hosts) and the messages whole while someone elsewhere asks for them. */
#include "core/bus/local.h"

#include <errno.h>
#include <sched.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>

#include "core/bus/provider.h"
#include "core/bus/shm_bus.h"
#include "core/err.h"
#include "core/new.h"
#include "core/time.h"

#define BEACON_EVERY_US 1000000     /* a notice on CHANNEL.SHM at most this often */

typedef struct lchan lchan_t;

/* The fast path's state for a bus: its doorbell and the channels it reads. */
typedef struct {
    lcm_t *bus;
    local_bell_t bell;              /* fd -1 until the first subscription */
    lchan_t *reading;
    /* The readers the last publish rang for (they slept): marie_bus_waking() */
    local_registry_t *rang_reg;
    uint64_t rang;                  /* their entries in rang_reg->subs, a bit each */
    bool rang_here;                 /* one of them went to sleep on this CPU */
    int64_t rang_at;                /* when (monotonic us) */
    bool gave_up;                   /* marie_bus_waking() said so for that ring */
    int missed;                     /* rings in a row whose reader did not run in WAKING_US */
    unsigned rings;
    bool slept;                     /* the loop slept since the doorbell was last drained */
    bool asleep;                    /* the registry's entries say this bus's reader sleeps */
    int writer_cpu;                 /* the CPU the last message read was committed on, or -1 */
} lbus_t;

/* A woken reader that has not run after this long most likely waits for the publisher's CPU
 * (docs/transport.md, "Waiting for the fast path"); one woken onto an idle CPU runs within it
 * here (8-10 us). After MISSED_MAX rings in a row whose reader did not, the kernel is taken to
 * put woken readers beside their waker: the loop does not wait that long, but for one ring in
 * PROBE_EVERY, to see whether that changed. */
#define WAKING_US 12
#define MISSED_MAX 4
#define PROBE_EVERY 16

/* A publisher this bus follows. */
typedef struct {
    int32_t pid;                    /* 0: none */
    uint32_t ticket;
    marie_shm_reader_t *r;
    char segment[MARIE_SHM_NAME_MAX];
    int64_t next;                   /* the next message to read */
} peer_t;

typedef struct lsub {
    struct lsub *next;
    marie_bus_recv_t rv;
    lchan_t *ch;
    bool removed;                   /* unsubscribed during a delivery: freed after it */
} lsub_t;

struct lchan {
    lbus_t *lb;
    marie_bus_transport_t t;
    local_reg_t reg;
    /* publishing */
    marie_shm_pub_t *pub;
    int pub_at;                     /* its registry entry */
    int bell_fd[LOCAL_SUBS];
    uint32_t bell_ticket[LOCAL_SUBS];
    /* reading */
    lsub_t *subs;
    int sub_at;                     /* its registry entry, -1: not reading */
    uint32_t ticket;                /* its registration's: publishers after it are read whole */
    uint32_t peers_seen;
    peer_t peers[LOCAL_PUBS];
    uint8_t *buf;                   /* a copy for handlers that keep no view */
    marie_shm_sub_t *remote;        /* notices from other hosts: their messages over LCM */
    marie_bus_sub_stats_t st;
    int depth;                      /* deliveries running (a handler may unsubscribe) */
    lchan_t *next_reading;
};

static void sweep(lchan_t *ch);

/* ---- the bus ---- */

static void *chan_open(lcm_t *bus, const marie_bus_transport_t *t, void **bus_st)
{
    if (!*bus_st && !(*bus_st = MARIE_NEW(lbus_t, .bus = bus, .bell = {.fd = -1, .self = -1}, .writer_cpu = -1)))
        return NULL;
    lchan_t *ch = MARIE_NEW(lchan_t, .lb = *bus_st, .t = *t, .pub_at = -1, .sub_at = -1);
    if (!ch)
        return NULL;
    if (local_reg_open(&ch->reg, t->channel) < 0) {
        MARIE_KEEP_ERRNO(free(ch));
        return NULL;
    }
    for (int i = 0; i < LOCAL_SUBS; i++)
        ch->bell_fd[i] = -1;
    return ch;
}

static void close_bus(void *bus_st)
{
    lbus_t *lb = bus_st;
    if (lb->bell.fd >= 0)
        local_bell_close(&lb->bell);
    free(lb);
}

static int bus_fd(void *bus_st) { return ((lbus_t *)bus_st)->bell.fd; }

/* ---- publishing ---- */

/* After each message is in the ring: the doorbells of the readers that sleep. */
static void ring_bells(void *user)
{
    lchan_t *ch = user;
    local_registry_t *reg = ch->reg.reg;
    uint32_t used = atomic_load(&reg->subs_used);
    lbus_t *lb = ch->lb;
    lb->rang_reg = reg;
    lb->rang = 0;
    lb->rang_here = false;
    int cpu = -2;
    for (uint32_t i = 0; i < used && i < LOCAL_SUBS; i++) {
        local_sub_t *e = &reg->subs[i];
        if (!atomic_load(&e->pid) || !atomic_load(&e->sleeping))
            continue;
        if (!lb->rang) {
            lb->rang_at = marie_mono_us();
            cpu = sched_getcpu();
            lb->gave_up = false;
            lb->rings++;
        }
        lb->rang |= 1ull << i;
        lb->rang_here |= cpu >= 0 && atomic_load(&e->cpu) == cpu;
        uint32_t ticket = atomic_load(&e->ticket);
        if (ch->bell_ticket[i] != ticket && ch->bell_fd[i] >= 0) {
            close(ch->bell_fd[i]);          /* the entry is another reader's now */
            ch->bell_fd[i] = -1;
        }
        ch->bell_ticket[i] = ticket;
        char bell[LOCAL_BELL_MAX] = "";
        if (ch->bell_fd[i] < 0)             /* the name only to open it */
            snprintf(bell, sizeof bell, "%.*s", (int)sizeof e->bell - 1, e->bell);
        local_bell_ring(bell, &ch->bell_fd[i]);
    }
}

static int chan_prepare(void *st)
{
    lchan_t *ch = st;
    if (ch->pub)
        return 0;
    struct sigaction old;
    if (sigaction(SIGPIPE, NULL, &old) == 0 && old.sa_handler == SIG_DFL)
        signal(SIGPIPE, SIG_IGN);           /* a doorbell whose reader is gone: EPIPE */
    if (!(ch->pub = marie_shm_pub_create(ch->lb->bus, ch->t.channel, ch->t.max_size, ch->t.slots)))
        return -1;
    marie_shm_pub_pace(ch->pub, BEACON_EVERY_US, ring_bells, ch);
    if ((ch->pub_at = local_reg_add_pub(&ch->reg, marie_shm_pub_segment(ch->pub))) < 0) {
        MARIE_KEEP_ERRNO(marie_shm_pub_destroy(ch->pub));
        ch->pub = NULL;
        return -1;
    }
    return 0;
}

static int chan_publish_with(void *st, size_t len, marie_bus_fill_t fill, void *user)
{
    lchan_t *ch = st;
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
    lchan_t *ch = st;
    return chan_prepare(ch) < 0 ? NULL : marie_shm_pub_loan(ch->pub);
}

static int chan_commit(void *st, size_t len)
{
    lchan_t *ch = st;
    return ch->pub ? marie_shm_pub_commit(ch->pub, len) : marie_fail(EINVAL);
}

/* ---- reading ---- */

static void peer_drop(peer_t *p)
{
    marie_shm_reader_destroy(p->r);
    *p = (peer_t){0};
}

/* The registry's publishers, when it changed: new ones are followed (from their first message
 * when they came after this reader, else from their next), gone ones let go. */
static void rescan(lchan_t *ch)
{
    local_registry_t *reg = ch->reg.reg;
    uint32_t tickets = atomic_load(&reg->tickets);
    if (tickets == ch->peers_seen)
        return;
    ch->peers_seen = tickets;
    for (int i = 0; i < LOCAL_PUBS; i++) {
        local_pub_t *e = &reg->pubs[i];
        peer_t *p = &ch->peers[i];
        int32_t pid = atomic_load(&e->pid);
        uint32_t ticket = atomic_load(&e->ticket);
        if (p->pid && (p->pid != pid || p->ticket != ticket))
            peer_drop(p);
        if (!pid || p->pid || !(p->r = marie_shm_reader_create()))
            continue;
        /* Written by another process: bounded, a name without its NUL is cut. */
        snprintf(p->segment, sizeof p->segment, "%.*s", (int)sizeof e->segment - 1, e->segment);
        int64_t newest = marie_shm_newest(p->r, p->segment);
        if (newest < 0) {
            peer_drop(p);           /* not there (yet): the next change looks again */
            continue;
        }
        p->pid = pid;
        p->ticket = ticket;
        p->next = ticket > ch->ticket ? 1 : newest + 1;
    }
}

static bool chan_pending(lchan_t *ch)
{
    if (atomic_load(&ch->reg.reg->tickets) != ch->peers_seen)
        return true;
    for (int i = 0; i < LOCAL_PUBS; i++)
        if (ch->peers[i].pid && marie_shm_ready(ch->peers[i].r, ch->peers[i].segment, ch->peers[i].next))
            return true;
    return false;
}

/* The slot of ref held for the subscriptions that can use it so, or NULL (then peeked). */
static const void *hold_for(lchan_t *ch, peer_t *p, const marie_shm_ref_t *ref)
{
    if (ref->size < MARIE_SHM_HOLD_MIN)
        return NULL;
    for (lsub_t *s = ch->subs; s; s = s->next)
        if (!s->removed && s->rv.held)
            return marie_shm_hold(p->r, ref);
    return NULL;
}

/* One message to every subscription: a view into the ring for those that decode in place (then
 * the verdict), held for those that can keep it through the verdict, a checked copy for the
 * others. */
static void deliver(lchan_t *ch, peer_t *p, const marie_shm_ref_t *ref)
{
    int64_t now = marie_wall_us();
    int64_t copied = -1;
    ch->depth++;
    const void *held = hold_for(ch, p, ref);
    for (lsub_t *s = ch->subs; s; s = s->next) {
        if (s->removed)
            continue;
        const void *at = NULL;
        if (s->rv.verdict)
            at = held ? held : marie_shm_peek(p->r, ref);
        else if (copied < 0 && ch->buf)
            copied = marie_shm_read(p->r, ref, ch->buf, ch->t.max_size), at = copied >= 0 ? ch->buf : NULL;
        else if (copied >= 0)
            at = ch->buf;
        if (!at) {
            ch->st.lost++;
            continue;
        }
        marie_bus_recv_t rv = s->rv;
        lcm_recv_buf_t rb = {(void *)at, ref->size, now, ch->lb->bus};
        (held && rv.held && rv.verdict ? rv.held : rv.handler)(&rb, ch->t.channel, rv.user);
        if (rv.verdict) {
            bool ok = marie_shm_still_valid(p->r, ref);
            ch->st.lost += !ok;
            rv.verdict(ok, rv.user);
        }
    }
    if (held)
        marie_shm_release(p->r, ref);
    ch->st.received++;
    if (--ch->depth == 0)
        sweep(ch);
}

/* What one publisher's ring holds for this reader, at most max messages. Each is looked for
 * where it should be first; the ring's newest (the header's line, which the writer changes at
 * every message) is read only when one is not there, and bounds what follows. */
static int follow(lchan_t *ch, peer_t *p, int max)
{
    int n = 0;
    int64_t newest = -1;
    while (p->pid && n < max) {
        marie_shm_ref_t ref;
        int rc = marie_shm_ref_at(p->r, p->segment, p->next, &ref);
        if (rc == 0) {
            p->next++;
            ch->lb->writer_cpu = marie_shm_reader_last_cpu(p->r);
            deliver(ch, p, &ref);
            n++;
            continue;
        }
        int err = errno;
        if (newest < 0 && (newest = marie_shm_newest(p->r, p->segment)) < 0)
            break;
        if (p->next > newest || err == EAGAIN)
            break;                  /* not written yet, or still being written */
        if (err == ESTALE) {        /* overwritten before it was read: skip to the oldest kept */
            int64_t oldest = newest - (int64_t)ch->t.slots + 2;
            ch->st.lost += oldest > p->next ? oldest - p->next : 1;
            p->next = oldest > p->next ? oldest : p->next + 1;
            continue;
        }
        p->next++;
        ch->st.bad++;
    }
    return n;
}

static int bus_handle(void *bus_st, int max)
{
    lbus_t *lb = bus_st;
    /* Publishers ring only a reader that sleeps: one that found its messages while it spun has
     * nothing to drain (a late ring stays until the next sleep: the spin's polls see it and the
     * loop goes round once more meanwhile, nothing is lost). */
    if (lb->bell.fd >= 0 && lb->slept)
        local_bell_drain(&lb->bell);
    lb->slept = false;
    int n = 0;
    for (lchan_t *ch = lb->reading; ch && n < max; ch = ch->next_reading) {
        rescan(ch);
        for (int i = 0; i < LOCAL_PUBS && n < max; i++)
            n += follow(ch, &ch->peers[i], max - n);
    }
    return n;
}

static bool bus_pending(void *bus_st)
{
    for (lchan_t *ch = ((lbus_t *)bus_st)->reading; ch; ch = ch->next_reading)
        if (chan_pending(ch))
            return true;
    return false;
}

/* The flag is stored before the rings are looked at, and a publisher stores its message before
 * it looks at the flag: one of the two sees the other, so no message waits for a doorbell
 * nobody rings. */
static int bus_sleep(void *bus_st, bool on)
{
    lbus_t *lb = bus_st;
    /* Awake again: stored only when the flags say asleep. Each store takes the entry's line
     * from the publishers' CPUs, which look at it at every message. */
    if (!on && !lb->asleep)
        return 0;
    lb->asleep = on;
    int cpu = on ? sched_getcpu() : -1;
    lb->slept |= on;
    for (lchan_t *ch = lb->reading; ch; ch = ch->next_reading) {
        if (on)
            atomic_store(&ch->reg.reg->subs[ch->sub_at].cpu, cpu);
        atomic_store(&ch->reg.reg->subs[ch->sub_at].sleeping, on);
    }
    return on && bus_pending(lb);
}

/* A reader the last publish rang for that still sleeps and most likely waits for this CPU: it
 * went to sleep on it (a doorbell's wake-up tends to put it back there when no CPU is idle), or
 * it has not run WAKING_US after it was rung. The loop does not spin then. */
static bool bus_waking(void *bus_st)
{
    lbus_t *lb = bus_st;
    /* The writer of the last message read committed it on this CPU: it runs here, and its answer
     * comes only once this loop lets go of the CPU (a spin would keep it waiting until the kernel
     * takes the CPU away). */
    if (lb->writer_cpu >= 0 && lb->writer_cpu == sched_getcpu())
        return true;
    bool probe = lb->missed < MISSED_MAX || lb->rings % PROBE_EVERY == 0;
    if (!lb->rang || (!lb->rang_here && probe && marie_mono_us() - lb->rang_at < WAKING_US))
        return false;
    for (uint64_t m = lb->rang; m; m &= m - 1)
        if (atomic_load(&lb->rang_reg->subs[__builtin_ctzll(m)].sleeping)) {
            if (!lb->gave_up && !lb->rang_here && probe && lb->missed < MISSED_MAX)
                lb->missed++;
            lb->gave_up = true;
            return true;
        }
    /* The readers it rang run: on another CPU, as this one is busy spinning. */
    if (!lb->rang_here)
        lb->missed = 0;
    lb->rang = 0;
    return false;
}

static void on_remote(const void *data, size_t len, void *user)
{
    lchan_t *ch = user;
    ch->st.remote++;
    lcm_recv_buf_t rb = {(void *)data, (uint32_t)len, marie_wall_us(), ch->lb->bus};
    ch->depth++;
    for (lsub_t *s = ch->subs; s; s = s->next) {
        if (s->removed)
            continue;
        marie_bus_recv_t rv = s->rv;
        rv.handler(&rb, ch->t.channel, rv.user);
        if (rv.verdict)
            rv.verdict(true, rv.user);      /* LCM's copy is the reader's own */
    }
    if (--ch->depth == 0)
        sweep(ch);
}

/* The first subscription on a channel registers the bus as its reader. */
static int start_reading(lchan_t *ch)
{
    lbus_t *lb = ch->lb;
    if (lb->bell.fd < 0 && local_bell_open(&lb->bell) < 0)
        return -1;
    if (!(ch->buf = malloc(ch->t.max_size)) ||
        !(ch->remote = marie_shm_sub_create(lb->bus, ch->t.channel, ch->t.max_size, on_remote, ch)))
        goto err;
    marie_shm_sub_remote_only(ch->remote);
    if ((ch->sub_at = local_reg_add_sub(&ch->reg, lb->bell.name)) < 0)
        goto err;
    ch->ticket = atomic_load(&ch->reg.reg->subs[ch->sub_at].ticket);
    ch->peers_seen = ch->ticket - 1;
    /* The publishers there already are followed from now: what they publish once the
     * subscription is made is read, as LCM's socket would have it. */
    rescan(ch);
    ch->next_reading = lb->reading;
    lb->reading = ch;
    return 0;
err:
    MARIE_KEEP_ERRNO(marie_shm_sub_destroy(ch->remote); free(ch->buf));
    ch->remote = NULL;
    ch->buf = NULL;
    return -1;
}

static void stop_reading(lchan_t *ch)
{
    for (lchan_t **pp = &ch->lb->reading; *pp; pp = &(*pp)->next_reading)
        if (*pp == ch) {
            *pp = ch->next_reading;
            break;
        }
    local_reg_remove_sub(&ch->reg, ch->sub_at);
    ch->sub_at = -1;
    marie_shm_sub_destroy(ch->remote);
    ch->remote = NULL;
    for (int i = 0; i < LOCAL_PUBS; i++)
        if (ch->peers[i].pid)
            peer_drop(&ch->peers[i]);
    free(ch->buf);
    ch->buf = NULL;
}

static void *chan_subscribe(void *st, const char *channel, const marie_bus_recv_t *rv)
{
    lchan_t *ch = st;
    if (ch->sub_at < 0 && start_reading(ch) < 0)
        return NULL;
    lsub_t *s = MARIE_NEW(lsub_t, .next = ch->subs, .rv = *rv, .ch = ch);
    if (s)
        ch->subs = s;
    return s;
}

/* Subscriptions unsubscribed, freed once no delivery runs; reading stops with the last. */
static void sweep(lchan_t *ch)
{
    for (lsub_t **pp = &ch->subs; *pp;) {
        lsub_t *s = *pp;
        if (s->removed) {
            *pp = s->next;
            free(s);
        } else {
            pp = &s->next;
        }
    }
    if (!ch->subs && ch->sub_at >= 0)
        stop_reading(ch);
}

static void chan_unsubscribe(void *st, void *sub)
{
    lchan_t *ch = st;
    ((lsub_t *)sub)->removed = true;
    if (ch->depth == 0)
        sweep(ch);
}

static marie_bus_sub_stats_t chan_sub_stats(const void *sub) { return ((const lsub_t *)sub)->ch->st; }

static void chan_close(void *st)
{
    lchan_t *ch = st;
    if (ch->lb->rang_reg == ch->reg.reg)
        ch->lb->rang = 0;
    while (ch->subs)
        chan_unsubscribe(ch, ch->subs);
    if (ch->pub_at >= 0)
        local_reg_remove_pub(&ch->reg, ch->pub_at);
    marie_shm_pub_destroy(ch->pub);
    for (int i = 0; i < LOCAL_SUBS; i++)
        if (ch->bell_fd[i] >= 0)
            close(ch->bell_fd[i]);
    local_reg_close(&ch->reg);
    free(ch);
}

const marie_bus_provider_t marie_bus_local = {
    .name = "local",
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
    .close_bus = close_bus,
    .bus_fd = bus_fd,
    .bus_handle = bus_handle,
    .bus_sleep = bus_sleep,
    .bus_pending = bus_pending,
    .bus_waking = bus_waking,
};
