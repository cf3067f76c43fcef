/* bus: the one interface (core/bus/bus.h): a bus's own provider, chosen by its URL, and the
 * channels that transports move to providers of their own. */
#include "core/bus/bus.h"

#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/bus/provider.h"
#include "core/config.h"
#include "core/err.h"
#include "core/log.h"
#include "lcmtypes/marie_types.h"

/* The bus's own providers, asked in this order for its URL; then those a channel may move to. */
static const marie_bus_provider_t *const own_providers[] = {&marie_bus_udpm, &marie_bus_liblcm};
static const marie_bus_provider_t *const channel_providers[] = {&marie_bus_shm, &marie_bus_local};
#define NCHANNEL_PROVIDERS (sizeof channel_providers / sizeof *channel_providers)

typedef struct route {
    struct route *next;
    char *channel, *kind;
    marie_bus_transport_t t;        /* its strings are channel and kind above */
    const marie_bus_provider_t *p;
    size_t pi;                      /* p's index in channel_providers */
    void *st;                       /* opened at first use */
} route_t;

struct marie_bus_sub {
    struct marie_bus_sub *next;
    const marie_bus_provider_t *p;
    void *st;                       /* the provider's state it was made on */
    void *ps;                       /* the provider's subscription */
};

typedef struct bus {
    struct bus *next;
    lcm_t *lcm;
    bool own_handle;                /* lcm is marie's address, not liblcm's (handle_new) */
    const marie_bus_provider_t *p;
    void *st;
    route_t *routes;
    marie_bus_sub_t *subs;          /* let go at destroy, those not unsubscribed */
    void *chan_st[NCHANNEL_PROVIDERS];  /* each channel provider's state for the bus, or NULL */
} bus_t;

/* The buses made, for lookups by lcm_t: guarded, since any thread may publish. */
static bus_t *buses;
static pthread_mutex_t buses_lock = PTHREAD_MUTEX_INITIALIZER;

/* The bus this thread is destroying: taken from the list, it is still found while its channels
 * close (they let their subscriptions go and may publish on it). */
static __thread bus_t *destroying;

/* Each destroy counts here; a thread keeps the last bus it found until the count moves (a
 * spinning loop asks for its bus every few hundred ns). */
static _Atomic uint64_t buses_gone;
static __thread struct {
    const lcm_t *lcm;
    bus_t *b;
    uint64_t gone;
} last_found;

static bus_t *find(const lcm_t *lcm)
{
    uint64_t gone = atomic_load_explicit(&buses_gone, memory_order_acquire);
    if (last_found.lcm == lcm && last_found.gone == gone && lcm)
        return last_found.b;
    pthread_mutex_lock(&buses_lock);
    bus_t *b = buses;
    while (b && b->lcm != lcm)
        b = b->next;
    pthread_mutex_unlock(&buses_lock);
    if (b)
        last_found.lcm = lcm, last_found.b = b, last_found.gone = gone;
    return b ? b : destroying && destroying->lcm == lcm ? destroying : NULL;
}

/* The bus lcm names; one marie did not make (plain lcm_create(): a tool's, a test's peer) is
 * liblcm's, described in *plain. NULL for NULL. */
static bus_t *bus_of(const lcm_t *lcm, bus_t *plain)
{
    bus_t *b = lcm ? find(lcm) : NULL;
    if (b || !lcm)
        return b;
    *plain = (bus_t){.lcm = (lcm_t *)lcm, .p = &marie_bus_liblcm, .st = (void *)lcm};
    return plain;
}

/* The bus's handle when marie reads and sends it itself and the program does not call liblcm:
 * an address of marie's own, so that liblcm is never loaded. A program that links liblcm may
 * hand the handle to liblcm's functions (a generated type's _publish): it gets liblcm's. */
static lcm_t *handle_new(const char *url, bool own)
{
    if (own)
        return malloc(1);
    const marie_liblcm_t *l = marie_liblcm();
    lcm_t *lcm = l ? l->create(url) : NULL;
    return lcm ? lcm : marie_fail_null(EINVAL);
}

