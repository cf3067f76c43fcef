/* component parameters and command line: options, --help, binding params from the system
 * file and --param, and filling the MARIE_PARAM_AT struct. */
#include "core/component.h"

#include <assert.h>
#include <errno.h>
#include <getopt.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/err.h"
#include "core/expand.h"
#include "core/bus/bus.h"
#include "core/time.h"
#include "core/spec.h"
#include "core/version.h"
#include "lcmtypes/marie_types.h"
#include "core/component_priv.h"

static const param_t *find_param(const marie_component_t *c, const char *name, marie_param_type_t type)
{
    for (size_t i = 0; i < c->nparams; i++) {
        if (strcmp(c->params[i].spec->name, name) == 0) {
            assert((c->params[i].spec->type == type || type == MARIE_PARAM_NODE) && "parameter read as another type");
            return &c->params[i];
        }
    }
    assert(!"no such parameter declared");
    return NULL;
}

int64_t marie_param_int(const marie_component_t *c, const char *name) { return find_param(c, name, MARIE_PARAM_INT)->i; }
double marie_param_double(const marie_component_t *c, const char *name) { return find_param(c, name, MARIE_PARAM_DOUBLE)->d; }
bool marie_param_bool(const marie_component_t *c, const char *name) { return find_param(c, name, MARIE_PARAM_BOOL)->b; }
const char *marie_param_str(const marie_component_t *c, const char *name) { return find_param(c, name, MARIE_PARAM_STRING)->s; }
const marie_node_t *marie_param_node(const marie_component_t *c, const char *name) { return find_param(c, name, MARIE_PARAM_NODE)->node; }
const void *marie_component_params(const marie_component_t *c) { return c->params_struct; }

/* Copies a bound parameter's value into the component's params struct. */
static void fill_one(marie_component_t *c, const param_t *pa)
{
    if (!pa->spec->bound || !c->params_struct)
        return;
    assert(pa->spec->offset < c->def->params_size && "MARIE_PARAM_AT outside params_size");
    void *at = (char *)c->params_struct + pa->spec->offset;
    switch (pa->spec->type) {
    case MARIE_PARAM_INT: memcpy(at, &pa->i, sizeof pa->i); break;
    case MARIE_PARAM_DOUBLE: memcpy(at, &pa->d, sizeof pa->d); break;
    case MARIE_PARAM_BOOL: memcpy(at, &pa->b, sizeof pa->b); break;
    case MARIE_PARAM_STRING: memcpy(at, &pa->s, sizeof pa->s); break;
    case MARIE_PARAM_NODE: memcpy(at, &pa->node, sizeof pa->node); break;
    }
}

/* Copies every bound parameter's value into the component's params struct. */
int marie_comp_fill_params(marie_component_t *c)
{
    if (!c->def->params_size)
        return 0;
    c->params_struct = calloc(1, c->def->params_size);
    if (!c->params_struct)
        return -1;
    for (size_t i = 0; i < c->nparams; i++)
        fill_one(c, &c->params[i]);
    return 0;
}


/* ---- creation ---- */


void marie_component_usage(const marie_component_def_t *def, const char *prog, FILE *out)
{
    fprintf(out, "usage: %s [--system FILE] [--name NAME] [--profile P] [--url URL] [--clock wall|sim]\n"
                 "       [--param KEY=VALUE]... [--port PORT=CHANNEL]... [--hold] [--describe] [--version]\n",
            prog ? prog : def->kind);
    fprintf(out, "ports:\n");
    for (const marie_port_spec_t *p = def->ports; p && p->name; p++)
        fprintf(out, "  %-16s %-4s %-6s %-28s default channel %s\n", p->name, p->dir == MARIE_IN ? "in" : "out",
                p->mech == MARIE_PUSH ? "push" : p->mech == MARIE_PULL ? "pull" : "event",
                p->type ? p->type->name : "raw", p->channel ? p->channel : "(must be bound)");
    fprintf(out, "params:\n");
    for (const marie_param_spec_t *p = def->params; p && p->name; p++)
        fprintf(out, "  %-20s default %-12s %s\n", p->name, p->def ? p->def : "(required)", p->help ? p->help : "");
}

