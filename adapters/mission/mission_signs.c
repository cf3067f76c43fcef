/* mission_signs: goals found by reading signs, pure apart from the YAML tree reading. */
#include "adapters/mission/mission_signs.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* n: the search list, or NULL when the goal (at `goal`) has none. */
static int parse_search(mission_sign_t *s, const marie_node_t *goal, const marie_node_t *n, marie_errors_t *errs)
{
    if (!n || n->kind != MARIE_NODE_SEQ || n->n == 0 || n->n > MISSION_SIGN_SEARCH_MAX) {
        const marie_node_t *at = n ? n : goal;
        marie_errors_add(errs, at->file, at->line, at->col, "search: expected a list of 1 to %d points [x, y]",
                         MISSION_SIGN_SEARCH_MAX);
        return -1;
    }
    for (size_t i = 0; i < n->n; i++) {
        const marie_node_t *p = n->items[i];
        if (p->kind != MARIE_NODE_SEQ || p->n != 2 || marie_node_double(p->items[0], &s->search[i][0], errs) < 0 ||
            marie_node_double(p->items[1], &s->search[i][1], errs) < 0 || !isfinite(s->search[i][0]) ||
            !isfinite(s->search[i][1])) {
            marie_errors_add(errs, p->file, p->line, p->col, "search point %zu: expected [x, y] in metres", i + 1);
            return -1;
        }
    }
    s->nsearch = (int)n->n;
    return 0;
}

int mission_signs_parse(mission_signs_t *ss, mission_t *m, const marie_node_t *seq, double default_tol,
                        marie_errors_t *errs)
{
    static const char *const keys[] = { "message", "search", "approach", "name", "priority", "deadline",
                                        "tolerance", "id", NULL };
    memset(ss, 0, sizeof *ss);
    if (!seq || (seq->kind == MARIE_NODE_SEQ && seq->n == 0))
        return 0;
    size_t nerr = errs->n;
    if (seq->kind != MARIE_NODE_SEQ) {
        marie_errors_add(errs, seq->file, seq->line, seq->col, "signs: expected a list of {message, search, ...}");
        return -1;
    }
    for (size_t i = 0; i < seq->n; i++) {
        const marie_node_t *g = seq->items[i], *n;
        if (g->kind != MARIE_NODE_MAP || !marie_node_get(g, "message")) {
            marie_errors_add(errs, g->file, g->line, g->col, "sign goal %zu: expected a map with message and search",
                             i + 1);
            continue;
        }
        if (m->n >= MISSION_MAX_GOALS) {
            marie_errors_add(errs, g->file, g->line, g->col, "signs: at most %d goals in all", MISSION_MAX_GOALS);
            return -1;
        }
        marie_node_check_keys(g, keys, "sign goal", errs);
        mission_sign_t *s = &ss->s[ss->n];
        memset(s, 0, sizeof *s);
        s->approach = 1.0;
        const char *str;
        if (marie_node_str(marie_node_get(g, "message"), &str, errs) == 0)
            snprintf(s->message, sizeof s->message, "%s", str);
        if (parse_search(s, g, marie_node_get(g, "search"), errs) < 0)
            continue;
        if ((n = marie_node_get(g, "approach")) && marie_node_double(n, &s->approach, errs) == 0 &&
            !(s->approach > 0 && s->approach < 10))
            marie_errors_add(errs, n->file, n->line, n->col, "approach: expected 0 < m < 10");
        mission_goal_t *o = &m->goals[m->n];
        memset(o, 0, sizeof *o);
        o->id = 1000 + (int32_t)i;
        o->tolerance = default_tol;
        o->x = s->search[0][0];
        o->y = s->search[0][1];
        snprintf(o->name, sizeof o->name, "sign:%s", s->message);
        mission_goal_options(g, o, errs);
        for (int k = 0; k < m->n; k++)
            if (m->goals[k].id == o->id)
                marie_errors_add(errs, g->file, g->line, g->col, "sign goal %zu: id %d used twice", i + 1, o->id);
        s->goal = m->n;
        m->state[m->n++] = MISSION_PENDING;
        ss->n++;
    }
    return errs->n == nerr ? ss->n : -1;
}

int mission_signs_read(mission_signs_t *ss, mission_t *m, const char *message, double x, double y, double yaw,
                       double range, mission_event_fn ev, void *user)
{
    int moved = 0;
    for (int i = 0; i < ss->n; i++) {
        mission_sign_t *s = &ss->s[i];
        mission_goal_state_t st = m->state[s->goal];
        if (s->read || strcmp(s->message, message) != 0 || st == MISSION_REACHED || st == MISSION_MISSED)
            continue;
        mission_goal_t *g = &m->goals[s->goal];
        s->read = true;
        g->x = x + s->approach * cos(yaw);
        g->y = y + s->approach * sin(yaw);
        g->theta = remainder(yaw + M_PI, 2 * M_PI);      /* facing the sign */
        moved++;
        if (ev) {
            char text[160];
            snprintf(text, sizeof text, "goal %s: sign '%s' read at (%.3f, %.3f) from %.2f m; going to (%.2f, %.2f)",
                     g->name, s->message, x, y, range, g->x, g->y);
            ev(user, "sign_read", g, text);
        }
    }
    return moved;
}

int mission_signs_steer(mission_signs_t *ss, mission_t *m, const double *pose, mission_event_fn ev, void *user)
{
    if (!pose || m->current < 0)
        return 0;
    for (int i = 0; i < ss->n; i++) {
        mission_sign_t *s = &ss->s[i];
        if (s->goal != m->current || s->read)
            continue;
        mission_goal_t *g = &m->goals[s->goal];
        if (hypot(pose[0] - g->x, pose[1] - g->y) > g->tolerance)
            return 0;
        if (++s->next < s->nsearch) {
            g->x = s->search[s->next][0];
            g->y = s->search[s->next][1];
            return 1;
        }
        char why[96];
        snprintf(why, sizeof why, "sign '%s' not read along the search", s->message);
        mission_give_up(m, why, ev, user);
        return 1;
    }
    return 0;
}
