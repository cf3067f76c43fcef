/* balance: the placement decisions of marie-am as a pure state machine (no I/O, no clock). */
#include "managers/balance.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define RING 256

typedef struct {
    int64_t t;
    double v;
} sample_t;

typedef struct {
    sample_t s[RING];
    int head, n;
    int64_t since;          /* first sample after the last reset; 0: none */
} window_t;

typedef struct {
    const char *name;
    double cores_cfg;       /* from balance.capacity, 0: what the manager reports */
    int ncpu;
    int64_t last_heard;     /* 0: never */
    window_t load;          /* sum of its components' CPU %, one sample per status */
} bhost_t;

typedef struct {
    const marie_component_cfg_t *cfg;
    char placed[128];
    bool movable;
    const marie_balance_entry_t *prefer;
    int64_t moved_at;       /* 0: never moved */
    window_t cpu;
    int64_t *running_at;    /* per host: last status saying it runs there */
} bcomp_t;

struct balance {
    const marie_balance_cfg_t *cfg;
    int self;
    bhost_t *hosts;
    size_t nhosts;
    bcomp_t *comps;
    size_t ncomps;
    int64_t term, max_seen;
    bool leading, rival;
    int64_t lead_since, last_move;
};

static void window_reset(window_t *w)
{
    w->head = w->n = 0;
    w->since = 0;
}

static void window_push(window_t *w, int64_t t, double v)
{
    if (!w->since)
        w->since = t;
    w->s[w->head] = (sample_t){t, v};
    w->head = (w->head + 1) % RING;
    if (w->n < RING)
        w->n++;
}

static sample_t *window_last(window_t *w)
{
    return w->n ? &w->s[(w->head + RING - 1) % RING] : NULL;
}

/* Mean over the last `span` µs; -1 until samples cover the whole span. */
static double window_mean(const window_t *w, int64_t now, int64_t span)
{
    if (!w->since || now - w->since < span)
        return -1;
    double sum = 0;
    int k = 0;
    for (int i = 0; i < w->n; i++) {
        const sample_t *s = &w->s[(w->head + RING - 1 - i) % RING];
        if (now - s->t > span)
            break;
        sum += s->v;
        k++;
    }
    return k ? sum / k : -1;
}

static int host_index(const balance_t *b, const char *name)
{
    for (size_t i = 0; i < b->nhosts; i++)
        if (strcmp(b->hosts[i].name, name) == 0)
            return (int)i;
    return -1;
}

static bcomp_t *comp_find(const balance_t *b, const char *name)
{
    for (size_t i = 0; i < b->ncomps; i++)
        if (strcmp(b->comps[i].cfg->name, name) == 0)
            return &b->comps[i];
    return NULL;
}

static int add_host(balance_t *b, const char *name)
{
    if (host_index(b, name) >= 0)
        return 0;
    bhost_t *h = &b->hosts[b->nhosts++];
    h->name = name;
    for (size_t i = 0; i < b->cfg->ncapacity; i++)
        if (strcmp(b->cfg->capacity[i].host, name) == 0)
            h->cores_cfg = b->cfg->capacity[i].cores;
    return 0;
}

balance_t *balance_create(const char *self, const marie_system_t *sys)
{
    balance_t *b = calloc(1, sizeof *b);
    if (!b)
        return NULL;
    b->cfg = &sys->balance;
    size_t maxh = sys->nhosts + sys->ncomponents + 1;
    if (!(b->hosts = calloc(maxh, sizeof *b->hosts)) ||
        !(b->comps = calloc(sys->ncomponents ? sys->ncomponents : 1, sizeof *b->comps)))
        goto err;
    for (size_t i = 0; i < sys->nhosts; i++)
        add_host(b, sys->hosts[i]);
    for (size_t i = 0; i < sys->ncomponents; i++)
        add_host(b, sys->components[i].host);
    add_host(b, self);
    b->self = host_index(b, self);
    for (size_t i = 0; i < sys->ncomponents; i++) {
        bcomp_t *c = &b->comps[b->ncomps++];
        c->cfg = &sys->components[i];
        snprintf(c->placed, sizeof c->placed, "%s", c->cfg->host);
        for (size_t k = 0; k < b->cfg->nmovable; k++)
            c->movable |= strcmp(b->cfg->movable[k], c->cfg->name) == 0;
        for (size_t k = 0; k < b->cfg->nprefer; k++)
            if (strcmp(b->cfg->prefer[k].host, c->cfg->name) == 0)
                c->prefer = &b->cfg->prefer[k];
        if (!(c->running_at = calloc(maxh, sizeof *c->running_at)))
            goto err;
    }
    return b;
err:
    balance_destroy(b);
    errno = ENOMEM;
    return NULL;
}

void balance_destroy(balance_t *b)
{
    if (!b)
        return;
    for (size_t i = 0; i < b->ncomps; i++)
        free(b->comps[i].running_at);
    free(b->comps);
    free(b->hosts);
    free(b);
}