int marie_comp_parse_options(const marie_component_def_t *def, int argc, char **argv, options_t *o, marie_errors_t *errs)
{
    static const struct option longopts[] = {
        {"system", required_argument, 0, 's'}, {"name", required_argument, 0, 'n'},
        {"profile", required_argument, 0, 'p'}, {"url", required_argument, 0, 'u'},
        {"clock", required_argument, 0, 'c'}, {"param", required_argument, 0, 'P'},
        {"port", required_argument, 0, 'o'}, {"hold", no_argument, 0, 'H'},
        {"help", no_argument, 0, 'h'}, {"describe", no_argument, 0, 'D'}, {"version", no_argument, 0, 'V'},
        {0, 0, 0, 0},
    };
    memset(o, 0, sizeof *o);
    o->system = getenv("MARIE_SYSTEM");
    o->name = getenv("MARIE_NAME");
    o->profile = getenv("MARIE_PROFILE");
    o->params = calloc((size_t)argc + 1, sizeof *o->params);
    o->ports = calloc((size_t)argc + 1, sizeof *o->ports);
    if (!o->params || !o->ports)
        return -1;
    optind = 1;
    opterr = 0;
    int ch;
    while ((ch = getopt_long(argc, argv, "", longopts, NULL)) != -1) {
        switch (ch) {
        case 's': o->system = optarg; break;
        case 'n': o->name = optarg; break;
        case 'p': o->profile = optarg; break;
        case 'u': o->url = optarg; break;
        case 'c': o->clock = optarg; break;
        case 'P': o->params[o->nparams++] = optarg; break;
        case 'o': o->ports[o->nports++] = optarg; break;
        case 'H': o->hold = true; break;
        case 'h': marie_component_usage(def, NULL, stdout); exit(0);
        case 'D': marie_spec_describe(def, stdout); exit(0);   /* for the managers' checks */
        case 'V': printf("%s (marie %s)\n", def->kind, MARIE_VERSION); exit(0);
        default:
            marie_errors_add(errs, "command line", 0, optind > 1 ? optind - 1 : 0, "unknown option '%s'",
                             argv[optind - 1]);
            return -1;
        }
    }
    if (optind < argc) {
        marie_errors_add(errs, "command line", 0, optind, "unexpected argument '%s'", argv[optind]);
        return -1;
    }
    if (o->clock && strcmp(o->clock, "wall") != 0 && strcmp(o->clock, "sim") != 0) {
        marie_errors_add(errs, "command line", 0, 0, "--clock: expected wall or sim, got '%s'", o->clock);
        return -1;
    }
    return 0;
}

static marie_doc_t *keep_doc(marie_component_t *c, marie_doc_t *d)
{
    marie_doc_t **n = realloc(c->docs, (c->ndocs + 1) * sizeof *n);
    if (!n) {
        marie_doc_destroy(d);
        return NULL;
    }
    c->docs = n;
    c->docs[c->ndocs++] = d;
    return d;
}

/* String parameters may name the environment (${MARIE_RUN_DIR}/can): one system file, per-run paths. */
static int expand_param(param_t *pa, const marie_node_t *node, marie_errors_t *errs)
{
    if (!strstr(pa->s, "${"))
        return 0;
    char why[256] = "";
    pa->expanded = marie_expand_env(pa->s, why, sizeof why);
    if (!pa->expanded) {
        marie_errors_add(errs, node->file, node->line, node->col, "%s: %s", pa->spec->name,
                         errno == ENOMEM ? strerror(errno) : why);
        return -1;
    }
    pa->s = pa->expanded;
    return 0;
}

