/* mission: goal scheduling by priority and deadline, pure apart from the YAML tree reading. */
#include "adapters/mission/mission.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include "core/log.h"

void mission_init(mission_t *m)
{
    memset(m, 0, sizeof(*m));
    m->current = -1;
}

void mission_goal_options(const marie_node_t *g, mission_goal_t *o, marie_errors_t *errs)
{
    const marie_node_t *n;
    int64_t iv;
    const char *s;
    if ((n = marie_node_get(g, "id")) && marie_node_int(n, &iv, errs) == 0)
        o->id = (int32_t)iv;
    if ((n = marie_node_get(g, "priority")) && marie_node_int(n, &iv, errs) == 0)
        o->priority = (int32_t)iv;
    if ((n = marie_node_get(g, "deadline")) && marie_node_double(n, &o->deadline_s, errs) == 0 && o->deadline_s < 0)
        marie_errors_add(errs, n->file, n->line, n->col, "deadline: must be >= 0 (s after the mission starts)");
    if ((n = marie_node_get(g, "tolerance")) && marie_node_double(n, &o->tolerance, errs) == 0 && !(o->tolerance > 0))
        marie_errors_add(errs, n->file, n->line, n->col, "tolerance: must be > 0");
    if ((n = marie_node_get(g, "name")) && marie_node_str(n, &s, errs) == 0)
        snprintf(o->name, sizeof o->name, "%s", s);
}

int mission_parse(mission_t *m, const marie_node_t *seq, double default_tol, marie_errors_t *errs)
{
    static const char *const keys[] = { "id", "name", "x", "y", "theta", "priority", "deadline", "tolerance", NULL };
    size_t nerr = errs->n;
    if (!seq || seq->kind != MARIE_NODE_SEQ) {
        if (seq)
            marie_errors_add(errs, seq->file, seq->line, seq->col, "goals: expected a list of goals");
        else
            marie_errors_add(errs, "(params)", 0, 0, "goals: missing");
        return -1;
    }
    if (seq->n > MISSION_MAX_GOALS) {
        marie_errors_add(errs, seq->file, seq->line, seq->col, "goals: at most %d goals", MISSION_MAX_GOALS);
        return -1;
    }
    for (size_t i = 0; i < seq->n; i++) {
        const marie_node_t *g = seq->items[i];
        if (g->kind != MARIE_NODE_MAP) {
            marie_errors_add(errs, g->file, g->line, g->col, "goal %zu: expected a map with x and y", i + 1);
            continue;
        }
        marie_node_check_keys(g, keys, "goal", errs);
        mission_goal_t *o = &m->goals[m->n];
        memset(o, 0, sizeof(*o));
        o->id = (int32_t)(i + 1);
        o->tolerance = default_tol;
        snprintf(o->name, sizeof(o->name), "goal%zu", i + 1);
        const marie_node_t *n;
        if (!(n = marie_node_get(g, "x")))
            marie_errors_add(errs, g->file, g->line, g->col, "goal %zu: missing x", i + 1);
        else
            marie_node_double(n, &o->x, errs);
        if (!(n = marie_node_get(g, "y")))
            marie_errors_add(errs, g->file, g->line, g->col, "goal %zu: missing y", i + 1);
        else
            marie_node_double(n, &o->y, errs);
        if ((n = marie_node_get(g, "theta")))
            marie_node_double(n, &o->theta, errs);
        mission_goal_options(g, o, errs);
        if (!isfinite(o->x) || !isfinite(o->y) || !isfinite(o->theta))
            marie_errors_add(errs, g->file, g->line, g->col, "goal %zu: coordinates must be finite", i + 1);
        for (int k = 0; k < m->n; k++)
            if (m->goals[k].id == o->id)
                marie_errors_add(errs, g->file, g->line, g->col, "goal %zu: id %d used twice", i + 1, o->id);
        m->state[m->n] = MISSION_PENDING;
        m->n++;
    }
    return errs->n == nerr ? m->n : -1;
}

int64_t mission_deadline(const mission_t *m, int i)
{
    return m->goals[i].deadline_s > 0 ? m->start_utime + (int64_t)(m->goals[i].deadline_s * 1e6) : 0;
}

