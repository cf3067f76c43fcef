/* config: the system file model (components, profiles, restart policies, hashes) over the YAML tree. */
#include "core/config.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include <sodium.h>

/* ---- system file ---- */

const char *marie_default_url(void)
{
    const char *env = getenv("LCM_DEFAULT_URL");
    return env && *env ? env : MARIE_DEFAULT_URL;
}

static char *dup_or_null(const char *s) { return s ? strdup(s) : NULL; }

static void free_strv(char **v, size_t n)
{
    for (size_t i = 0; i < n; i++)
        free(v[i]);
    free(v);
}

static void component_cfg_free(marie_component_cfg_t *c)
{
    free(c->name);
    free(c->exec);
    free_strv(c->args, c->nargs);
    free_strv(c->env, c->nenv);
    free(c->host);
    free(c->group);
    for (size_t i = 0; i < c->nports; i++) {
        free(c->ports[i].name);
        free(c->ports[i].channel);
        free(c->ports[i].url);
    }
    free(c->ports);
    free_strv(c->depends, c->ndepends);
}

void marie_system_destroy(marie_system_t *sys)
{
    if (!sys)
        return;
    for (size_t i = 0; i < sys->ncomponents; i++)
        component_cfg_free(&sys->components[i]);
    free(sys->components);
    free_strv(sys->hosts, sys->nhosts);
    free(sys->file);
    free(sys->name);
    free(sys->profile);
    free(sys->lcm_url);
    free(sys->key_file);
    marie_doc_destroy(sys->doc);
    free(sys);
}

const marie_component_cfg_t *marie_system_component(const marie_system_t *sys, const char *name)
{
    for (size_t i = 0; sys && name && i < sys->ncomponents; i++)
        if (strcmp(sys->components[i].name, name) == 0)
            return &sys->components[i];
    return NULL;
}

/* A sequence of scalars (or one scalar) as a string vector. */
static int read_strv(const marie_node_t *n, char ***out, size_t *count, marie_errors_t *errs)
{
    *out = NULL;
    *count = 0;
    if (!n)
        return 0;
    if (n->kind == MARIE_NODE_SCALAR) {
        *out = calloc(1, sizeof **out);
        if (!*out || !((*out)[0] = strdup(n->value)))
            return -1;
        *count = 1;
        return 0;
    }
    if (n->kind != MARIE_NODE_SEQ) {
        marie_node_error(errs, n, "%s: expected a list", n->key ? n->key : "value");
        return -1;
    }
    *out = calloc(n->n ? n->n : 1, sizeof **out);
    if (!*out)
        return -1;
    int rc = 0;
    for (size_t i = 0; i < n->n; i++) {
        const char *s;
        if (marie_node_str(n->items[i], &s, errs) < 0) {
            rc = -1;
            continue;
        }
        (*out)[(*count)++] = strdup(s);
    }
    return rc;
}

static int read_seconds(const marie_node_t *map, const char *key, double *out, marie_errors_t *errs)
{
    const marie_node_t *n = marie_node_get(map, key);
    if (!n)
        return 0;
    if (marie_node_double(n, out, errs) < 0)
        return -1;
    if (*out < 0) {
        marie_node_error(errs, n, "%s: must not be negative", key);
        return -1;
    }
    return 0;
}

static int read_restart(const marie_node_t *n, marie_restart_cfg_t *r, marie_errors_t *errs)
{
    if (!n)
        return 0;
    const char *policy = NULL;
    const marie_node_t *pn = n;
    if (n->kind == MARIE_NODE_MAP) {
        static const char *const keys[] = {"policy", "backoff_min", "backoff_max", "stable_after",
                                           "max_failures", "window", NULL};
        int rc = marie_node_check_keys(n, keys, "restart", errs);
        pn = marie_node_get(n, "policy");
        rc |= read_seconds(n, "backoff_min", &r->backoff_min_s, errs);
        rc |= read_seconds(n, "backoff_max", &r->backoff_max_s, errs);
        rc |= read_seconds(n, "stable_after", &r->stable_s, errs);
        rc |= read_seconds(n, "window", &r->window_s, errs);
        const marie_node_t *mf = marie_node_get(n, "max_failures");
        int64_t v = 0;
        if (mf) {
            if (marie_node_int(mf, &v, errs) < 0 || v < 0) {
                if (v < 0)
                    marie_node_error(errs, mf, "max_failures: must not be negative");
                rc = -1;
            } else {
                r->max_failures = (int)v;
            }
        }
        if (rc)
            return -1;
        if (!pn)
            return 0;
    }
    if (marie_node_str(pn, &policy, errs) < 0)
        return -1;
    if (strcmp(policy, "always") == 0)
        r->policy = MARIE_RESTART_ALWAYS;
    else if (strcmp(policy, "on-failure") == 0)
        r->policy = MARIE_RESTART_ON_FAILURE;
    else if (strcmp(policy, "never") == 0)
        r->policy = MARIE_RESTART_NEVER;
    else {
        marie_node_error(errs, pn, "restart policy: expected always, on-failure or never, got '%s'", policy);
        return -1;
    }
    return 0;
}

