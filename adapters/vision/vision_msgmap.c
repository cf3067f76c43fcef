/* vision_msgmap: "message reading": tag ids mapped by configuration to messages and goals. */
#include "adapters/vision/vision_msgmap.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"
#include "lcmtypes/marie_event_t.h"

static const char *const entry_keys[] = { "id", "message", "kind", "severity", "goal", NULL };
static const char *const goal_keys[] = { "x", "y", "theta", "tolerance", "priority", "name", "id", NULL };

static int parse_severity(const marie_node_t *n, int *out, marie_errors_t *errs)
{
    static const char *const names[] = { "debug", "info", "warn", "error" };
    const char *s;
    if (marie_node_str(n, &s, errs) < 0)
        return -1;
    for (int i = 0; i < 4; i++)
        if (strcmp(s, names[i]) == 0) {
            *out = i;   /* the order of marie_event_t SEV_DEBUG..SEV_ERROR */
            return 0;
        }
    marie_errors_add(errs, n->file, n->line, n->col, "severity: expected debug, info, warn or error, got '%s'", s);
    return -1;
}

static int opt_double(const marie_node_t *map, const char *key, double def, double *out, marie_errors_t *errs)
{
    const marie_node_t *n = marie_node_get(map, key);
    *out = def;
    if (!n)
        return 0;
    if (marie_node_double(n, out, errs) < 0)
        return -1;
    if (!isfinite(*out)) {
        marie_errors_add(errs, n->file, n->line, n->col, "%s: expected a finite number", key);
        return -1;
    }
    return 0;
}

static int parse_goal(const marie_node_t *g, vision_msg_t *m, marie_errors_t *errs)
{
    if (g->kind != MARIE_NODE_MAP) {
        marie_errors_add(errs, g->file, g->line, g->col, "goal: expected a map with x, y, theta");
        return -1;
    }
    int rc = marie_node_check_keys(g, goal_keys, "goal", errs) < 0 ? -1 : 0;
    if (!marie_node_get(g, "x") || !marie_node_get(g, "y")) {
        marie_errors_add(errs, g->file, g->line, g->col, "goal: x and y are required");
        rc = -1;
    }
    rc |= opt_double(g, "x", 0, &m->x, errs);
    rc |= opt_double(g, "y", 0, &m->y, errs);
    rc |= opt_double(g, "theta", 0, &m->theta, errs);
    rc |= opt_double(g, "tolerance", 0.2, &m->tolerance, errs);
    const marie_node_t *n;
    int64_t v;
    if ((n = marie_node_get(g, "priority"))) {
        if (marie_node_int(n, &v, errs) < 0)
            rc = -1;
        m->priority = (int)v;
    }
    m->goal_id = m->tag_id;
    if ((n = marie_node_get(g, "id"))) {
        if (marie_node_int(n, &v, errs) < 0)
            rc = -1;
        m->goal_id = (int)v;
    }
    const char *s = NULL;
    if ((n = marie_node_get(g, "name")) && marie_node_str(n, &s, errs) < 0)
        rc = -1;
    m->goal_name = strdup(s ? s : "");
    m->has_goal = true;
    return rc ? -1 : 0;
}

static int parse_entry(const marie_node_t *e, vision_msg_t *m, marie_errors_t *errs)
{
    if (e->kind != MARIE_NODE_MAP) {
        marie_errors_add(errs, e->file, e->line, e->col, "messages: each entry must be a map with id and message or goal");
        return -1;
    }
    int rc = marie_node_check_keys(e, entry_keys, "messages entry", errs) < 0 ? -1 : 0;
    const marie_node_t *n = marie_node_get(e, "id");
    int64_t id = -1;
    if (!n) {
        marie_errors_add(errs, e->file, e->line, e->col, "messages entry: id is required");
        rc = -1;
    } else if (marie_node_int(n, &id, errs) < 0) {
        rc = -1;
    } else if (id < 0 || id > INT32_MAX) {
        marie_errors_add(errs, n->file, n->line, n->col, "id: expected a tag id >= 0, got %lld", (long long)id);
        rc = -1;
    }
    m->tag_id = (int)id;
    m->severity = MARIE_EVENT_T_SEV_INFO;
    const char *s;
    if ((n = marie_node_get(e, "message"))) {
        if (marie_node_str(n, &s, errs) < 0)
            rc = -1;
        else
            m->text = strdup(s);
    }
    s = "tag_message";
    if ((n = marie_node_get(e, "kind")) && marie_node_str(n, &s, errs) < 0)
        rc = -1;
    m->kind = strdup(s);
    if ((n = marie_node_get(e, "severity")) && parse_severity(n, &m->severity, errs) < 0)
        rc = -1;
    if ((n = marie_node_get(e, "goal")) && parse_goal(n, m, errs) < 0)
        rc = -1;
    if (!marie_node_get(e, "message") && !marie_node_get(e, "goal")) {
        marie_errors_add(errs, e->file, e->line, e->col, "messages entry for id %d: needs a message, a goal or both", m->tag_id);
        rc = -1;
    }
    return rc;
}

int vision_msgmap_parse(const marie_node_t *seq, vision_msgmap_t *m, marie_errors_t *errs)
{
    memset(m, 0, sizeof *m);
    if (!seq)
        return 0;
    if (seq->kind != MARIE_NODE_SEQ) {
        marie_errors_add(errs, seq->file, seq->line, seq->col, "messages: expected a list of {id, message, goal}");
        return marie_fail(EINVAL);
    }
    m->items = calloc(seq->n ? seq->n : 1, sizeof *m->items);
    if (!m->items)
        return marie_fail(ENOMEM);
    int rc = 0;
    for (size_t i = 0; i < seq->n; i++) {
        vision_msg_t *it = &m->items[m->n++];
        if (parse_entry(seq->items[i], it, errs) < 0) {
            rc = -1;
            continue;
        }
        for (size_t j = 0; j + 1 < m->n; j++)
            if (m->items[j].tag_id == it->tag_id) {
                const marie_node_t *e = seq->items[i];
                marie_errors_add(errs, e->file, e->line, e->col, "messages: tag id %d is mapped twice", it->tag_id);
                rc = -1;
            }
    }
    if (rc < 0)
        vision_msgmap_clear(m);
    return rc < 0 ? marie_fail(EINVAL) : 0;
}

const vision_msg_t *vision_msgmap_find(const vision_msgmap_t *m, int tag_id)
{
    for (size_t i = 0; i < m->n; i++)
        if (m->items[i].tag_id == tag_id)
            return &m->items[i];
    return NULL;
}

void vision_msgmap_clear(vision_msgmap_t *m)
{
    for (size_t i = 0; i < m->n; i++) {
        free(m->items[i].text);
        free(m->items[i].kind);
        free(m->items[i].goal_name);
    }
    free(m->items);
    memset(m, 0, sizeof *m);
}