static void emit(mission_event_fn ev, void *user, const char *kind, const mission_goal_t *g, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
static void emit(mission_event_fn ev, void *user, const char *kind, const mission_goal_t *g, const char *fmt, ...)
{
    if (!ev)
        return;
    char text[200];
    MARIE_VFORMAT(text, fmt);
    ev(user, kind, g, text);
}

void mission_update(mission_t *m, int64_t now, const double *pose, mission_event_fn ev, void *user)
{
    if (m->done)
        return;
    if (!m->started) {
        m->started = true;
        m->start_utime = now;
    }
    /* The current goal: reached, or out of time. */
    if (m->current >= 0) {
        const mission_goal_t *g = &m->goals[m->current];
        int64_t dl = mission_deadline(m, m->current);
        if (pose && hypot(pose[0] - g->x, pose[1] - g->y) <= g->tolerance) {
            m->state[m->current] = MISSION_REACHED;
            m->reached++;
            emit(ev, user, "goal_reached", g, "goal %d '%s' reached after %.1f s", g->id, g->name,
                 (now - m->start_utime) / 1e6);
            m->current = -1;
        } else if (dl && now > dl) {
            m->state[m->current] = MISSION_MISSED;
            m->missed++;
            emit(ev, user, "goal_missed", g, "goal %d '%s' missed its deadline (%.0f s)", g->id, g->name, g->deadline_s);
            m->current = -1;
        }
    }
    /* Pending goals whose deadline has passed are skipped. */
    for (int i = 0; i < m->n; i++) {
        int64_t dl = mission_deadline(m, i);
        if (m->state[i] == MISSION_PENDING && dl && now > dl) {
            m->state[i] = MISSION_MISSED;
            m->missed++;
            emit(ev, user, "goal_missed", &m->goals[i], "goal %d '%s' skipped: deadline (%.0f s) passed",
                 m->goals[i].id, m->goals[i].name, m->goals[i].deadline_s);
        }
    }
    if (m->current >= 0)
        return;
    /* Next: highest priority, then earliest deadline, then list order. */
    int best = -1;
    for (int i = 0; i < m->n; i++) {
        if (m->state[i] != MISSION_PENDING)
            continue;
        if (best < 0) { best = i; continue; }
        const mission_goal_t *a = &m->goals[i], *b = &m->goals[best];
        int64_t da = mission_deadline(m, i), db = mission_deadline(m, best);
        if (a->priority > b->priority ||
            (a->priority == b->priority && da && (!db || da < db)))
            best = i;
    }
    if (best < 0) {
        m->done = true;
        emit(ev, user, "mission_done", NULL, "mission done: %lld of %d goals reached, %lld missed, %.1f s",
             (long long)m->reached, m->n, (long long)m->missed, (now - m->start_utime) / 1e6);
        return;
    }
    m->current = best;
    m->state[best] = MISSION_ACTIVE;
    const mission_goal_t *g = &m->goals[best];
    emit(ev, user, "goal_started", g, "goal %d '%s' (%.2f, %.2f), priority %d", g->id, g->name, g->x, g->y, g->priority);
}

int mission_restore(mission_t *m, int64_t start_utime, int current, const int32_t *ids, const int8_t *states, int n)
{
    if (n != m->n || current < -1 || current >= n)
        return -1;
    for (int i = 0; i < n; i++)
        if (ids[i] != m->goals[i].id || states[i] < MISSION_PENDING || states[i] > MISSION_MISSED)
            return -1;
    m->reached = m->missed = 0;
    for (int i = 0; i < n; i++) {
        m->state[i] = (mission_goal_state_t)states[i];
        m->reached += m->state[i] == MISSION_REACHED;
        m->missed += m->state[i] == MISSION_MISSED;
    }
    m->current = current;
    if (current >= 0)
        m->state[current] = MISSION_ACTIVE;
    m->started = true;
    m->start_utime = start_utime;
    m->done = false;    /* the next update declares it done if nothing is left */
    return 0;
}

void mission_give_up(mission_t *m, const char *why, mission_event_fn ev, void *user)
{
    if (m->current < 0)
        return;
    const mission_goal_t *g = &m->goals[m->current];
    m->state[m->current] = MISSION_MISSED;
    m->missed++;
    emit(ev, user, "goal_missed", g, "goal %d '%s' given up: %s", g->id, g->name, why);
    m->current = -1;
}