void balance_heard(balance_t *b, const char *host, int64_t term, bool leads, int ncpu, int64_t now_us)
{
    int i = host_index(b, host);
    if (i < 0)
        return;
    bhost_t *h = &b->hosts[i];
    h->last_heard = now_us;
    h->ncpu = ncpu;
    window_push(&h->load, now_us, 0);
    if (term > b->max_seen)
        b->max_seen = term;
    /* Another leader (the other side of a healed partition): lead again under a new term. */
    if (leads && i != b->self && b->leading && term >= b->term)
        b->rival = true;
}

void balance_sample(balance_t *b, const char *host, const char *component, double cpu, bool running,
                    int64_t now_us)
{
    int i = host_index(b, host);
    if (i < 0)
        return;
    /* Everything its manager reports loads a host, known to the system or not. */
    sample_t *last = window_last(&b->hosts[i].load);
    if (last && last->t == now_us)
        last->v += cpu;
    bcomp_t *c = comp_find(b, component);
    if (!c || !running)
        return;
    c->running_at[i] = now_us;
    if (strcmp(c->placed, host) == 0)
        window_push(&c->cpu, now_us, cpu);
}

void balance_placed(balance_t *b, const char *component, const char *host, int64_t now_us)
{
    bcomp_t *c = comp_find(b, component);
    if (!c || strcmp(c->placed, host) == 0)
        return;
    int from = host_index(b, c->placed), to = host_index(b, host);
    snprintf(c->placed, sizeof c->placed, "%s", host);
    c->moved_at = now_us;
    b->last_move = now_us;
    window_reset(&c->cpu);
    /* Both hosts' loads change: decide again only on a whole new window. */
    if (from >= 0)
        window_reset(&b->hosts[from].load);
    if (to >= 0)
        window_reset(&b->hosts[to].load);
}

static bool host_live(const balance_t *b, int i, int64_t now)
{
    return i == b->self ||
           (b->hosts[i].last_heard && now - b->hosts[i].last_heard <= (int64_t)(b->cfg->host_lost_s * 1e6));
}

const char *balance_leader(balance_t *b, int64_t now_us)
{
    const char *best = NULL;
    for (size_t i = 0; i < b->nhosts; i++)
        if (host_live(b, (int)i, now_us) && (!best || strcmp(b->hosts[i].name, best) < 0))
            best = b->hosts[i].name;
    return best;
}

int64_t balance_term(const balance_t *b)
{
    return b->term;
}

bool balance_leads(const balance_t *b)
{
    return b->leading;
}

/* A new leader (or one that hears a higher term) takes a term above every one heard, then
 * waits host_lost before acting: by then every live manager has heard it, and a rival leader
 * from the other side of a healed partition has stepped down. */
bool balance_acting(balance_t *b, int64_t now_us)
{
    b->rival &= b->leading;
    if (!b->cfg->enabled)
        return false;
    bool lead = strcmp(balance_leader(b, now_us), b->hosts[b->self].name) == 0;
    if (!lead) {
        b->leading = false;
        if (b->max_seen > b->term)
            b->term = b->max_seen;
        return false;
    }
    if (!b->leading || b->max_seen > b->term || b->rival) {
        b->rival = false;
        b->term = (b->max_seen > b->term ? b->max_seen : b->term) + 1;
        b->max_seen = b->term;
        b->leading = true;
        b->lead_since = now_us;
    }
    return now_us - b->lead_since >= (int64_t)(b->cfg->host_lost_s * 1e6);
}

const char *balance_placement(const balance_t *b, const char *component)
{
    const bcomp_t *c = comp_find(b, component);
    return c ? c->placed : NULL;
}

static double host_cores(const bhost_t *h)
{
    return h->cores_cfg > 0 ? h->cores_cfg : h->ncpu > 0 ? h->ncpu : 1;
}

double balance_load(const balance_t *b, const char *host, int64_t now_us)
{
    int i = host_index(b, host);
    if (i < 0)
        return -1;
    double m = window_mean(&b->hosts[i].load, now_us, (int64_t)(b->cfg->window_s * 1e6));
    return m < 0 ? -1 : m / (100.0 * host_cores(&b->hosts[i]));
}

static bool preferred(const bcomp_t *c, const char *host, int *rank)
{
    for (size_t k = 0; c->prefer && k < c->prefer->nhosts; k++)
        if (strcmp(c->prefer->hosts[k], host) == 0) {
            *rank = (int)k;
            return true;
        }
    *rank = 1 << 20;
    return false;
}

/* The best live host other than `avoid` for a component adding `cpu` %: preferred hosts in
 * their order, then the least loaded after the move. With `limit` >= 0, only hosts whose
 * window is covered and whose load stays under it. -1 when none. */