static int read_ports(const marie_node_t *n, marie_component_cfg_t *c, marie_errors_t *errs)
{
    if (!n)
        return 0;
    if (n->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, n, "ports: expected a mapping of port: channel");
        return -1;
    }
    c->ports = calloc(n->n ? n->n : 1, sizeof *c->ports);
    if (!c->ports)
        return -1;
    int rc = 0;
    for (size_t i = 0; i < n->n; i++) {
        const marie_node_t *p = n->items[i];
        const char *channel = NULL, *url = NULL;
        if (p->kind == MARIE_NODE_MAP) {
            static const char *const keys[] = {"channel", "url", NULL};
            if (marie_node_check_keys(p, keys, "port", errs) < 0) {
                rc = -1;
                continue;
            }
            const marie_node_t *ch = marie_node_get(p, "channel"), *u = marie_node_get(p, "url");
            if (!ch) {
                marie_node_error(errs, p, "port '%s': missing 'channel'", p->key);
                rc = -1;
                continue;
            }
            if (marie_node_str(ch, &channel, errs) < 0 || (u && marie_node_str(u, &url, errs) < 0)) {
                rc = -1;
                continue;
            }
        } else if (marie_node_str(p, &channel, errs) < 0) {
            rc = -1;
            continue;
        }
        if (!channel[0]) {
            marie_node_error(errs, p, "port '%s': empty channel name", p->key);
            rc = -1;
            continue;
        }
        marie_port_binding_t *b = &c->ports[c->nports++];
        b->name = strdup(p->key);
        b->channel = strdup(channel);
        b->url = dup_or_null(url);
        b->line = p->line;
        b->col = p->col;
    }
    return rc;
}

static int read_env(const marie_node_t *n, marie_component_cfg_t *c, marie_errors_t *errs)
{
    if (!n)
        return 0;
    if (n->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, n, "env: expected a mapping of NAME: value");
        return -1;
    }
    c->env = calloc(n->n ? n->n : 1, sizeof *c->env);
    if (!c->env)
        return -1;
    int rc = 0;
    for (size_t i = 0; i < n->n; i++) {
        const char *v;
        if (marie_node_str(n->items[i], &v, errs) < 0) {
            rc = -1;
            continue;
        }
        char *kv;
        if (asprintf(&kv, "%s=%s", n->items[i]->key, v) < 0)
            return -1;
        c->env[c->nenv++] = kv;
    }
    return rc;
}

static const char *const component_keys[] = {
    "exec", "args", "env", "shell", "host", "group", "ports", "params", "restart",
    "stop_timeout", "heartbeat_timeout", "depends", NULL,
};

static void hash_component(marie_component_cfg_t *c, const marie_node_t *n, const char *url)
{
    /* The effective configuration: the component's node plus the bus it runs on. */
    char *text = marie_node_canonical(n);
    unsigned char h[crypto_hash_sha256_BYTES];
    crypto_hash_sha256_state st;
    crypto_hash_sha256_init(&st);
    crypto_hash_sha256_update(&st, (const unsigned char *)url, strlen(url));
    if (text)
        crypto_hash_sha256_update(&st, (const unsigned char *)text, strlen(text));
    crypto_hash_sha256_final(&st, h);
    free(text);
    for (size_t i = 0; i < sizeof h; i++)
        snprintf(c->hash + 2 * i, 3, "%02x", h[i]);
}