int marie_comp_bind_params(marie_component_t *c, const options_t *o, marie_errors_t *errs)
{
    size_t n = 0;
    for (const marie_param_spec_t *p = c->def->params; p && p->name; p++)
        n++;
    c->params = calloc(n ? n : 1, sizeof *c->params);
    if (!c->params)
        return -1;
    c->nparams = n;
    int rc = 0;
    const marie_node_t *given = c->cfg ? c->cfg->params : NULL;
    /* Every configured parameter must be one the component declares. */
    for (size_t i = 0; given && i < given->n; i++) {
        const marie_node_t *g = given->items[i];
        bool known = false;
        for (size_t k = 0; k < n && !known; k++)
            known = strcmp(c->def->params[k].name, g->key) == 0;
        if (!known) {
            marie_errors_add(errs, g->file, g->key_line, g->key_col, "unknown parameter '%s' for %s '%s'", g->key,
                             c->def->kind, c->name);
            rc = -1;
        }
    }
    for (size_t i = 0; i < o->nparams; i++) {
        const char *eq = strchr(o->params[i], '=');
        bool known = false;
        for (size_t k = 0; eq && k < n && !known; k++)
            known = strlen(c->def->params[k].name) == (size_t)(eq - o->params[i]) &&
                    strncmp(c->def->params[k].name, o->params[i], (size_t)(eq - o->params[i])) == 0;
        if (!known) {
            marie_errors_add(errs, "command line", 0, 0, "--param %s: %s", o->params[i],
                             eq ? "unknown parameter" : "expected KEY=VALUE");
            rc = -1;
        }
    }
    for (size_t k = 0; k < n; k++) {
        param_t *pa = &c->params[k];
        pa->spec = &c->def->params[k];
        const char *name = pa->spec->name;
        size_t nlen = strlen(name);
        pa->node = marie_node_get(given, name);
        /* robot_radius and the like: the system file's one robot description. */
        if (!pa->node && c->sys && c->sys->robot && strncmp(name, "robot_", 6) == 0)
            pa->node = marie_node_get(c->sys->robot, name + 6);
        for (size_t i = 0; i < o->nparams; i++) {
            if (strncmp(o->params[i], name, nlen) == 0 && o->params[i][nlen] == '=') {
                char label[128];
                snprintf(label, sizeof label, "--param %s", name);
                const char *v = o->params[i] + nlen + 1;
                marie_doc_t *d = keep_doc(c, marie_doc_parse(label, v, strlen(v), errs));
                if (!d) {
                    rc = -1;
                    continue;
                }
                pa->node = marie_doc_root(d);
            }
        }
        if (!pa->node && pa->spec->def) {
            char label[128];
            snprintf(label, sizeof label, "default of %s.%s", c->def->kind, name);
            /* An empty default is the empty string, not an empty document. */
            const char *def = pa->spec->def[0] ? pa->spec->def : "''";
            marie_doc_t *d = keep_doc(c, marie_doc_parse(label, def, strlen(def), errs));
            pa->node = d ? marie_doc_root(d) : NULL;
        }
        if (!pa->node) {
            if (!pa->spec->def)
                marie_errors_add(errs, c->cfg ? c->cfg->file : "command line", c->cfg ? c->cfg->line : 0,
                                 c->cfg ? c->cfg->col : 0, "%s '%s': missing required parameter '%s'",
                                 c->def->kind, c->name, name);
            rc = pa->spec->type == MARIE_PARAM_NODE && pa->spec->def ? rc : -1;
            continue;
        }
        /* Labels in messages use the parameter's name. */
        marie_node_t *node = (marie_node_t *)pa->node;
        char *saved_key = node->key;
        node->key = (char *)name;
        int r = 0;
        switch (pa->spec->type) {
        case MARIE_PARAM_INT: r = marie_node_int(node, &pa->i, errs); break;
        case MARIE_PARAM_DOUBLE: r = marie_node_double(node, &pa->d, errs); break;
        case MARIE_PARAM_BOOL: r = marie_node_bool(node, &pa->b, errs); break;
        case MARIE_PARAM_STRING: r = marie_node_str(node, &pa->s, errs) < 0 ? -1 : expand_param(pa, node, errs); break;
        case MARIE_PARAM_NODE: break;
        }
        node->key = saved_key;
        rc |= r;
    }
    return rc;
}