static void handle_free(lcm_t *lcm, bool own)
{
    if (own)
        free(lcm);
    else
        marie_liblcm()->destroy(lcm);
}

/* The handle of the bus being opened on this thread, when it is marie's own. */
static __thread const lcm_t *opening_own;

/* Opens the bus's own provider on b->lcm; b->own_handle cleared when liblcm has to read it. */
static int open_own(bus_t *b, const char *url)
{
    for (size_t i = 0; i < sizeof own_providers / sizeof *own_providers && !b->st; i++) {
        if (own_providers[i] == &marie_bus_liblcm && b->own_handle) {
            /* marie does not read this URL itself: liblcm's handle after all */
            lcm_t *lcm = handle_new(url, false);
            if (!lcm)
                return -1;
            free(b->lcm);
            b->lcm = lcm;
            b->own_handle = false;
        }
        opening_own = b->own_handle ? b->lcm : NULL;
        if ((b->st = own_providers[i]->open(b->lcm, url)))
            b->p = own_providers[i];
        opening_own = NULL;
    }
    return b->st ? 0 : -1;
}

lcm_t *marie_bus_create(const char *url)
{
    if (!url)
        url = marie_default_url();
    bus_t *b = calloc(1, sizeof *b);
    if (!b)
        return NULL;
    b->own_handle = !marie_liblcm_in_process();
    if (!(b->lcm = handle_new(url, b->own_handle))) {
        MARIE_KEEP_ERRNO(free(b));
        return NULL;
    }
    if (open_own(b, url) < 0) {
        MARIE_KEEP_ERRNO(handle_free(b->lcm, b->own_handle); free(b));
        return NULL;
    }
    pthread_mutex_lock(&buses_lock);
    b->next = buses;
    buses = b;
    pthread_mutex_unlock(&buses_lock);
    return b->lcm;
}

/* Lets s go; one not on the bus's list was let go already (with the bus: a channel closing
 * after it asks again). */
static void sub_drop(bus_t *b, marie_bus_sub_t *s)
{
    marie_bus_sub_t **pp = &b->subs;
    while (*pp && *pp != s)
        pp = &(*pp)->next;
    if (!*pp)
        return;
    *pp = s->next;
    s->p->unsubscribe(s->st, s->ps);
    free(s);
}

static void route_free(route_t *r)
{
    if (r->st)
        r->p->close(r->st);
    free(r->channel);
    free(r->kind);
    free(r);
}

void marie_bus_destroy(lcm_t *lcm)
{
    if (!lcm)
        return;
    bus_t *b = NULL;
    pthread_mutex_lock(&buses_lock);
    for (bus_t **pp = &buses; *pp; pp = &(*pp)->next)
        if ((*pp)->lcm == lcm) {
            b = *pp;
            *pp = b->next;
            atomic_fetch_add_explicit(&buses_gone, 1, memory_order_release);
            break;
        }
    pthread_mutex_unlock(&buses_lock);
    if (!b)
        return;
    destroying = b;
    while (b->subs)
        sub_drop(b, b->subs);
    while (b->routes) {     /* before the bus's own provider: they unsubscribe from it */
        route_t *n = b->routes->next;
        route_free(b->routes);
        b->routes = n;
    }
    for (size_t i = 0; i < NCHANNEL_PROVIDERS; i++)
        if (b->chan_st[i])
            channel_providers[i]->close_bus(b->chan_st[i]);
    destroying = NULL;
    b->p->close(b->st);
    handle_free(b->lcm, b->own_handle);
    free(b);
}

/* ---- transports ---- */

static route_t *route_named(const bus_t *b, const char *channel)
{
    for (route_t *r = b->routes; r && channel; r = r->next)
        if (strcmp(r->channel, channel) == 0)
            return r;
    return NULL;
}

