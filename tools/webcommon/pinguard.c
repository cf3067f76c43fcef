/* pinguard: the web pages' PIN check against guessing (delays, lockouts, constant time). */
#include "tools/webcommon/pinguard.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <sodium.h>

#define MAX_ADDRS 256           /* addresses remembered; the one unheard longest makes room */

/* The state of one scope: an address, or every address together. */
typedef struct {
    int fails;                  /* wrong PINs in a row */
    int lockouts;               /* lockouts since the scope last gave the right PIN */
    int64_t next_us;            /* nothing compared before this */
    int64_t locked_until_us;
    int64_t last_us;            /* the last attempt */
} limit_t;

typedef struct {
    char addr[48];
    limit_t l;
} addr_t;

struct pinguard {
    pinguard_cfg_t cfg;
    unsigned char key[crypto_generichash_KEYBYTES];
    unsigned char hash[crypto_generichash_BYTES];
    limit_t all;
    addr_t addrs[MAX_ADDRS];
    int naddrs;
    pinguard_stats_t st;
};

void pinguard_cfg_defaults(pinguard_cfg_t *cfg)
{
    *cfg = (pinguard_cfg_t){ .max_failures = 5, .max_failures_all = 20, .delay_s = 1, .delay_all_s = 0.1,
                             .max_delay_s = 30, .lockout_s = 60, .max_lockout_s = 3600 };
}

/* A keyed hash of the text: both sides of a comparison have the same length whatever was typed. */
static void digest(const pinguard_t *g, const char *pin, unsigned char out[crypto_generichash_BYTES])
{
    crypto_generichash(out, crypto_generichash_BYTES, (const unsigned char *)pin, strlen(pin), g->key, sizeof g->key);
}

pinguard_t *pinguard_create(const char *pin, const pinguard_cfg_t *cfg)
{
    size_t n = pin ? strlen(pin) : 0;
    if (n < 4 || n > 64 || sodium_init() < 0) {
        errno = EINVAL;
        return NULL;
    }
    pinguard_t *g = calloc(1, sizeof *g);
    if (!g)
        return NULL;
    if (cfg)
        g->cfg = *cfg;
    else
        pinguard_cfg_defaults(&g->cfg);
    randombytes_buf(g->key, sizeof g->key);
    digest(g, pin, g->hash);
    return g;
}

void pinguard_destroy(pinguard_t *g)
{
    if (g)
        sodium_memzero(g, sizeof *g);
    free(g);
}

static limit_t *addr_limit(pinguard_t *g, const char *addr)
{
    int oldest = 0;
    for (int i = 0; i < g->naddrs; i++) {
        if (strcmp(g->addrs[i].addr, addr) == 0)
            return &g->addrs[i].l;
        if (g->addrs[i].l.last_us < g->addrs[oldest].l.last_us)
            oldest = i;
    }
    addr_t *a = g->naddrs < MAX_ADDRS ? &g->addrs[g->naddrs++] : &g->addrs[oldest];
    memset(a, 0, sizeof *a);
    snprintf(a->addr, sizeof a->addr, "%s", addr);
    return &a->l;
}

static int64_t us(double s) { return (int64_t)(s * 1e6); }

/* A scope unheard for the longest lockout starts afresh. */
static void forgive(const pinguard_cfg_t *cfg, limit_t *l, int64_t now)
{
    if (l->last_us && now - l->last_us > us(cfg->max_lockout_s) && now >= l->locked_until_us)
        *l = (limit_t){ 0 };
}

/* A wrong PIN in scope l: its wait doubles; max wrong ones in a row lock it out. True when this
 * one began a lockout. */
static bool fail(const pinguard_cfg_t *cfg, limit_t *l, int max, double delay_s, int64_t now)
{
    double wait = delay_s;
    for (int i = 1; i < l->fails + 1 && wait < cfg->max_delay_s; i++)
        wait *= 2;
    l->fails++;
    l->next_us = now + us(wait < cfg->max_delay_s ? wait : cfg->max_delay_s);
    if (l->fails < max)
        return false;
    double lock = cfg->lockout_s;
    for (int i = 0; i < l->lockouts && lock < cfg->max_lockout_s; i++)
        lock *= 2;
    l->locked_until_us = now + us(lock < cfg->max_lockout_s ? lock : cfg->max_lockout_s);
    l->lockouts++;
    l->fails = 0;
    return true;
}