/* ---- the resolved configuration, for runtimes in other languages (core/spec.h) ---- */

static const char *bus_url(const marie_component_t *c, const lcm_t *lcm)
{
    for (size_t i = 0; i < c->nbuses; i++)
        if (c->buses[i].lcm == lcm)
            return c->buses[i].url;
    return c->buses[0].url;
}

static void param_json(const param_t *pa, FILE *out)
{
    char *canon;
    switch (pa->spec->type) {
    case MARIE_PARAM_INT: fprintf(out, "%lld", (long long)pa->i); break;
    case MARIE_PARAM_DOUBLE: fprintf(out, "%.17g", pa->d); break;
    case MARIE_PARAM_BOOL: fputs(pa->b ? "true" : "false", out); break;
    case MARIE_PARAM_STRING: marie_spec_json_str(out, pa->s); break;
    case MARIE_PARAM_NODE:
        canon = pa->node ? marie_node_canonical(pa->node) : NULL;
        marie_spec_json_str(out, canon);
        free(canon);
        break;
    }
}

void marie_spec_resolved(const marie_component_t *c, FILE *out)
{
    const char *key = getenv("MARIE_KEY") && *getenv("MARIE_KEY") ? getenv("MARIE_KEY") : c->sys ? c->sys->key_file : NULL;
    fputs("{\"name\": ", out);
    marie_spec_json_str(out, c->name);
    fputs(", \"kind\": ", out);
    marie_spec_json_str(out, c->def->kind);
    fputs(", \"host\": ", out);
    marie_spec_json_str(out, c->host);
    fputs(", \"group\": ", out);
    marie_spec_json_str(out, c->cfg ? c->cfg->group : NULL);
    fputs(", \"url\": ", out);
    marie_spec_json_str(out, c->buses[0].url);
    fprintf(out, ", \"clock\": \"%s\", \"key_file\": ", marie_loop_clock(c->loop) == MARIE_CLOCK_SIM ? "sim" : "wall");
    marie_spec_json_str(out, key);
    fputs(", \"system\": ", out);
    marie_spec_json_str(out, c->sys ? c->sys->file : NULL);
    fputs(", \"profile\": ", out);
    marie_spec_json_str(out, c->sys ? c->sys->profile : NULL);
    fprintf(out, ", \"heartbeat_timeout_s\": %.17g, \"spin_us\": %d, \"hold\": %s, \"hash\": ",
            c->cfg ? c->cfg->heartbeat_timeout_s : 0.0, c->cfg ? c->cfg->sched.spin_us : 0, c->hold ? "true" : "false");
    marie_spec_json_str(out, c->cfg ? marie_component_hash(c->cfg) : NULL);
    fputs(", \"types\": [", out);
    for (size_t i = 0; c->sys && i < c->sys->ntypes; i++) {
        char path[4096];
        const char *t = c->sys->types[i], *slash = strrchr(c->sys->file, '/');
        if (t[0] == '/' || !slash)
            snprintf(path, sizeof path, "%s", t);
        else
            snprintf(path, sizeof path, "%.*s/%s", (int)(slash - c->sys->file), c->sys->file, t);
        fputs(i ? ", " : "", out);
        marie_spec_json_str(out, path);
    }
    fputs("],\n \"params\": {", out);
    for (size_t i = 0; i < c->nparams; i++) {
        fputs(i ? ", " : "", out);
        marie_spec_json_str(out, c->params[i].spec->name);
        fputs(": ", out);
        param_json(&c->params[i], out);
    }
    fputs("},\n \"ports\": {", out);
    for (size_t i = 0; i < c->nports; i++) {
        const marie_port_t *p = &c->ports[i];
        fputs(i ? ", " : "", out);
        marie_spec_json_str(out, p->spec->name);
        fputs(": {\"channel\": ", out);
        marie_spec_json_str(out, p->channel);
        fputs(", \"url\": ", out);
        marie_spec_json_str(out, bus_url(c, p->lcm));
        fprintf(out, ", \"shm\": %s, \"max_size\": %zu}", p->shm ? "true" : "false", p->shm ? p->shm->max_size : 0);
    }
    fputs("}}\n", out);
}