/* The channel's route with its provider open, or NULL (the bus's own carries it); *err when
 * the route's provider could not open. */
static route_t *route_open(bus_t *b, const char *channel, int *err)
{
    route_t *r = route_named(b, channel);
    *err = 0;
    if (r && !r->st && !(r->st = r->p->open_channel(b->lcm, &r->t, &b->chan_st[r->pi])))
        *err = errno ? errno : EIO;
    return r;
}

int marie_bus_set_transport(lcm_t *lcm, const marie_bus_transport_t *t)
{
    bus_t *b = find(lcm);
    if (!b || !t || !t->channel || !t->kind)
        return marie_fail(EINVAL);
    const marie_bus_provider_t *p = NULL;
    size_t pi = 0;
    for (size_t i = 0; i < NCHANNEL_PROVIDERS; i++)
        if (strcmp(channel_providers[i]->name, t->kind) == 0)
            p = channel_providers[pi = i];
    route_t *old = route_named(b, t->channel);
    if (old && old->st)
        return marie_fail(EEXIST);
    if (!p && strcmp(t->kind, "lcm") != 0)
        return marie_fail(EINVAL);
    for (route_t **pp = &b->routes; old && *pp; pp = &(*pp)->next)
        if (*pp == old) {
            *pp = old->next;
            route_free(old);
            break;
        }
    if (!p)
        return 0;           /* on the bus's own provider, as if not listed */
    route_t *r = calloc(1, sizeof *r);
    if (!r || !(r->channel = strdup(t->channel)) || !(r->kind = strdup(t->kind))) {
        if (r)
            route_free(r);
        return marie_fail(ENOMEM);
    }
    r->t = *t;
    r->t.channel = r->channel;
    r->t.kind = r->kind;
    r->p = p;
    r->pi = pi;
    r->next = b->routes;
    b->routes = r;
    return 0;
}

int marie_bus_set_transports(lcm_t *lcm, const marie_system_t *sys)
{
    for (size_t i = 0; sys && i < sys->ntransports; i++) {
        const marie_transport_cfg_t *c = &sys->transports[i];
        marie_bus_transport_t t = {c->channel, c->kind, c->max_size, c->slots};
        if (marie_bus_set_transport(lcm, &t) < 0)
            return -1;
    }
    return 0;
}

/* ---- publishing ---- */

int marie_bus_publish(lcm_t *lcm, const char *channel, const void *data, size_t len)
{
    bus_t plain, *b = bus_of(lcm, &plain);
    if (!b || !channel || (!data && len))
        return marie_fail(EINVAL);
    int err;
    route_t *r = route_open(b, channel, &err);
    if (err)
        return marie_fail(err);
    return r ? r->p->publish(r->st, channel, data, len) : b->p->publish(b->st, channel, data, len);
}

int marie_bus_publish_own(lcm_t *lcm, const char *channel, const void *data, size_t len)
{
    bus_t plain, *b = bus_of(lcm, &plain);
    if (!b || !channel || (!data && len))
        return marie_fail(EINVAL);
    return b->p->publish(b->st, channel, data, len);
}

int marie_bus_publish_with(lcm_t *lcm, const char *channel, size_t len, marie_bus_fill_t fill, void *user)
{
    bus_t plain, *b = bus_of(lcm, &plain);
    if (!b || !channel || !fill)
        return marie_fail(EINVAL);
    int err;
    route_t *r = route_open(b, channel, &err);
    if (err)
        return marie_fail(err);
    if (r && r->p->publish_with)
        return r->p->publish_with(r->st, len, fill, user);
    uint8_t small[2048];    /* heartbeats, events, replies: no allocation */
    uint8_t *buf = len <= sizeof small ? small : malloc(len);
    if (!buf)
        return -1;
    int rc = fill(buf, len, user) == 0 ? marie_bus_publish(lcm, channel, buf, len) : marie_fail(EINVAL);
    if (buf != small)
        MARIE_KEEP_ERRNO(free(buf));
    return rc;
}