static int pick_target(balance_t *b, const bcomp_t *c, int avoid, double cpu, double limit, int64_t now)
{
    int best = -1, best_rank = 0;
    double best_after = 0;
    for (size_t i = 0; i < b->nhosts; i++) {
        if ((int)i == avoid || !host_live(b, (int)i, now))
            continue;
        double load = balance_load(b, b->hosts[i].name, now);
        if (limit >= 0 && load < 0)
            continue;
        double after = (load < 0 ? 0 : load) + cpu / (100.0 * host_cores(&b->hosts[i]));
        if (limit >= 0 && after > limit)
            continue;
        int rank;
        preferred(c, b->hosts[i].name, &rank);
        if (best < 0 || rank < best_rank || (rank == best_rank && after < best_after)) {
            best = (int)i;
            best_rank = rank;
            best_after = after;
        }
    }
    return best;
}

static int make_move(balance_move_t *out, balance_why_t why, const bcomp_t *c, const char *from, const char *to)
{
    out->why = why;
    snprintf(out->component, sizeof out->component, "%s", c->cfg->name);
    snprintf(out->from, sizeof out->from, "%s", from);
    snprintf(out->to, sizeof out->to, "%s", to);
    return 1;
}

static int step_failover(balance_t *b, int64_t now, balance_move_t *out)
{
    for (size_t k = 0; k < b->ncomps; k++) {
        bcomp_t *c = &b->comps[k];
        int at = host_index(b, c->placed);
        if (!c->movable || at < 0 || host_live(b, at, now) || !b->hosts[at].last_heard)
            continue;
        double cpu = window_mean(&c->cpu, now, (int64_t)(b->cfg->window_s * 1e6));
        int to = pick_target(b, c, at, cpu < 0 ? 0 : cpu, -1, now);
        if (to < 0)
            continue;
        snprintf(out->reason, sizeof out->reason, "%s lost (unheard for %.1f s): %s starts on %s", c->placed,
                 (double)(now - b->hosts[at].last_heard) * 1e-6, c->cfg->name, b->hosts[to].name);
        return make_move(out, BALANCE_FAILOVER, c, c->placed, b->hosts[to].name);
    }
    return 0;
}

/* Running where it is not placed, after the old copy has had time to stop: a partition
 * healed, or a manager came back with an old placement. The placement wins. */
static int step_duplicates(balance_t *b, int64_t now, balance_move_t *out)
{
    int64_t fresh = (int64_t)(b->cfg->host_lost_s * 1e6);
    for (size_t k = 0; k < b->ncomps; k++) {
        bcomp_t *c = &b->comps[k];
        int64_t grace = c->moved_at + (int64_t)((c->cfg->stop_timeout_s + 2 * b->cfg->host_lost_s + 1) * 1e6);
        int at = host_index(b, c->placed);
        for (size_t i = 0; i < b->nhosts; i++) {
            int64_t seen = c->running_at[i];
            if ((int)i == at || !seen || now - seen > fresh || seen < grace || !host_live(b, (int)i, now))
                continue;
            snprintf(out->reason, sizeof out->reason, "%s runs on %s and %s: it stays on %s only",
                     c->cfg->name, b->hosts[i].name, c->placed, c->placed);
            return make_move(out, BALANCE_DUPLICATE, c, b->hosts[i].name, c->placed);
        }
    }
    return 0;
}

static int step_overload(balance_t *b, int64_t now, balance_move_t *out)
{
    int64_t cool = (int64_t)(b->cfg->cooldown_s * 1e6), span = (int64_t)(b->cfg->window_s * 1e6);
    if (b->last_move && now - b->last_move < cool)
        return 0;
    int worst = -1;
    double worst_load = b->cfg->high;
    for (size_t i = 0; i < b->nhosts; i++) {
        double l = balance_load(b, b->hosts[i].name, now);
        if (host_live(b, (int)i, now) && l > worst_load) {
            worst = (int)i;
            worst_load = l;
        }
    }
    if (worst < 0)
        return 0;
    /* The busiest movable component that fits somewhere under `low`. */
    const bcomp_t *pick = NULL;
    int to = -1;
    double pick_cpu = -1;
    for (size_t k = 0; k < b->ncomps; k++) {
        bcomp_t *c = &b->comps[k];
        if (!c->movable || strcmp(c->placed, b->hosts[worst].name) != 0 ||
            (c->moved_at && now - c->moved_at < cool))
            continue;
        double cpu = window_mean(&c->cpu, now, span);
        if (cpu <= pick_cpu)
            continue;
        int t = pick_target(b, c, worst, cpu, b->cfg->low, now);
        if (t >= 0) {
            pick = c;
            pick_cpu = cpu;
            to = t;
        }
    }
    if (!pick)
        return 0;
    snprintf(out->reason, sizeof out->reason, "%s at %.0f%% of its cores over %.0f s: %s (%.0f%% CPU) moves to %s",
             b->hosts[worst].name, worst_load * 100, b->cfg->window_s, pick->cfg->name, pick_cpu, b->hosts[to].name);
    return make_move(out, BALANCE_OVERLOAD, pick, b->hosts[worst].name, b->hosts[to].name);
}

int balance_step(balance_t *b, int64_t now_us, balance_move_t *out)
{
    if (!balance_acting(b, now_us))
        return 0;
    return step_failover(b, now_us, out) || step_duplicates(b, now_us, out) || step_overload(b, now_us, out);
}