/* ---- parameters at run time (marie param) ---- */

int marie_component_on_param(marie_component_t *c, const char *name, marie_param_cb_t cb)
{
    for (size_t i = 0; i < c->nparams; i++)
        if (strcmp(c->params[i].spec->name, name) == 0) {
            c->params[i].on_change = cb;
            return 0;
        }
    return marie_fail(ENOENT);
}

static const char *const param_type_names[] = {"int", "double", "bool", "string", "node"};

/* A parameter's value as YAML text, into buf (or an allocated canonical text in *owned). */
static const char *param_text(const param_t *pa, char *buf, size_t len, char **owned)
{
    *owned = NULL;
    switch (pa->spec->type) {
    case MARIE_PARAM_INT: snprintf(buf, len, "%lld", (long long)pa->i); return buf;
    case MARIE_PARAM_DOUBLE: snprintf(buf, len, "%.17g", pa->d); return buf;
    case MARIE_PARAM_BOOL: return pa->b ? "true" : "false";
    case MARIE_PARAM_STRING: return pa->s ? pa->s : "";
    case MARIE_PARAM_NODE: return pa->node && (*owned = marie_node_canonical(pa->node)) ? *owned : "";
    }
    return "";
}

static void param_reply(marie_component_t *c, const marie_param_request_t *rq, bool ok, const char *why,
                        param_t *only)
{
    size_t n = only ? 1 : c->nparams;
    marie_param_value_t *vals = calloc(n ? n : 1, sizeof *vals);
    char (*bufs)[64] = calloc(n ? n : 1, sizeof *bufs);
    char **owned = calloc(n ? n : 1, sizeof *owned);
    for (size_t i = 0; vals && bufs && owned && ok && i < n; i++) {
        param_t *pa = only ? only : &c->params[i];
        vals[i] = (marie_param_value_t){(char *)pa->spec->name, (char *)param_type_names[pa->spec->type],
                                        (char *)param_text(pa, bufs[i], sizeof bufs[i], &owned[i]),
                                        pa->on_change != NULL, (char *)(pa->spec->help ? pa->spec->help : "")};
    }
    marie_param_reply_t r = {.utime = marie_wall_us(), .request_id = rq->request_id, .component = c->name,
                             .op = rq->op, .ok = ok, .reason = (char *)why,
                             .nparams = ok && vals && bufs && owned ? (int32_t)n : 0, .params = vals};
    marie_bus_publish_msg(c->buses[0].lcm, MARIE_CH_PARAM_REPLY, &marie_type_param_reply_t, &r);
    for (size_t i = 0; owned && i < n; i++)
        free(owned[i]);
    free(owned);
    free(bufs);
    free(vals);
}