typedef struct {
    const marie_type_t *t;
    const void *msg;
} encoding_t;

static int encode_into(void *dst, size_t len, void *user)
{
    const encoding_t *e = user;
    return e->t->encode(dst, 0, (int)len, e->msg) == (int)len ? 0 : -1;
}

int marie_bus_publish_msg(lcm_t *lcm, const char *channel, const marie_type_t *t, const void *msg)
{
    int size = t->encoded_size(msg);
    if (size < 0)
        return marie_fail(EINVAL);
    return marie_bus_publish_with(lcm, channel, (size_t)size, encode_into, &(encoding_t){t, msg});
}

int marie_bus_publish_batch(lcm_t *lcm, const marie_bus_msg_t *m, int n, int *rc)
{
    bus_t plain, *b = bus_of(lcm, &plain);
    int sent = 0;
    for (int i = 0; i < n;) {
        int k = 0;      /* a run the bus's own provider carries, sent together */
        while (b && b->p->publish_batch && i + k < n && !route_named(b, m[i + k].channel))
            k++;
        if (k > 1) {
            sent += b->p->publish_batch(b->st, m + i, k, rc + i);
            i += k;
            continue;
        }
        rc[i] = marie_bus_publish(lcm, m[i].channel, m[i].data, m[i].len);
        sent += rc[i] == 0;
        i++;
    }
    return sent;
}

void *marie_bus_loan(lcm_t *lcm, const char *channel)
{
    bus_t plain, *b = bus_of(lcm, &plain);
    int err = 0;
    route_t *r = b ? route_open(b, channel, &err) : NULL;
    if (err)
        return marie_fail_null(err);
    if (!r || !r->p->loan)
        return marie_fail_null(ENOTSUP);
    return r->p->loan(r->st);
}

int marie_bus_commit(lcm_t *lcm, const char *channel, size_t len)
{
    bus_t plain, *b = bus_of(lcm, &plain);
    route_t *r = b ? route_named(b, channel) : NULL;
    if (!r || !r->st || !r->p->commit)
        return marie_fail(EINVAL);
    return r->p->commit(r->st, len);
}

int marie_bus_prepare(lcm_t *lcm, const char *channel)
{
    bus_t plain, *b = bus_of(lcm, &plain);
    if (!b)
        return marie_fail(EINVAL);
    int err;
    route_t *r = route_open(b, channel, &err);
    if (err)
        return marie_fail(err);
    return r && r->p->prepare ? r->p->prepare(r->st) : 0;
}

/* ---- subscribing ---- */

/* The channel a pattern names when it matches one name only: a plain name, or one whose special
 * characters are all escaped (ca_channel_pattern's); else false. */
static bool named(const char *pattern, char *out, size_t cap)
{
    size_t n = 0;
    for (const char *p = pattern; *p; p++) {
        if (*p == '\\') {
            if (!p[1] || !strchr(".^$|()[]{}*+?\\", p[1]))
                return false;
            p++;
        } else if (strchr(".^$|()[]{}*+?", *p)) {
            return false;
        }
        if (n + 1 >= cap)
            return false;
        out[n++] = *p;
    }
    out[n] = '\0';
    return n > 0;
}

