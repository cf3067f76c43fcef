/* config_check: what a system file must also be, beyond what reading it refuses, so that a file
 * that passes `marie up` never makes its components fail at run time (docs/system-file.md,
 * "Checked before anything starts"). */
#include "core/config_priv.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/bus/bus.h"

#define MAX_NAME 63         /* a component, group or host name */
#define MAX_CHANNEL 63      /* LCM's limit (LCM_MAX_CHANNEL_NAME_LENGTH): a longer one is never sent */
#define MAX_SECONDS 86400.0 /* a duration the managers count in microseconds without overflow */
#define MIN_HEARTBEAT_S 0.15 /* the shortest heartbeat_timeout measured to hold (docs/system-file.md) */

int marie_config_seconds_ok(const marie_node_t *n, const char *key, double v, marie_errors_t *errs)
{
    bool hb = strcmp(key, "heartbeat_timeout") == 0;
    if (v >= 0 && v <= MAX_SECONDS && (!hb || v == 0 || v >= MIN_HEARTBEAT_S))
        return 0;
    if (hb)
        marie_node_error(errs, n, "heartbeat_timeout: 0 (no heartbeat) or %g to %.0f s, not %g", MIN_HEARTBEAT_S,
                         MAX_SECONDS, v);
    else
        marie_node_error(errs, n, "%s: 0 to %.0f s (a day), not %g", key, MAX_SECONDS, v);
    return -1;
}

/* s for a message: bytes outside printable ASCII as \xHH, so an escape sequence or a
 * right-to-left override in a name is shown, not obeyed, by the terminal. */
static const char *shown(const char *s, char *buf, size_t len)
{
    size_t o = 0;
    for (; *s && o + 5 < len; s++) {
        unsigned char ch = (unsigned char)*s;
        o += (size_t)snprintf(buf + o, len - o, ch >= 0x20 && ch < 0x7f ? "%c" : "\\x%02x", ch);
    }
    buf[o] = 0;
    return buf;
}

