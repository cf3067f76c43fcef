/* spec: a component's declared ports and parameters as JSON (PROG --describe), and the check of
 * a system file entry against such a description, so managers refuse a bad file before start. */
#include "core/spec.h"

#include <stdlib.h>
#include <string.h>

#include "core/buf.h"
#include "core/expand.h"

static const char *const type_names[] = {"int", "double", "bool", "string", "node"};

/* NULL as null: a spec's optional text that is not given. */
void marie_spec_json_str(FILE *f, const char *s)
{
    if (s)
        marie_json_fputs(f, s);
    else
        fputs("null", f);
}

void marie_spec_describe(const marie_component_def_t *def, FILE *out)
{
    fprintf(out, "{\"describe\": \"%s\", \"kind\": ", MARIE_SPEC_MARKER);
    marie_spec_json_str(out, def->kind);
    fputs(",\n \"ports\": [", out);
    for (const marie_port_spec_t *p = def->ports; p && p->name; p++) {
        fprintf(out, "%s\n  {\"name\": ", p == def->ports ? "" : ",");
        marie_spec_json_str(out, p->name);
        fprintf(out, ", \"dir\": \"%s\", \"mech\": \"%s\", \"type\": ", p->dir == MARIE_IN ? "in" : "out",
                p->mech == MARIE_PUSH ? "push" : p->mech == MARIE_PULL ? "pull" : "event");
        marie_spec_json_str(out, p->type ? p->type->name : NULL);
        fputs(", \"channel\": ", out);
        marie_spec_json_str(out, p->channel);
        fputs("}", out);
    }
    fputs("],\n \"params\": [", out);
    for (const marie_param_spec_t *p = def->params; p && p->name; p++) {
        fprintf(out, "%s\n  {\"name\": ", p == def->params ? "" : ",");
        marie_spec_json_str(out, p->name);
        fprintf(out, ", \"type\": \"%s\", \"default\": ", type_names[p->type]);
        marie_spec_json_str(out, p->def);
        fputs(", \"help\": ", out);
        marie_spec_json_str(out, p->help);
        fputs("}", out);
    }
    fputs("]}\n", out);
}

/* A string field of a description entry; NULL when absent or JSON null. */
static const char *field(const marie_node_t *entry, const char *key)
{
    const marie_node_t *n = marie_node_get(entry, key);
    return n && n->kind == MARIE_NODE_SCALAR && n->quoted ? n->value : NULL;
}

static const marie_node_t *find_entry(const marie_node_t *list, const char *name, size_t len)
{
    for (size_t i = 0; list && list->kind == MARIE_NODE_SEQ && i < list->n; i++) {
        const char *n = field(list->items[i], "name");
        if (n && strlen(n) == len && strncmp(n, name, len) == 0)
            return list->items[i];
    }
    return NULL;
}

/* The names in a spec's list, comma-separated, for a message (valid until the next call). */
static const char *names_of(const marie_node_t *list)
{
    static __thread char buf[1024];
    size_t len = sizeof buf;
    buf[0] = 0;
    for (size_t i = 0; list && list->kind == MARIE_NODE_SEQ && i < list->n; i++) {
        const char *n = field(list->items[i], "name");
        size_t used = strlen(buf);
        snprintf(buf + used, len - used, "%s%s", used ? ", " : "", n ? n : "?");
    }
    if (!buf[0])
        snprintf(buf, len, "none");
    return buf;
}

/* What marie-am sets for every component it starts (docs/managers.md): set wherever it runs. */
static char *const manager_env[] = {"MARIE_SYSTEM", "MARIE_NAME", "MARIE_HOST", "MARIE_PROFILE", "MARIE_STATE_DIR",
                                    "MARIE_RUN_DIR"};

/* A string the component expands (${NAME}) must expand where it runs: with the entry's env, what
 * the manager sets, and the environment here. */
static int check_expands(const marie_component_cfg_t *c, const marie_node_t *value, const char *name,
                         const char *s, marie_errors_t *errs)
{
    size_t n = c->nenv + sizeof manager_env / sizeof manager_env[0];
    char **env = strstr(s, "${") ? calloc(n, sizeof *env) : NULL;
    if (!env)
        return 0;
    if (c->nenv)        /* an entry without env has no array to copy */
        memcpy(env, c->env, c->nenv * sizeof *env);
    memcpy(env + c->nenv, manager_env, sizeof manager_env);
    char why[256] = "";
    int rc = marie_expand_check(s, env, n, why, sizeof why);
    free(env);
    if (rc < 0)
        marie_node_error(errs, value, "%s: %s (the component would refuse to start)", name, why);
    return rc;
}