static marie_bus_sub_t *subscribe(lcm_t *lcm, const char *channel, const marie_bus_recv_t *rv, bool own)
{
    bus_t *b = lcm ? find(lcm) : NULL;
    if (!lcm || !channel || !rv->handler)
        return marie_fail_null(EINVAL);
    if (!b) {       /* a plain lcm_create()'s bus: liblcm's own subscription stands for it */
        const marie_liblcm_t *l = marie_liblcm();
        lcm_subscription_t *ls = rv->verdict || !l ? NULL : l->subscribe(lcm, channel, rv->handler, rv->user);
        if (!ls)
            return marie_fail_null(rv->verdict ? EINVAL : EIO);
        l->subscription_set_queue_capacity(ls, MARIE_BUS_QUEUE);
        return (marie_bus_sub_t *)ls;
    }
    /* A name a transport moved, written plainly or with its special characters escaped. */
    char name[LCM_MAX_CHANNEL_NAME_LENGTH + 1];
    const char *moved = own ? NULL : route_named(b, channel) ? channel : named(channel, name, sizeof name) ? name : NULL;
    int err = 0;
    route_t *r = moved ? route_open(b, moved, &err) : NULL;
    if (err)
        return marie_fail_null(err);
    marie_bus_sub_t *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    *s = r ? (marie_bus_sub_t){NULL, r->p, r->st, NULL} : (marie_bus_sub_t){NULL, b->p, b->st, NULL};
    if (!(s->ps = s->p->subscribe(s->st, r ? moved : channel, rv))) {
        MARIE_KEEP_ERRNO(free(s));
        return NULL;
    }
    /* Linked only now: a channel's provider subscribes on the bus itself meanwhile (a ring's
     * notices and copies), and those must stay on the list to be let go. */
    s->next = b->subs;
    b->subs = s;
    return s;
}

marie_bus_sub_t *marie_bus_subscribe(lcm_t *lcm, const char *channel, lcm_msg_handler_t handler, void *user)
{
    return subscribe(lcm, channel, &(marie_bus_recv_t){handler, NULL, user}, false);
}

marie_bus_sub_t *marie_bus_subscribe_in_place(lcm_t *lcm, const char *channel, lcm_msg_handler_t handler,
                                              lcm_msg_handler_t held, marie_bus_verdict_t verdict, void *user)
{
    return subscribe(lcm, channel, &(marie_bus_recv_t){handler, verdict, user, held}, false);
}

marie_bus_sub_t *marie_bus_subscribe_own(lcm_t *lcm, const char *channel, lcm_msg_handler_t handler, void *user)
{
    return subscribe(lcm, channel, &(marie_bus_recv_t){handler, NULL, user}, true);
}

void marie_bus_unsubscribe(lcm_t *lcm, marie_bus_sub_t *s)
{
    if (!s)
        return;
    bus_t *b = find(lcm);
    if (b)
        sub_drop(b, s);
    else
        marie_liblcm()->unsubscribe(lcm, (lcm_subscription_t *)s);
}

marie_bus_sub_stats_t marie_bus_sub_stats(const lcm_t *lcm, const marie_bus_sub_t *s)
{
    return s && find(lcm) && s->p->sub_stats ? s->p->sub_stats(s->ps) : (marie_bus_sub_stats_t){0};
}

/* ---- the loop's side ---- */

int marie_bus_fd(lcm_t *lcm)
{
    bus_t plain, *b = bus_of(lcm, &plain);
    return b ? b->p->fd(b->st) : -1;
}

int marie_bus_handle(lcm_t *lcm, int max)
{
    bus_t plain, *b = bus_of(lcm, &plain);
    return b ? b->p->handle(b->st, max) : 0;
}

/* The channel providers' own parts (the fast path's doorbell). One provider has them. */
static const marie_bus_provider_t *bus_part(const bus_t *b, void **st)
{
    for (size_t i = 0; b && i < NCHANNEL_PROVIDERS; i++)
        if (b->chan_st[i] && channel_providers[i]->bus_fd) {
            *st = b->chan_st[i];
            return channel_providers[i];
        }
    return NULL;
}

int marie_bus_wake_fd(lcm_t *lcm)
{
    void *st;
    const marie_bus_provider_t *p = bus_part(find(lcm), &st);
    return p ? p->bus_fd(st) : -1;
}

int marie_bus_handle_wake(lcm_t *lcm, int max)
{
    void *st;
    const marie_bus_provider_t *p = bus_part(find(lcm), &st);
    return p ? p->bus_handle(st, max) : 0;
}

