/* config: the system file model over the YAML tree: loading a file, its profiles and their
 * params, the lookups. A component's own keys are read in config_component.c, its hash (made
 * when asked) in config_hash.c, the checks of a loaded file in config_check.c. */
#include "core/clear.h"
#include "core/config.h"
#include "core/config_priv.h"
#include "core/typeinfo.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

/* ---- system file ---- */

const char *marie_default_url(void)
{
    const char *env = getenv("LCM_DEFAULT_URL");
    return env && *env ? env : MARIE_DEFAULT_URL;
}


/* A map made by override_params: its items are the document's nodes, not its own. */
static void free_merged(marie_node_t *m)
{
    if (!m)
        return;
    free(m->items);
    free(m->index);
    free(m);
}

static void component_cfg_free(marie_component_cfg_t *c)
{
    free_merged(c->params_merged);
    free(c->name);
    free(c->exec);
    marie_config_free_strv(c->args, c->nargs);
    marie_config_free_strv(c->env, c->nenv);
    free(c->host);
    free(c->group);
    for (size_t i = 0; i < c->nports; i++) {
        free(c->ports[i].name);
        free(c->ports[i].channel);
        free(c->ports[i].url);
    }
    free(c->ports);
    marie_config_free_strv(c->depends, c->ndepends);
    marie_sched_cfg_clear(&c->sched);
}

void marie_system_destroy(marie_system_t *sys)
{
    if (!sys)
        return;
    for (size_t i = 0; i < sys->ncomponents; i++)
        component_cfg_free(&sys->components[i]);
    free(sys->components);
    free(sys->by_name);
    for (size_t i = 0; i < sys->ntransports; i++)
        free(sys->transports[i].channel);
    free(sys->transports);
    marie_config_free_strv(sys->hosts, sys->nhosts);
    marie_config_free_strv(sys->types, sys->ntypes);
    free(sys->file);
    free(sys->name);
    free(sys->profile);
    free(sys->lcm_url);
    free(sys->key_file);
    marie_doc_destroy(sys->doc);
    free(sys);
}

int marie_system_load_types(const marie_system_t *sys, marie_errors_t *errs)
{
    char why[512], dir[4096];
    if (marie_types_load_list(getenv("MARIE_TYPES_PATH"), why, sizeof why) < 0) {
        marie_errors_add(errs, "MARIE_TYPES_PATH", 0, 0, "%s", why);
        return -1;
    }
    if (!sys || !sys->ntypes)
        return 0;
    snprintf(dir, sizeof dir, "%s", sys->file);
    char *slash = strrchr(dir, '/');
    snprintf(slash ? slash : dir, sizeof dir - (size_t)(slash ? slash - dir : 0), "%s", slash ? "" : ".");
    const marie_node_t *n = marie_node_get(marie_doc_root(sys->doc), "types");
    for (size_t i = 0; i < sys->ntypes; i++) {
        if (marie_types_load(sys->types[i], dir, why, sizeof why) < 0) {
            const marie_node_t *at = n && n->kind == MARIE_NODE_SEQ && i < n->n ? n->items[i] : n;
            marie_errors_add(errs, sys->file, at ? at->line : 0, at ? at->col : 0, "%s", why);
            return -1;
        }
    }
    return 0;
}

static int cmp_cfg_name(const void *a, const void *b)
{
    return strcmp((*(marie_component_cfg_t *const *)a)->name, (*(marie_component_cfg_t *const *)b)->name);
}

const marie_component_cfg_t *marie_system_component(const marie_system_t *sys, const char *name)
{
    if (!sys || !name || !sys->by_name)
        return NULL;
    marie_component_cfg_t key = {.name = (char *)name}, *kp = &key;
    marie_component_cfg_t **hit = bsearch(&kp, sys->by_name, sys->ncomponents, sizeof *sys->by_name, cmp_cfg_name);
    return hit ? *hit : NULL;
}