/* Reads text as pa's type into pa (its doc kept by c). 0, or -1 with why. */
static int param_parse(marie_component_t *c, param_t *pa, const char *text, char *why, size_t wl)
{
    marie_errors_t errs = {0};
    char label[160];
    snprintf(label, sizeof label, "marie param set %s", pa->spec->name);
    marie_doc_t *d = keep_doc(c, marie_doc_parse(label, text[0] ? text : "''", text[0] ? strlen(text) : 2, &errs));
    marie_node_t *node = d ? (marie_node_t *)marie_doc_root(d) : NULL;
    int rc = node ? 0 : -1;
    if (node) {
        char *saved = node->key;
        node->key = (char *)pa->spec->name;
        switch (pa->spec->type) {
        case MARIE_PARAM_INT: rc = marie_node_int(node, &pa->i, &errs); break;
        case MARIE_PARAM_DOUBLE: rc = marie_node_double(node, &pa->d, &errs); break;
        case MARIE_PARAM_BOOL: rc = marie_node_bool(node, &pa->b, &errs); break;
        case MARIE_PARAM_STRING: rc = marie_node_str(node, &pa->s, &errs); break;
        case MARIE_PARAM_NODE: pa->node = node; break;
        }
        node->key = saved;
    }
    snprintf(why, wl, "%s", errs.n ? errs.msgs[0] : "not a value");
    marie_errors_clear(&errs);
    return rc;
}

static void param_set(marie_component_t *c, const marie_param_request_t *rq, param_t *pa)
{
    char why[400];
    if (c->auth) {
        marie_auth_result_t auth = marie_auth_check_param(c->auth, c->replay, rq);
        if (auth != MARIE_AUTH_OK) {
            snprintf(why, sizeof why, "order refused: %s", marie_auth_result_name(auth));
            marie_component_bad_input(c, "refused_orders", "param set %s from %s: %s", pa->spec->name, rq->sender, why);
            return param_reply(c, rq, false, why, NULL);
        }
    }
    if (!pa->on_change) {
        snprintf(why, sizeof why, "parameter '%s' is not dynamic: %s reads it at init (set it in the system file "
                 "or with --param, then restart)", pa->spec->name, c->def->kind);
        return param_reply(c, rq, false, why, NULL);
    }
    param_t old = *pa;
    if (param_parse(c, pa, rq->value, why, sizeof why) < 0) {
        *pa = old;
        return param_reply(c, rq, false, why, NULL);
    }
    fill_one(c, pa);
    c->fail_reason[0] = 0;
    if (pa->on_change(c, pa->spec->name) < 0) {
        snprintf(why, sizeof why, "refused: %s", c->fail_reason[0] ? c->fail_reason : "the component said no");
        *pa = old;
        fill_one(c, pa);
        return param_reply(c, rq, false, why, NULL);
    }
    marie_info("%s: parameter %s set to %s by %s", c->name, pa->spec->name, rq->value, rq->sender);
    marie_component_count(c, "params_set", 1);
    param_reply(c, rq, true, "ok", pa);
}

void marie_comp_on_param_request(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_component_t *c = user;
    marie_param_request_t rq;
    if (marie_decode_checked(&marie_type_param_request_t, rbuf->data, rbuf->data_size, &rq) < 0) {
        marie_component_bad_input(c, "bad_param_request", "undecodable parameter request (%u bytes)", rbuf->data_size);
        return;
    }
    param_t *pa = NULL;
    for (size_t i = 0; i < c->nparams && !pa; i++)
        if (strcmp(c->params[i].spec->name, rq.name) == 0)
            pa = &c->params[i];
    if (strcmp(rq.target, c->name) != 0) {
        marie_param_request_t_decode_cleanup(&rq);
        return;
    }
    if (rq.op == MARIE_PARAM_REQUEST_T_OP_LIST)
        param_reply(c, &rq, true, "ok", NULL);
    else if (rq.op != MARIE_PARAM_REQUEST_T_OP_GET && rq.op != MARIE_PARAM_REQUEST_T_OP_SET)
        param_reply(c, &rq, false, "unknown operation", NULL);
    else if (!pa)
        param_reply(c, &rq, false, "no such parameter", NULL);
    else if (rq.op == MARIE_PARAM_REQUEST_T_OP_GET)
        param_reply(c, &rq, true, "ok", pa);
    else
        param_set(c, &rq, pa);
    marie_param_request_t_decode_cleanup(&rq);
}