int marie_bus_sleep(lcm_t *lcm, bool on)
{
    void *st;
    const marie_bus_provider_t *p = bus_part(find(lcm), &st);
    return p ? p->bus_sleep(st, on) : 0;
}

bool marie_bus_pending(lcm_t *lcm)
{
    void *st;
    const marie_bus_provider_t *p = bus_part(find(lcm), &st);
    return p && p->bus_pending(st);
}

bool marie_bus_waking(lcm_t *lcm)
{
    void *st;
    const marie_bus_provider_t *p = bus_part(find(lcm), &st);
    return p && p->bus_waking && p->bus_waking(st);
}

void marie_bus_stats(const lcm_t *lcm, marie_bus_stats_t *st)
{
    bus_t plain;
    const bus_t *b = bus_of(lcm, &plain);
    *st = (marie_bus_stats_t){0};
    if (b && b->p->stats)
        b->p->stats(b->st, st);
}

int marie_bus_native(const lcm_t *lcm)
{
    const bus_t *b = find(lcm);
    return b && b->p == &marie_bus_udpm;
}

int marie_bus_sends(const lcm_t *lcm)
{
    bus_t plain;
    const bus_t *b = bus_of(lcm, &plain);
    return b && b->p->sends && b->p->sends(b->st);
}

/* ---- the generated types' calls ----
 * lcm-gen's TYPE_publish(), _subscribe(), _unsubscribe() and _subscription_set_queue_capacity()
 * call liblcm; libmarie compiles them calling these instead (lcmtypes/module.mk renames the
 * four), so that a program using marie's types need not load liblcm. On a bus with marie's own
 * handle they are the bus's calls; on a bus liblcm made, liblcm's, as before. */
static bool own_bus(const lcm_t *lcm)
{
    const bus_t *b = find(lcm);
    return b && b->own_handle;
}

bool marie_bus_handle_is_liblcm(const lcm_t *lcm) { return lcm != opening_own && !own_bus(lcm); }

int marie_lcm_publish(lcm_t *lcm, const char *channel, const void *data, unsigned int len)
{
    if (own_bus(lcm))
        return marie_bus_publish(lcm, channel, data, len);
    const marie_liblcm_t *l = marie_liblcm();
    return l ? l->publish(lcm, channel, data, len) : -1;
}

lcm_subscription_t *marie_lcm_subscribe(lcm_t *lcm, const char *channel, lcm_msg_handler_t handler, void *user)
{
    if (own_bus(lcm))
        return (lcm_subscription_t *)marie_bus_subscribe(lcm, channel, handler, user);
    const marie_liblcm_t *l = marie_liblcm();
    return l ? l->subscribe(lcm, channel, handler, user) : NULL;
}

int marie_lcm_unsubscribe(lcm_t *lcm, lcm_subscription_t *s)
{
    if (own_bus(lcm)) {
        marie_bus_unsubscribe(lcm, (marie_bus_sub_t *)s);
        return 0;
    }
    const marie_liblcm_t *l = marie_liblcm();
    return l ? l->unsubscribe(lcm, s) : -1;
}

/* Whether s is a subscription on a bus with marie's own handle. */
static bool own_sub(const lcm_subscription_t *s)
{
    bool found = false;
    pthread_mutex_lock(&buses_lock);
    for (const bus_t *b = buses; b && !found; b = b->next)
        for (const marie_bus_sub_t *m = b->own_handle ? b->subs : NULL; m && !found; m = m->next)
            found = (const void *)m == (const void *)s;
    pthread_mutex_unlock(&buses_lock);
    return found;
}

/* marie's subscriptions keep MARIE_BUS_QUEUE messages, whatever is asked. */
int marie_lcm_subscription_set_queue_capacity(lcm_subscription_t *s, int n)
{
    if (own_sub(s))
        return 0;
    const marie_liblcm_t *l = marie_liblcm();
    return l ? l->subscription_set_queue_capacity(s, n) : -1;
}