static const marie_node_t *find_profile(const marie_node_t *root, const char *profile, const marie_node_t *named_at,
                                        marie_errors_t *errs, const char *file)
{
    const marie_node_t *profiles = marie_node_get(root, "profiles");
    const marie_node_t *p = marie_node_get(profiles, profile);
    if (!p) {
        const marie_node_t *at = named_at ? named_at : profiles;
        marie_errors_add(errs, file, at ? at->line : 1, at ? at->col : 1, "no profile '%s' in this file", profile);
        return NULL;
    }
    static const char *const keys[] = {"extends", "components", "remove", "clock", "robot", "params", NULL};
    if (marie_node_check_keys(p, keys, "profile", errs) < 0)
        return NULL;
    return p;
}

/* A profile and the profiles it extends, nearest first: chain[0] is the one asked for. A profile
 * applies on top of the one it extends as that one applies on the base. Returns the length, -1
 * on error (unknown name, a cycle, deeper than MAX_PROFILE_CHAIN). */
#define MAX_PROFILE_CHAIN 8
static int profile_chain(const marie_node_t *root, const char *profile, const marie_node_t **chain,
                         marie_errors_t *errs, const char *file)
{
    int n = 0;
    const marie_node_t *named_at = NULL;
    const char *name = profile;
    while (name) {
        const marie_node_t *p = find_profile(root, name, named_at, errs, file);
        if (!p)
            return -1;
        for (int i = 0; i < n; i++)
            if (chain[i] == p) {
                marie_node_error(errs, named_at, "extends: profile '%s' leads back to itself (a cycle from '%s')", name,
                                 profile);
                return -1;
            }
        if (n == MAX_PROFILE_CHAIN) {
            marie_node_error(errs, named_at, "extends: profiles extend one another more than %d deep",
                             MAX_PROFILE_CHAIN);
            return -1;
        }
        chain[n++] = p;
        name = NULL;
        if ((named_at = marie_node_get(p, "extends")) && marie_node_str(named_at, &name, errs) < 0)
            return -1;
    }
    return n;
}

/* A profile's `params: {COMPONENT: {KEY: VALUE, ...}}` over a component's params: a new map
 * with the component's own entries that are not overridden, then the profile's, each the
 * file's own node (so a bad value is reported at its line). */
static int override_params(marie_component_cfg_t *c, const marie_node_t *over, marie_errors_t *errs)
{
    if (over->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, over, "params: %s: expected a mapping of parameter: value", over->key);
        return -1;
    }
    const marie_node_t *base = c->params;
    size_t n = over->n + (base ? base->n : 0);
    marie_node_t *m = calloc(1, sizeof *m);
    marie_node_t **items = calloc(n ? n : 1, sizeof *items);
    if (!m || !items) {
        free(m);
        free(items);
        marie_node_error(errs, over, "params: out of memory");
        return -1;
    }
    *m = (marie_node_t){ .kind = MARIE_NODE_MAP, .file = over->file, .line = over->line, .col = over->col,
                         .key = base ? base->key : over->key, .key_line = over->key_line,
                         .key_col = over->key_col, .items = items };
    for (size_t i = 0; base && i < base->n; i++)
        if (!marie_node_get(over, base->items[i]->key))
            items[m->n++] = base->items[i];
    for (size_t i = 0; i < over->n; i++)
        items[m->n++] = over->items[i];
    free_merged(c->params_merged);
    c->params_merged = m;
    c->params = m;
    return 0;
}

marie_system_t *marie_system_load(const char *path, const char *profile, marie_errors_t *errs)
{
    return marie_system_load_text(path, NULL, 0, profile, errs);
}

marie_system_t *marie_system_load_text(const char *path, const char *text, size_t len, const char *profile,
                                       marie_errors_t *errs)
{
    return marie_system_load_only(path, text, len, profile, NULL, errs);
}