static int64_t blocked_until(const limit_t *l)
{
    return l->next_us > l->locked_until_us ? l->next_us : l->locked_until_us;
}

pinguard_result_t pinguard_check(pinguard_t *g, const char *addr, const char *pin, int64_t now)
{
    pinguard_result_t r = { .verdict = PINGUARD_OK };
    limit_t *a = addr_limit(g, addr ? addr : "?");
    forgive(&g->cfg, a, now);
    forgive(&g->cfg, &g->all, now);
    a->last_us = g->all.last_us = now;
    int64_t mine = blocked_until(a), every = blocked_until(&g->all);
    if (now < mine || now < every) {
        r.everyone = every > mine;
        const limit_t *by = r.everyone ? &g->all : a;
        r.verdict = now < by->locked_until_us ? PINGUARD_LOCKED : PINGUARD_WAIT;
        r.retry_s = (double)((mine > every ? mine : every) - now) * 1e-6;
        g->st.refused_early++;
        return r;
    }
    unsigned char h[crypto_generichash_BYTES];
    digest(g, pin ? pin : "", h);
    if (sodium_memcmp(h, g->hash, sizeof h) == 0) {
        *a = (limit_t){ .last_us = now };
        g->all.fails = 0;
        return r;
    }
    g->st.wrong++;
    r.verdict = PINGUARD_WRONG;
    bool own = fail(&g->cfg, a, g->cfg.max_failures, g->cfg.delay_s, now);
    bool all = fail(&g->cfg, &g->all, g->cfg.max_failures_all, g->cfg.delay_all_s, now);
    r.locked_now = own || all;
    r.everyone = all || blocked_until(&g->all) > blocked_until(a);
    r.failures = own ? g->cfg.max_failures : a->fails;
    g->st.lockouts += own + all;
    mine = blocked_until(a);
    every = blocked_until(&g->all);
    r.retry_s = (double)((mine > every ? mine : every) - now) * 1e-6;
    return r;
}

pinguard_stats_t pinguard_stats(const pinguard_t *g)
{
    return g->st;
}

int pinguard_random_pin(int digits, char *out, size_t len)
{
    if (digits < 4 || digits > 12 || len < (size_t)digits + 1 || sodium_init() < 0) {
        errno = EINVAL;
        return -1;
    }
    for (int i = 0; i < digits; i++)
        out[i] = (char)('0' + randombytes_uniform(10));
    out[digits] = 0;
    return 0;
}

/* Wrong PINs compared in `seconds` from a fresh start by a guesser with addresses enough that only
 * the shared limit holds: rounds of max_failures_all, each its waits and then a lockout (doubling). */
static double guesses_within(const pinguard_cfg_t *cfg, double seconds)
{
    double t = 0, n = 0, lock = cfg->lockout_s;
    for (;;) {
        double wait = cfg->delay_all_s;
        for (int i = 0; i < cfg->max_failures_all; i++) {
            if (t > seconds)
                return n;
            n++;
            if (i + 1 < cfg->max_failures_all) {
                t += wait < cfg->max_delay_s ? wait : cfg->max_delay_s;
                wait *= 2;
            }
        }
        t += lock < cfg->max_lockout_s ? lock : cfg->max_lockout_s;
        lock *= 2;
    }
}

void pinguard_strength(const pinguard_cfg_t *cfg, int digits, char *out, size_t len)
{
    double first = guesses_within(cfg, 86400), later = guesses_within(cfg, 30 * 86400.0) / 30, space = 1;
    for (int i = 0; i < digits; i++)
        space *= 10;
    snprintf(out, len, "at most %.0f guesses in the first day (%.0f a day later on): a %d-digit PIN is found within "
             "the first day with probability %.2g%%, on average after %.0f days", first, later, digits,
             100 * first / space, space / 2 / later);
}