static int read_component(const marie_node_t *n, const marie_system_t *sys, const marie_restart_cfg_t *defaults,
                          marie_component_cfg_t *c, marie_errors_t *errs)
{
    memset(c, 0, sizeof *c);
    c->name = strdup(n->key);
    c->file = n->file;
    c->line = n->key_line;
    c->col = n->key_col;
    c->restart = *defaults;
    c->stop_timeout_s = 3.0;
    c->heartbeat_timeout_s = 5.0;
    if (n->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, n, "component '%s': expected a mapping", n->key);
        return -1;
    }
    int rc = marie_node_check_keys(n, component_keys, "component", errs);
    const marie_node_t *v;
    const char *s;
    if (!(v = marie_node_get(n, "exec"))) {
        marie_errors_add(errs, n->file, n->key_line, n->key_col, "component '%s': missing 'exec'", n->key);
        rc = -1;
    } else if (marie_node_str(v, &s, errs) == 0) {
        c->exec = strdup(s);
    } else {
        rc = -1;
    }
    if ((v = marie_node_get(n, "host")) && marie_node_str(v, &s, errs) == 0) {
        int known = sys->nhosts == 0;
        for (size_t i = 0; i < sys->nhosts; i++)
            known |= strcmp(sys->hosts[i], s) == 0;
        if (!known) {
            marie_node_error(errs, v, "component '%s': host '%s' is not in hosts", n->key, s);
            rc = -1;
        }
        c->host = strdup(s);
    } else if (v) {
        rc = -1;
    }
    if ((v = marie_node_get(n, "group")) && marie_node_str(v, &s, errs) == 0)
        c->group = strdup(s);
    else if (v)
        rc = -1;
    if ((v = marie_node_get(n, "shell")) && marie_node_bool(v, &c->shell, errs) < 0)
        rc = -1;
    if ((v = marie_node_get(n, "params")) && v->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, v, "params: expected a mapping");
        rc = -1;
    }
    c->params = v;
    rc |= read_strv(marie_node_get(n, "args"), &c->args, &c->nargs, errs);
    rc |= read_strv(marie_node_get(n, "depends"), &c->depends, &c->ndepends, errs);
    rc |= read_env(marie_node_get(n, "env"), c, errs);
    rc |= read_ports(marie_node_get(n, "ports"), c, errs);
    rc |= read_restart(marie_node_get(n, "restart"), &c->restart, errs);
    rc |= read_seconds(n, "stop_timeout", &c->stop_timeout_s, errs);
    rc |= read_seconds(n, "heartbeat_timeout", &c->heartbeat_timeout_s, errs);
    hash_component(c, n, sys->lcm_url);
    return rc ? -1 : 0;
}

static const marie_node_t *find_profile(const marie_node_t *root, const char *profile, marie_errors_t *errs,
                                        const char *file)
{
    const marie_node_t *profiles = marie_node_get(root, "profiles");
    const marie_node_t *p = marie_node_get(profiles, profile);
    if (!p) {
        marie_errors_add(errs, file, profiles ? profiles->line : 1, profiles ? profiles->col : 1,
                         "no profile '%s' in this file", profile);
        return NULL;
    }
    static const char *const keys[] = {"components", "remove", "clock", NULL};
    if (marie_node_check_keys(p, keys, "profile", errs) < 0)
        return NULL;
    return p;
}