/* The value must read as the declared type; messages carry the parameter's name. */
static int check_type(const marie_component_cfg_t *c, const marie_node_t *entry, marie_node_t *value,
                      const char *name, marie_errors_t *errs)
{
    const char *type = field(entry, "type");
    char *saved = value->key;
    value->key = (char *)name;
    int64_t i;
    double d;
    bool b;
    const char *s;
    int rc = 0;
    if (type && strcmp(type, "int") == 0)
        rc = marie_node_int(value, &i, errs);
    else if (type && strcmp(type, "double") == 0)
        rc = marie_node_double(value, &d, errs);
    else if (type && strcmp(type, "bool") == 0)
        rc = marie_node_bool(value, &b, errs);
    else if (type && strcmp(type, "string") == 0 && (rc = marie_node_str(value, &s, errs)) == 0)
        rc = check_expands(c, value, name, s, errs);
    value->key = saved;
    return rc;
}

/* "--param K=V" / "--param=K=V" (and --port) in a component's args: what= "param" or "port". */
static const char *arg_value(char **args, size_t nargs, size_t *i, const char *what)
{
    size_t wl = strlen(what);
    const char *a = args[*i];
    if (strncmp(a, "--", 2) != 0 || strncmp(a + 2, what, wl) != 0)
        return NULL;
    if (a[2 + wl] == '=')
        return a + 3 + wl;
    if (a[2 + wl] == 0 && *i + 1 < nargs)
        return args[++*i];
    return NULL;
}

static int check_args(const marie_node_t *spec, const marie_component_cfg_t *c, const char *kind,
                      marie_errors_t *errs)
{
    const marie_node_t *at = marie_node_get(c->node, "args");
    const char *file = c->file;
    int line = at ? at->line : c->line, col = at ? at->col : c->col, rc = 0;
    for (size_t i = 0; i < c->nargs; i++) {
        bool is_port = strncmp(c->args[i], "--port", 6) == 0;
        const char *kv = arg_value(c->args, c->nargs, &i, is_port ? "port" : "param");
        if (!kv)
            continue;
        const char *eq = strchr(kv, '=');
        const marie_node_t *e = eq ? find_entry(marie_node_get(spec, is_port ? "ports" : "params"), kv,
                                                (size_t)(eq - kv)) : NULL;
        if (!e) {
            marie_errors_add(errs, file, line, col, "args: --%s %s: %s '%s' has no such %s", is_port ? "port" : "param",
                             kv, kind, c->name, is_port ? "port" : "parameter");
            rc = -1;
            continue;
        }
        if (is_port) {
            if (strlen(eq + 1) == 0 || strlen(eq + 1) > 63) {
                marie_errors_add(errs, file, line, col, "args: --port %.*s: channel of %zu bytes (1 to 63: LCM "
                                 "sends no longer name)", (int)(eq - kv), kv, strlen(eq + 1));
                rc = -1;
            }
            continue;
        }
        char label[256];
        snprintf(label, sizeof label, "%s:%d:%d: args --param %.*s", file, line, col, (int)(eq - kv), kv);
        marie_doc_t *d = marie_doc_parse(label, eq + 1, strlen(eq + 1), errs);
        char name[128];
        snprintf(name, sizeof name, "%.*s", (int)(eq - kv), kv);
        if (!d || check_type(c, e, (marie_node_t *)marie_doc_root(d), name, errs) < 0)
            rc = -1;
        marie_doc_destroy(d);
    }
    return rc;
}

/* Is parameter/port `name` given in the args? */
static bool in_args(const marie_component_cfg_t *c, const char *what, const char *name)
{
    size_t nl = strlen(name);
    for (size_t i = 0; i < c->nargs; i++) {
        const char *kv = arg_value(c->args, c->nargs, &i, what);
        if (kv && strncmp(kv, name, nl) == 0 && kv[nl] == '=')
            return true;
    }
    return false;
}

static int check_params(const marie_node_t *spec, const marie_component_cfg_t *c, const char *kind,
                        marie_errors_t *errs)
{
    const marie_node_t *params = marie_node_get(spec, "params");
    int rc = 0;
    for (size_t i = 0; c->params && c->params->kind == MARIE_NODE_MAP && i < c->params->n; i++) {
        marie_node_t *g = c->params->items[i];
        const marie_node_t *e = find_entry(params, g->key, strlen(g->key));
        if (!e) {
            marie_errors_add(errs, g->file, g->key_line, g->key_col, "unknown parameter '%s' for %s '%s' (known: %s)",
                             g->key, kind, c->name, names_of(params));
            rc = -1;
        } else if (check_type(c, e, g, g->key, errs) < 0) {
            rc = -1;
        }
    }
    for (size_t i = 0; params && params->kind == MARIE_NODE_SEQ && i < params->n; i++) {
        const char *name = field(params->items[i], "name");
        if (!name || field(params->items[i], "default") || marie_node_get(c->params, name) ||
            in_args(c, "param", name))
            continue;
        marie_errors_add(errs, c->file, c->line, c->col, "%s '%s': missing required parameter '%s'", kind, c->name,
                         name);
        rc = -1;
    }
    return rc;
}

