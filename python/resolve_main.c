/* marie-resolve: a component's configuration resolved by libmarie for a runtime in another
 * language (python/marie): its description on stdin, its command line as arguments, the same
 * options, environment, system file, profiles, checks and errors as a C component; the result
 * as JSON on stdout (core/spec.h, marie_spec_resolved), or file:line:col errors and status 2. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/component.h"
#include "core/spec.h"
#include "core/version.h"

#define MAX_ENTRIES 256

static const char *field(const marie_node_t *e, const char *key)
{
    const marie_node_t *n = marie_node_get(e, key);
    return n && n->kind == MARIE_NODE_SCALAR && n->quoted ? n->value : NULL;
}

static int param_type(const char *t)
{
    static const char *const names[] = {"int", "double", "bool", "string", "node"};
    for (int i = 0; t && i < 5; i++)
        if (strcmp(t, names[i]) == 0)
            return i;
    return -1;
}

/* The description as a component definition (raw ports: the types matter to the caller only). */
static int make_def(const marie_node_t *spec, marie_component_def_t *def, marie_port_spec_t *ports,
                    marie_param_spec_t *params)
{
    const marie_node_t *pl = marie_node_get(spec, "ports"), *ql = marie_node_get(spec, "params");
    size_t np = pl && pl->kind == MARIE_NODE_SEQ ? pl->n : 0, nq = ql && ql->kind == MARIE_NODE_SEQ ? ql->n : 0;
    if (np >= MAX_ENTRIES || nq >= MAX_ENTRIES)
        return -1;
    for (size_t i = 0; i < np; i++) {
        const marie_node_t *e = pl->items[i];
        const char *dir = field(e, "dir"), *mech = field(e, "mech");
        if (!field(e, "name") || !dir || !mech)
            return -1;
        ports[i] = (marie_port_spec_t){field(e, "name"), NULL, strcmp(dir, "out") == 0 ? MARIE_OUT : MARIE_IN,
                                       strcmp(mech, "pull") == 0 ? MARIE_PULL : strcmp(mech, "event") == 0 ? MARIE_EVENT : MARIE_PUSH,
                                       field(e, "channel")};
    }
    for (size_t i = 0; i < nq; i++) {
        const marie_node_t *e = ql->items[i];
        int t = param_type(field(e, "type"));
        if (!field(e, "name") || t < 0)
            return -1;
        params[i] = (marie_param_spec_t){field(e, "name"), (marie_param_type_t)t, field(e, "default"), field(e, "help")};
    }
    *def = (marie_component_def_t){.kind = field(spec, "kind"), .ports = ports, .params = params};
    return def->kind ? 0 : -1;
}

int main(int argc, char **argv)
{
    if (argc == 2 && (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "--version") == 0)) {
        printf("usage: PROG --describe | marie-resolve [COMPONENT OPTIONS...]   (marie %s)\n"
               "The configuration of a component in another language (python/marie), resolved by libmarie:\n"
               "its description on stdin, its options as arguments, JSON on stdout.\n", MARIE_VERSION);
        return 0;
    }
    static char text[1 << 20];
    size_t len = fread(text, 1, sizeof text - 1, stdin);
    marie_errors_t errs = {0};
    marie_doc_t *doc = marie_doc_parse("description", text, len, &errs);
    static marie_port_spec_t ports[MAX_ENTRIES];
    static marie_param_spec_t params[MAX_ENTRIES];
    marie_component_def_t def;
    if (!doc || !marie_spec_valid(marie_doc_root(doc)) || make_def(marie_doc_root(doc), &def, ports, params) < 0) {
        marie_errors_print(&errs, stderr);
        fprintf(stderr, "marie-resolve: stdin is not a component description (PROG --describe)\n");
        return 1;
    }
    marie_component_t *c = marie_component_create(&def, argc, argv, NULL, &errs);
    if (!c) {
        marie_errors_print(&errs, stderr);
        return 2;
    }
    marie_spec_resolved(c, stdout);
    marie_component_destroy(c);
    marie_doc_destroy(doc);
    return 0;
}