marie_system_t *marie_system_load(const char *path, const char *profile, marie_errors_t *errs)
{
    marie_system_t *sys = calloc(1, sizeof *sys);
    if (!sys)
        return NULL;
    size_t errs_before = errs ? errs->n : 0;
    sys->file = strdup(path);
    sys->profile = dup_or_null(profile);
    if (!(sys->doc = marie_doc_load(path, errs)))
        goto err;
    const marie_node_t *root = marie_doc_root(sys->doc), *v;
    static const char *const top_keys[] = {"system", "lcm_url", "clock", "auth", "hosts", "defaults",
                                           "components", "profiles", "manager", NULL};
    if (marie_node_check_keys(root, top_keys, "the system file", errs) < 0)
        goto err;
    const char *s;
    sys->name = strdup((v = marie_node_get(root, "system")) && marie_node_str(v, &s, errs) == 0 ? s : "marie");
    sys->lcm_url = strdup((v = marie_node_get(root, "lcm_url")) && marie_node_str(v, &s, errs) == 0
                              ? s : marie_default_url());
    if ((v = marie_node_get(root, "auth"))) {
        static const char *const keys[] = {"key_file", NULL};
        const marie_node_t *k = marie_node_get(v, "key_file");
        if (marie_node_check_keys(v, keys, "auth", errs) == 0 && k && marie_node_str(k, &s, errs) == 0)
            sys->key_file = strdup(s);
    }
    if ((v = marie_node_get(root, "hosts"))) {
        if (v->kind == MARIE_NODE_MAP) {
            sys->hosts = calloc(v->n ? v->n : 1, sizeof *sys->hosts);
            for (size_t i = 0; sys->hosts && i < v->n; i++)
                sys->hosts[sys->nhosts++] = strdup(v->items[i]->key);
        } else if (read_strv(v, &sys->hosts, &sys->nhosts, errs) < 0) {
            goto err;
        }
    }
    marie_restart_cfg_t defaults = {MARIE_RESTART_ON_FAILURE, 0.1, 5.0, 10.0, 5, 60.0};
    if ((v = marie_node_get(root, "defaults"))) {
        static const char *const keys[] = {"restart", NULL};
        if (marie_node_check_keys(v, keys, "defaults", errs) < 0 ||
            read_restart(marie_node_get(v, "restart"), &defaults, errs) < 0)
            goto err;
    }
    const marie_node_t *comps = marie_node_get(root, "components");
    const marie_node_t *prof = profile ? find_profile(root, profile, errs, path) : NULL;
    if (profile && !prof)
        goto err;
    if (comps && comps->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, comps, "components: expected a mapping of name: component");
        goto err;
    }
    /* A profile may run on another clock (the simulator's). */
    const marie_node_t *clk = marie_node_get(prof, "clock");
    if ((v = clk ? clk : marie_node_get(root, "clock")) && marie_node_str(v, &s, errs) == 0) {
        if (strcmp(s, "sim") == 0)
            sys->clock = MARIE_CLOCK_SIM;
        else if (strcmp(s, "wall") != 0)
            marie_node_error(errs, v, "clock: expected wall or sim, got '%s'", s);
    }
    const marie_node_t *pcomps = marie_node_get(prof, "components");
    if (pcomps && pcomps->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, pcomps, "components: expected a mapping of name: component");
        goto err;
    }
    char **removed = NULL;
    size_t nremoved = 0;
    if (read_strv(marie_node_get(prof, "remove"), &removed, &nremoved, errs) < 0)
        goto err;
    size_t max = (comps ? comps->n : 0) + (pcomps ? pcomps->n : 0);
    sys->components = calloc(max ? max : 1, sizeof *sys->components);
    if (!sys->components) {
        free_strv(removed, nremoved);
        goto err;
    }
    int rc = 0;
    /* Base components, each replaced whole by the profile's entry of the same name. */
    for (size_t i = 0; comps && i < comps->n; i++) {
        const marie_node_t *n = comps->items[i];
        int skip = marie_node_get(pcomps, n->key) != NULL;
        for (size_t k = 0; k < nremoved; k++)
            skip |= strcmp(removed[k], n->key) == 0;
        if (!skip)
            rc |= read_component(n, sys, &defaults, &sys->components[sys->ncomponents++], errs);
    }
    for (size_t i = 0; pcomps && i < pcomps->n; i++)
        rc |= read_component(pcomps->items[i], sys, &defaults, &sys->components[sys->ncomponents++], errs);
    free_strv(removed, nremoved);
    /* Dependencies must name components of the system. */
    for (size_t i = 0; i < sys->ncomponents; i++) {
        const marie_component_cfg_t *c = &sys->components[i];
        for (size_t k = 0; k < c->ndepends; k++) {
            if (!marie_system_component(sys, c->depends[k])) {
                marie_errors_add(errs, c->file, c->line, c->col, "component '%s' depends on unknown component '%s'",
                                 c->name, c->depends[k]);
                rc = -1;
            }
        }
    }
    if (rc || (errs && errs->n > errs_before))
        goto err;
    return sys;
err:
    if (errs && errs->n == errs_before)
        marie_errors_add(errs, path, 0, 0, "cannot load the system file");
    marie_system_destroy(sys);
    return NULL;
}