static int check_ports(const marie_node_t *spec, const marie_component_cfg_t *c, const char *kind,
                       marie_errors_t *errs)
{
    const marie_node_t *ports = marie_node_get(spec, "ports");
    int rc = 0;
    for (size_t i = 0; i < c->nports; i++) {
        const marie_port_binding_t *b = &c->ports[i];
        if (!find_entry(ports, b->name, strlen(b->name))) {
            marie_errors_add(errs, c->file, b->line, b->col, "%s '%s' has no port '%s' (ports: %s)", kind, c->name,
                             b->name, names_of(ports));
            rc = -1;
        }
    }
    for (size_t i = 0; ports && ports->kind == MARIE_NODE_SEQ && i < ports->n; i++) {
        const char *name = field(ports->items[i], "name");
        bool bound = !name || field(ports->items[i], "channel") || in_args(c, "port", name);
        for (size_t k = 0; !bound && k < c->nports; k++)
            bound = strcmp(c->ports[k].name, name) == 0;
        if (!bound) {
            marie_errors_add(errs, c->file, c->line, c->col, "%s '%s': port '%s' is not bound to a channel", kind,
                             c->name, name);
            rc = -1;
        }
    }
    return rc;
}

int marie_spec_check(const marie_node_t *spec, const marie_component_cfg_t *c, marie_errors_t *errs)
{
    const char *kind = field(spec, "kind");
    if (!kind)
        kind = "component";
    int rc = check_params(spec, c, kind, errs);
    rc |= check_ports(spec, c, kind, errs);
    rc |= check_args(spec, c, kind, errs);
    return rc;
}

bool marie_spec_valid(const marie_node_t *spec)
{
    const char *m = field(spec, "describe");
    return spec && spec->kind == MARIE_NODE_MAP && m && strcmp(m, MARIE_SPEC_MARKER) == 0;
}

/* ---- one type per channel, across components ---- */

typedef struct {
    const char *channel, *type, *port;
    const marie_component_cfg_t *c;
    bool out;
    int line, col;
} use_t;

/* Where port `name` of c is bound: its ports entry, a --port in its args, else the program's
 * default; position of the binding (the component's when it is the default). */
static const char *bound_channel(const marie_component_cfg_t *c, const char *name, const char *def, int *line,
                                 int *col)
{
    *line = c->line;
    *col = c->col;
    for (size_t k = 0; k < c->nports; k++)
        if (strcmp(c->ports[k].name, name) == 0) {
            *line = c->ports[k].line;
            *col = c->ports[k].col;
            return c->ports[k].channel;
        }
    size_t nl = strlen(name);
    const char *found = def;
    for (size_t i = 0; i < c->nargs; i++) {
        const char *kv = arg_value(c->args, c->nargs, &i, "port");
        const marie_node_t *at = marie_node_get(c->node, "args");
        if (kv && strncmp(kv, name, nl) == 0 && kv[nl] == '=') {
            found = kv + nl + 1;
            *line = at ? at->line : c->line;
            *col = at ? at->col : c->col;
        }
    }
    return found;
}

/* The typed ports of comp, with their channels, appended to *uses. */
static int collect_uses(const marie_node_t *spec, const marie_component_cfg_t *c, use_t **uses, size_t *n,
                        size_t *cap)
{
    const marie_node_t *ports = marie_node_get(spec, "ports");
    for (size_t i = 0; ports && ports->kind == MARIE_NODE_SEQ && i < ports->n; i++) {
        const marie_node_t *p = ports->items[i];
        const char *name = field(p, "name"), *type = field(p, "type"), *dir = field(p, "dir");
        use_t u = {.port = name, .type = type, .c = c, .out = dir && strcmp(dir, "out") == 0};
        if (!name || !type || !(u.channel = bound_channel(c, name, field(p, "channel"), &u.line, &u.col)))
            continue;
        if (MARIE_GROW(*uses, *cap, *n + 1) < 0)
            return -1;
        (*uses)[(*n)++] = u;
    }
    return 0;
}

int marie_spec_check_channels(const marie_node_t *const *spec, const marie_component_cfg_t *const *comp, size_t n,
                              marie_errors_t *errs)
{
    use_t *u = NULL;
    size_t nu = 0, cap = 0;
    int rc = 0;
    for (size_t i = 0; i < n && rc == 0; i++)
        if (spec[i])
            rc = collect_uses(spec[i], comp[i], &u, &nu, &cap);
    bool bad = false;
    for (size_t i = 0; rc == 0 && i < nu; i++) {
        /* the type the channel carries: its first output's, else its first input's */
        const use_t *ref = NULL;
        for (size_t k = 0; k < nu && !(ref && ref->out); k++)
            if (strcmp(u[k].channel, u[i].channel) == 0 && (!ref || u[k].out))
                ref = &u[k];
        if (ref == &u[i] || strcmp(ref->type, u[i].type) == 0)
            continue;
        marie_errors_add(errs, u[i].c->file, u[i].line, u[i].col, "channel '%s': port '%s' of '%s' %s %s, but port "
                         "'%s' of '%s' (line %d) %s %s", u[i].channel, u[i].port, u[i].c->name,
                         u[i].out ? "publishes" : "reads", u[i].type, ref->port, ref->c->name, ref->line,
                         ref->out ? "publishes" : "reads", ref->type);
        bad = true;
    }
    free(u);
    return rc || bad ? -1 : 0;
}
