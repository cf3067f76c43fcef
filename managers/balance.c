/* balance: the placement decisions of marie-am as a pure state machine (no I/O, no clock). */
#include "managers/balance.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"

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
    const marie_node_t *prefer;     /* its list of hosts, or NULL */
    int64_t moved_at;       /* 0: never moved */
    window_t cpu;
    int64_t *running_at;    /* per host: last status saying it runs there */
} bcomp_t;

struct balance {
    const balance_cfg_t *cfg;
    int self;
    bhost_t *hosts;
    size_t nhosts;
    bcomp_t *comps;
    size_t ncomps;
    int64_t term, max_seen;
    bool leading, rival;
    int64_t lead_since, last_move;
};

/* Position of `name` in a list node (a scalar counts as a list of one); -1 if absent. */
static int seq_has(const marie_node_t *list, const char *name)
{
    if (!list)
        return -1;
    if (list->kind == MARIE_NODE_SCALAR)
        return strcmp(list->value, name) == 0 ? 0 : -1;
    for (size_t i = 0; i < list->n; i++)
        if (list->items[i]->kind == MARIE_NODE_SCALAR && strcmp(list->items[i]->value, name) == 0)
            return (int)i;
    return -1;
}

static bool host_declared(const marie_system_t *sys, const char *h)
{
    for (size_t i = 0; i < sys->nhosts; i++)
        if (strcmp(sys->hosts[i], h) == 0)
            return true;
    for (size_t i = 0; i < sys->ncomponents; i++)
        if (sys->components[i].host && strcmp(sys->components[i].host, h) == 0)
            return true;
    return false;
}

static int read_number(const marie_node_t *sec, const char *key, double *out, marie_errors_t *errs)
{
    const marie_node_t *n = marie_node_get(sec, key);
    if (!n)
        return 0;
    if (marie_node_double(n, out, errs) < 0)
        return -1;
    if (*out < 0) {
        marie_node_error(errs, n, "balance: %s must not be negative", key);
        return -1;
    }
    return 0;
}

/* Every item of a list (or a scalar) must name a component (hosts = false) or a host. */
static int check_names(const marie_system_t *sys, const marie_node_t *list, bool hosts, const char *what,
                       marie_errors_t *errs)
{
    if (list->kind == MARIE_NODE_MAP) {
        marie_node_error(errs, list, "balance: %s: expected a list", what);
        return -1;
    }
    int rc = 0;
    size_t n = list->kind == MARIE_NODE_SCALAR ? 1 : list->n;
    for (size_t i = 0; i < n; i++) {
        const marie_node_t *it = list->kind == MARIE_NODE_SCALAR ? list : list->items[i];
        const char *v = it->kind == MARIE_NODE_SCALAR ? it->value : NULL;
        if (!v || (hosts ? !host_declared(sys, v) : !marie_system_component(sys, v))) {
            marie_node_error(errs, it, "balance: %s names unknown %s '%s'", what, hosts ? "host" : "component",
                             v ? v : "(not a name)");
            rc = -1;
        }
    }
    return rc;
}

int balance_read_cfg(const marie_system_t *sys, balance_cfg_t *cfg, marie_errors_t *errs)
{
    *cfg = (balance_cfg_t){.window_s = 10, .high = 0.85, .low = 0.6, .cooldown_s = 30, .host_lost_s = 2};
    const marie_node_t *n = marie_node_get(marie_doc_root(sys->doc), "balance");
    if (!n)
        return 0;
    static const char *const keys[] = {"window", "high", "low", "cooldown", "host_lost", "movable",
                                       "capacity", "prefer", NULL};
    if (n->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, n, "balance: expected a mapping");
        return -1;
    }
    if (marie_node_check_keys(n, keys, "balance", errs) < 0)
        return -1;
    cfg->enabled = true;
    int rc = read_number(n, "window", &cfg->window_s, errs) | read_number(n, "cooldown", &cfg->cooldown_s, errs) |
             read_number(n, "host_lost", &cfg->host_lost_s, errs) | read_number(n, "high", &cfg->high, errs) |
             read_number(n, "low", &cfg->low, errs);
    if (rc == 0 && !(cfg->low < cfg->high && cfg->high <= 1.0 && cfg->window_s > 0 && cfg->host_lost_s > 0)) {
        marie_node_error(errs, n, "balance: needs 0 <= low < high <= 1, window > 0 and host_lost > 0 "
                         "(low %g, high %g, window %g, host_lost %g)", cfg->low, cfg->high, cfg->window_s,
                         cfg->host_lost_s);
        rc = -1;
    }
    if ((cfg->movable = marie_node_get(n, "movable")))
        rc |= check_names(sys, cfg->movable, false, "movable", errs);
    cfg->capacity = marie_node_get(n, "capacity");
    cfg->prefer = marie_node_get(n, "prefer");
    if ((cfg->capacity && cfg->capacity->kind != MARIE_NODE_MAP) || (cfg->prefer && cfg->prefer->kind != MARIE_NODE_MAP)) {
        marie_node_error(errs, n, "balance: capacity and prefer are mappings");
        return -1;
    }
    for (size_t i = 0; cfg->capacity && i < cfg->capacity->n; i++) {
        const marie_node_t *c = cfg->capacity->items[i];
        double cores = 0;
        if (!host_declared(sys, c->key)) {
            marie_node_error(errs, c, "balance: capacity names unknown host '%s'", c->key);
            rc = -1;
        } else if (marie_node_double(c, &cores, errs) < 0 || cores <= 0) {
            if (cores <= 0)
                marie_node_error(errs, c, "balance: capacity of %s must be a positive number of cores", c->key);
            rc = -1;
        }
    }
    for (size_t i = 0; cfg->prefer && i < cfg->prefer->n; i++) {
        const marie_node_t *p = cfg->prefer->items[i];
        if (!marie_system_component(sys, p->key)) {
            marie_node_error(errs, p, "balance: prefer names unknown component '%s'", p->key);
            rc = -1;
        }
        rc |= check_names(sys, p, true, "prefer", errs);
    }
    return rc ? -1 : 0;
}

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
    const marie_node_t *cores = marie_node_get(b->cfg->capacity, name);
    if (cores)
        marie_node_double(cores, &h->cores_cfg, NULL);
    return 0;
}

balance_t *balance_create(const char *self, const marie_system_t *sys, const balance_cfg_t *cfg)
{
    balance_t *b = calloc(1, sizeof *b);
    if (!b)
        return NULL;
    b->cfg = cfg;
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
        c->movable = seq_has(cfg->movable, c->cfg->name) >= 0;
        c->prefer = marie_node_get(cfg->prefer, c->cfg->name);
        if (!(c->running_at = calloc(maxh, sizeof *c->running_at)))
            goto err;
    }
    return b;
err:
    balance_destroy(b);
    return marie_fail_null(ENOMEM);
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

static double balance_load(const balance_t *b, const char *host, int64_t now_us)
{
    int i = host_index(b, host);
    if (i < 0)
        return -1;
    double m = window_mean(&b->hosts[i].load, now_us, (int64_t)(b->cfg->window_s * 1e6));
    return m < 0 ? -1 : m / (100.0 * host_cores(&b->hosts[i]));
}

/* Preferred hosts first, in their order. */
static int preference(const bcomp_t *c, const char *host)
{
    int k = seq_has(c->prefer, host);
    return k >= 0 ? k : 1 << 20;
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
        int rank = preference(c, b->hosts[i].name);
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