marie_system_t *marie_system_load_only(const char *path, const char *text, size_t len, const char *profile,
                                       const char *only, marie_errors_t *errs)
{
    marie_system_t *sys = calloc(1, sizeof *sys);
    if (!sys)
        return NULL;
    size_t errs_before = errs ? errs->n : 0;
    sys->file = strdup(path);
    sys->profile = profile ? strdup(profile) : NULL;
    if (!(sys->doc = text ? marie_doc_parse(path, text, len, errs) : marie_doc_load(path, errs)))
        goto err;
    const marie_node_t *root = marie_doc_root(sys->doc), *v;
    static const char *const top_keys[] = {"system", "lcm_url", "clock", "auth", "hosts", "defaults",
                                           "components", "profiles", "manager", "balance", "robot", "transports",
                                           "ros2", "types", NULL};
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
        } else if (marie_config_read_strv(v, &sys->hosts, &sys->nhosts, errs) < 0) {
            goto err;
        }
    }
    if (marie_transports_read(marie_node_get(root, "transports"), sys, errs) < 0 ||
        marie_config_read_strv(marie_node_get(root, "types"), &sys->types, &sys->ntypes, errs) < 0)
        goto err;
    /* The bridge reads the entries themselves (with their positions); the loader checks the shape. */
    if ((v = marie_node_get(root, "ros2")) && v->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, v, "ros2: expected a mapping such as {topics: [{channel: LASER, topic: /scan}]}");
        goto err;
    }
    sys->ros2 = v;
    marie_restart_cfg_t defaults = {MARIE_RESTART_ON_FAILURE, 0.1, 5.0, 10.0, 5, 60.0};
    if ((v = marie_node_get(root, "defaults"))) {
        static const char *const keys[] = {"restart", NULL};
        if (marie_node_check_keys(v, keys, "defaults", errs) < 0 ||
            marie_config_read_restart(marie_node_get(v, "restart"), &defaults, errs) < 0)
            goto err;
        if (defaults.backoff_min_s > defaults.backoff_max_s) {
            const marie_node_t *r = marie_node_get(v, "restart");
            marie_errors_add(errs, path, r ? r->line : v->line, r ? r->col : v->col,
                             "defaults: restart backoff_min (%g s) is above backoff_max (%g s)",
                             defaults.backoff_min_s, defaults.backoff_max_s);
            goto err;
        }
    }
    const marie_node_t *comps = marie_node_get(root, "components");
    const marie_node_t *chain[MAX_PROFILE_CHAIN];
    int nchain = profile ? profile_chain(root, profile, chain, errs, path) : 0;
    if (nchain < 0)
        goto err;
    if (comps && comps->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, comps, "components: expected a mapping of name: component");
        goto err;
    }
    /* A profile may run on another clock (the simulator's); the nearest profile that says wins. */
    const marie_node_t *clk = NULL, *rb = NULL;
    for (int i = nchain - 1; i >= 0; i--) {
        clk = marie_node_get(chain[i], "clock") ? marie_node_get(chain[i], "clock") : clk;
        rb = marie_node_get(chain[i], "robot") ? marie_node_get(chain[i], "robot") : rb;
    }
    if ((v = clk ? clk : marie_node_get(root, "clock")) && marie_node_str(v, &s, errs) == 0) {
        if (strcmp(s, "sim") == 0)
            sys->clock = MARIE_CLOCK_SIM;
        else if (strcmp(s, "wall") != 0)
            marie_node_error(errs, v, "clock: expected wall or sim, got '%s'", s);
    }
    /* One description of the robot's shape, for every component that needs it (a profile's
     * robot replaces the base one whole). */
    if ((v = rb ? rb : marie_node_get(root, "robot"))) {
        static const char *const keys[] = {"radius", "clearance", NULL};
        double d;
        if (v->kind != MARIE_NODE_MAP) {
            marie_node_error(errs, v, "robot: expected a mapping such as {radius: 0.3}");
            goto err;
        }
        if (marie_node_check_keys(v, keys, "robot", errs) < 0)
            goto err;
        for (size_t i = 0; i < v->n; i++) {
            if (marie_node_double(v->items[i], &d, errs) < 0)
                goto err;
            if (!(d >= 0)) {
                marie_node_error(errs, v->items[i], "robot.%s: must not be negative", v->items[i]->key);
                goto err;
            }
        }
        sys->robot = v;
    }
    /* Level 0 is the base, level k the profile chain[nchain - k]: an entry of a level is kept
     * unless a higher level replaces it (components) or drops it (remove). */
    const marie_node_t *level_comps[MAX_PROFILE_CHAIN + 1] = {comps};
    char **removed[MAX_PROFILE_CHAIN + 1] = {NULL};
    size_t nremoved[MAX_PROFILE_CHAIN + 1] = {0}, max = comps ? comps->n : 0;
    int rc = 0;
    for (int k = 1; k <= nchain; k++) {
        const marie_node_t *pc = marie_node_get(chain[nchain - k], "components");
        if (pc && pc->kind != MARIE_NODE_MAP) {
            marie_node_error(errs, pc, "components: expected a mapping of name: component");
            rc = -1;
        }
        level_comps[k] = pc && pc->kind == MARIE_NODE_MAP ? pc : NULL;
        max += level_comps[k] ? level_comps[k]->n : 0;
        if (marie_config_read_strv(marie_node_get(chain[nchain - k], "remove"), &removed[k], &nremoved[k], errs) < 0)
            rc = -1;
    }
    sys->components = rc ? NULL : calloc(max ? max : 1, sizeof *sys->components);
    int *level = sys->components ? calloc(max ? max : 1, sizeof *level) : NULL;
    if (!level)
        MARIE_CLEAR(sys->components, free);
    for (int k = 0; level && k <= nchain; k++)
        for (size_t i = 0; level_comps[k] && i < level_comps[k]->n; i++) {
            const marie_node_t *n = level_comps[k]->items[i];
            bool kept = !only || strcmp(n->key, only) == 0;
            for (int m = k + 1; m <= nchain && kept; m++) {
                kept = !marie_node_get(level_comps[m], n->key);
                for (size_t r = 0; r < nremoved[m] && kept; r++)
                    kept = strcmp(removed[m][r], n->key) != 0;
            }
            if (kept) {
                level[sys->ncomponents] = k;
                rc |= marie_config_read_component(n, sys, &defaults, &sys->components[sys->ncomponents++], errs);
            }
        }
    /* Each profile's `params:`, base-most first, over the components present after it: one
     * that a nearer profile replaces or removes takes that profile's entry instead. */
    for (int k = 1; level && k <= nchain; k++) {
        const marie_node_t *pp = marie_node_get(chain[nchain - k], "params");
        if (pp && pp->kind != MARIE_NODE_MAP) {
            marie_node_error(errs, pp, "params: expected a mapping of component: {parameter: value}");
            rc = -1;
            continue;
        }
        for (size_t i = 0; pp && i < pp->n; i++) {
            const marie_node_t *o = pp->items[i];
            if (only && strcmp(o->key, only) != 0)
                continue;
            bool known = false;
            for (int m = 0; m <= k; m++)
                known |= marie_node_get(level_comps[m], o->key) != NULL;
            for (size_t r = 0; r < nremoved[k]; r++)
                known &= strcmp(removed[k][r], o->key) != 0;
            size_t j = 0;
            while (j < sys->ncomponents && strcmp(sys->components[j].name, o->key) != 0)
                j++;
            if (!known) {
                marie_errors_add(errs, o->file, o->key_line, o->key_col,
                                 "params: no component '%s' in this profile", o->key);
                rc = -1;
            } else if (j < sys->ncomponents && level[j] <= k) {
                rc |= override_params(&sys->components[j], o, errs);
            }
        }
    }
    free(level);
    for (int k = 0; k <= nchain; k++)
        marie_config_free_strv(removed[k], nremoved[k]);
    if (!sys->components)
        goto err;
    if (!(sys->by_name = malloc((sys->ncomponents ? sys->ncomponents : 1) * sizeof *sys->by_name)))
        goto err;
    for (size_t i = 0; i < sys->ncomponents; i++)
        sys->by_name[i] = &sys->components[i];
    qsort(sys->by_name, sys->ncomponents, sizeof *sys->by_name, cmp_cfg_name);
    /* Dependencies must name components of the system (the other entries, when one is read). */
    for (size_t i = 0; i < sys->ncomponents; i++) {
        marie_component_cfg_t *c = &sys->components[i];
        for (size_t k = 0; !only && k < c->ndepends; k++) {
            if (!marie_system_component(sys, c->depends[k])) {
                marie_errors_add(errs, c->file, c->line, c->col, "component '%s' depends on unknown component '%s'",
                                 c->name, c->depends[k]);
                rc = -1;
            }
        }
        c->sys_ = sys;
    }
    if (rc == 0 && marie_config_check(sys, errs) < 0)
        rc = -1;
    if (rc || (errs && errs->n > errs_before))
        goto err;
    return sys;
err:
    if (errs && errs->n == errs_before)
        marie_errors_add(errs, path, 0, 0, "cannot load the system file");
    marie_system_destroy(sys);
    return NULL;
}
