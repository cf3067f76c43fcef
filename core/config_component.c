/* config_component: one component's entry of the system file (exec, args, env, ports, restart,
 * timeouts, sched, limits) read into its marie_component_cfg_t, with file:line:col for what is wrong. */
#include "core/config.h"
#include "core/config_priv.h"

#include <stdlib.h>
#include <string.h>

void marie_config_free_strv(char **v, size_t n)
{
    for (size_t i = 0; i < n; i++)
        free(v[i]);
    free(v);
}

/* A sequence of scalars (or one scalar) as a string vector. */
int marie_config_read_strv(const marie_node_t *n, char ***out, size_t *count, marie_errors_t *errs)
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
    return marie_config_seconds_ok(n, key, *out, errs);
}

int marie_config_read_restart(const marie_node_t *n, marie_restart_cfg_t *r, marie_errors_t *errs)
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
        b->url = url ? strdup(url) : NULL;
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
    "stop_timeout", "heartbeat_timeout", "depends", "sched", "limits", NULL,
};

int marie_config_read_component(const marie_node_t *n, const marie_system_t *sys,
                                const marie_restart_cfg_t *defaults, marie_component_cfg_t *c,
                                marie_errors_t *errs)
{
    memset(c, 0, sizeof *c);
    c->name = strdup(n->key);
    c->node = n;
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
    rc |= marie_config_read_strv(marie_node_get(n, "args"), &c->args, &c->nargs, errs);
    rc |= marie_config_read_strv(marie_node_get(n, "depends"), &c->depends, &c->ndepends, errs);
    rc |= read_env(marie_node_get(n, "env"), c, errs);
    rc |= read_ports(marie_node_get(n, "ports"), c, errs);
    rc |= marie_config_read_restart(marie_node_get(n, "restart"), &c->restart, errs);
    rc |= read_seconds(n, "stop_timeout", &c->stop_timeout_s, errs);
    rc |= read_seconds(n, "heartbeat_timeout", &c->heartbeat_timeout_s, errs);
    if ((v = marie_node_get(n, "sched")) && marie_sched_cfg_read(v, &c->sched, errs) < 0)
        rc = -1;
    if ((v = marie_node_get(n, "limits")) && marie_limits_cfg_read(v, &c->limits, errs) < 0)
        rc = -1;
    /* Simulated time does not need the CPU on time, and a simulation must run where real-time
     * scheduling is not allowed: on the simulator's clock the setting is checked, not applied. */
    if (sys->clock == MARIE_CLOCK_SIM && marie_sched_cfg_any(&c->sched)) {
        marie_sched_cfg_clear(&c->sched);
        c->sched_sim = true;
    }
    if (c->restart.backoff_min_s > c->restart.backoff_max_s) {
        const marie_node_t *r = marie_node_get(n, "restart");
        marie_errors_add(errs, n->file, r ? r->line : n->key_line, r ? r->col : n->key_col,
                         "component '%s': restart backoff_min (%g s) is above backoff_max (%g s)", n->key,
                         c->restart.backoff_min_s, c->restart.backoff_max_s);
        rc = -1;
    }
    return rc ? -1 : 0;
}