/* A name of the file: letters, digits, '_', '-', '.', not starting with '-' or '.'. */
static bool word_ok(const char *s)
{
    size_t n = strlen(s);
    if (n == 0 || n > MAX_NAME || s[0] == '-' || s[0] == '.')
        return false;
    return strspn(s, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-.") == n;
}

static int check_word(const char *file, int line, int col, const char *what, const char *s, marie_errors_t *errs)
{
    if (word_ok(s))
        return 0;
    char buf[300];
    marie_errors_add(errs, file, line, col, "%s '%s': letters, digits, '_', '-' and '.' only, 1 to %d of them, "
                     "not starting with '-' or '.'", what, shown(s, buf, sizeof buf), MAX_NAME);
    return -1;
}

/* A channel LCM can carry: 1 to 63 bytes of printable ASCII. */
static int check_channel(const char *file, int line, int col, const char *what, const char *ch, marie_errors_t *errs)
{
    size_t n = strlen(ch), ok = 0;
    while (ok < n && ch[ok] > 0x20 && ch[ok] < 0x7f)
        ok++;
    if (n > 0 && n <= MAX_CHANNEL && ok == n)
        return 0;
    char buf[120];
    marie_errors_add(errs, file, line, col, "%s: channel '%s%s' (%zu bytes): 1 to %d bytes of printable ASCII "
                     "without spaces (LCM sends no longer name)", what, shown(ch, buf, 64), n > 40 ? "..." : "", n,
                     MAX_CHANNEL);
    return -1;
}

static int check_url(const marie_node_t *at, const char *what, const char *url, marie_errors_t *errs)
{
    char why[200];
    if (marie_bus_url_check(url, why, sizeof why) == 0)
        return 0;
    marie_node_error(errs, at, "%s '%s': %s", what, url, why);
    return -1;
}

static int check_hosts(const marie_node_t *h, marie_errors_t *errs)
{
    if (!h)
        return 0;
    int rc = 0;
    if (h->n == 0) {
        marie_node_error(errs, h, "hosts: empty: name the hosts, or leave the key out (one host, this one)");
        return -1;
    }
    for (size_t i = 0; i < h->n; i++) {
        const marie_node_t *it = h->items[i];
        const char *name = h->kind == MARIE_NODE_MAP ? it->key : it->value;
        int line = h->kind == MARIE_NODE_MAP ? it->key_line : it->line;
        int col = h->kind == MARIE_NODE_MAP ? it->key_col : it->col;
        if (!name)
            continue;           /* not a scalar: reading the file said so */
        rc |= check_word(it->file, line, col, "host", name, errs);
        for (size_t k = 0; k < i; k++) {
            const marie_node_t *o = h->items[k];
            const char *other = h->kind == MARIE_NODE_MAP ? o->key : o->value;
            if (other && strcmp(other, name) == 0) {
                marie_errors_add(errs, it->file, line, col, "hosts: '%s' twice (also at line %d)", name,
                                 h->kind == MARIE_NODE_MAP ? o->key_line : o->line);
                rc = -1;
            }
        }
    }
    return rc;
}

static int check_component(const marie_component_cfg_t *c, marie_errors_t *errs)
{
    int rc = check_word(c->file, c->line, c->col, "component", c->name, errs);
    const marie_node_t *n;
    if (c->group && (n = marie_node_get(c->node, "group")))
        rc |= check_word(n->file, n->line, n->col, "group", c->group, errs);
    if ((n = marie_node_get(c->node, "args")) && n->kind == MARIE_NODE_SCALAR) {
        marie_node_error(errs, n, "args: a list, one argument an item ([--param, rate_hz=5]), not one string: "
                         "nothing splits it");
        rc = -1;
    }
    for (size_t i = 0; i < c->nports; i++) {
        const marie_port_binding_t *b = &c->ports[i];
        char what[128];
        snprintf(what, sizeof what, "port '%.60s'", b->name);
        rc |= check_channel(c->file, b->line, b->col, what, b->channel, errs);
        const marie_node_t *pn = marie_node_get(marie_node_get(c->node, "ports"), b->name);
        if (b->url && pn)
            rc |= check_url(marie_node_get(pn, "url") ? marie_node_get(pn, "url") : pn, "url", b->url, errs);
    }
    return rc;
}

/* Every profile's `extends` chain, whether the profile is applied or not: a file whose profile
 * cannot be applied is wrong before anyone asks for it. */
static int check_profiles(const marie_node_t *profiles, marie_errors_t *errs)
{
    int rc = 0;
    for (size_t i = 0; profiles && profiles->kind == MARIE_NODE_MAP && i < profiles->n; i++) {
        const marie_node_t *p = profiles->items[i];
        for (int depth = 0; p && p->kind == MARIE_NODE_MAP; depth++) {
            const marie_node_t *ext = marie_node_get(p, "extends");
            if (!ext || ext->kind != MARIE_NODE_SCALAR)
                break;
            const marie_node_t *next = marie_node_get(profiles, ext->value);
            if (!next) {
                marie_node_error(errs, ext, "extends: no profile '%s' in this file", ext->value);
            } else if (strcmp(ext->value, profiles->items[i]->key) == 0) {
                marie_node_error(errs, ext, depth ? "extends: profile '%s' leads back to itself (a cycle)"
                                                  : "extends: profile '%s' extends itself", profiles->items[i]->key);
            } else if (depth >= 8) {
                marie_node_error(errs, ext, "extends: profiles extend one another more than 8 deep, or in a cycle");
            } else {
                p = next;
                continue;
            }
            rc = -1;
            break;
        }
    }
    return rc;
}

/* Iterative depth-first search (a long dependency chain must not overflow the stack): a
 * dependency on a component still on the path closes a cycle. */
static int find_cycle(const marie_system_t *sys, marie_errors_t *errs)
{
    size_t n = sys->ncomponents;
    unsigned char *mark = calloc(n ? n : 1, 1);           /* 0 new, 1 on the path, 2 done */
    size_t *stack = malloc((n ? n : 1) * sizeof *stack), *next = calloc(n ? n : 1, sizeof *next);
    int rc = mark && stack && next ? 0 : -1;
    for (size_t root = 0; rc == 0 && root < n; root++) {
        if (mark[root])
            continue;
        size_t top = 0;
        stack[top++] = root;
        mark[root] = 1;
        while (top && rc == 0) {
            const marie_component_cfg_t *c = &sys->components[stack[top - 1]];
            if (next[stack[top - 1]] == c->ndepends) {
                mark[stack[--top]] = 2;
                continue;
            }
            const marie_component_cfg_t *d = marie_system_component(sys, c->depends[next[stack[top - 1]]++]);
            size_t j = d ? (size_t)(d - sys->components) : 0;
            if (!d || mark[j] == 2)
                continue;
            if (mark[j] == 1) {
                marie_errors_add(errs, d->file, d->line, d->col, "component '%s' is part of a dependency cycle",
                                 d->name);
                rc = -1;
                break;
            }
            mark[j] = 1;
            stack[top++] = j;
        }
    }
    free(mark);
    free(stack);
    free(next);
    return rc;
}

int marie_config_check(const marie_system_t *sys, marie_errors_t *errs)
{
    const marie_node_t *root = marie_doc_root(sys->doc), *v;
    int rc = check_hosts(marie_node_get(root, "hosts"), errs);
    if ((v = marie_node_get(root, "lcm_url")) && v->kind == MARIE_NODE_SCALAR)
        rc |= check_url(v, "lcm_url", v->value, errs);
    for (size_t i = 0; i < sys->ntransports; i++)
        rc |= check_channel(sys->file, sys->transports[i].line, sys->transports[i].col, "transports",
                            sys->transports[i].channel, errs);
    for (size_t i = 0; i < sys->ncomponents; i++)
        rc |= check_component(&sys->components[i], errs);
    rc |= check_profiles(marie_node_get(root, "profiles"), errs);
    if (rc == 0 && find_cycle(sys, errs) < 0)
        rc = -1;
    return rc;
}
