/* am_balance: marie-am's side of automatic placement: statuses in, signed moves out. */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "core/clear.h"
#include "core/log.h"
#include "lcmtypes/marie_event_t.h"
#include "managers/am.h"

static bool runs(const char *state)
{
    return strcmp(state, "running") == 0 || strcmp(state, "degraded") == 0 || strcmp(state, "starting") == 0;
}

/* Every status (our own too) feeds the decisions; a returning manager adopts what it hears. */
void am_balance_on_status(am_t *am, const marie_am_status_t *st)
{
    if (!am->balance.b)
        return;
    int64_t now = am_now_us();
    balance_heard(am->balance.b, st->host, st->balance_term, strcmp(st->balance_leader, st->host) == 0, st->ncpu, now);
    for (int i = 0; i < st->ncomponents; i++) {
        const marie_am_component_status_t *cs = &st->components[i];
        balance_sample(am->balance.b, st->host, cs->name, cs->cpu, runs(cs->state), now);
        comp_t *c = am_comp_find(am, cs->name);
        if (am->balance.adopt_until && runs(cs->state) && c && c->sv.local && strcmp(st->host, am->env.host) != 0) {
            am_event(am, MARIE_EVENT_T_SEV_INFO, "balance", "%s runs on %s now: not starting it here",
                     c->cfg->name, st->host);
            am_apply_move(am, c, st->host);
            am_save_up_state(am);
        }
    }
}

void am_balance_decide(am_t *am)
{
    balance_move_t m;
    if (!am->balance.b || am->balance.adopt_until || !am_is_up(am) || !balance_step(am->balance.b, am_now_us(), &m))
        return;
    snprintf(am->balance.last, sizeof am->balance.last, "%s", m.reason);
    if (!am->env.auth) {
        am_event(am, MARIE_EVENT_T_SEV_WARN, "balance", "%s: not done, no key to sign the move", m.reason);
        return;
    }
    am_event(am, m.why == BALANCE_OVERLOAD ? MARIE_EVENT_T_SEV_INFO : MARIE_EVENT_T_SEV_WARN, "balance",
             "%s (term %lld)", m.reason, (long long)balance_term(am->balance.b));
    /* Decided: the next step must not decide it again before the order comes back. */
    balance_placed(am->balance.b, m.component, m.to, am_now_us());
    char *targets[] = {m.component};
    marie_am_order_t o = {.host = "*", .op = MARIE_AM_ORDER_T_OP_MOVE, .ntargets = 1, .targets = targets, .arg = m.to};
    if (marie_am_send_order_as(am->env.lcm, am->env.auth, &o, am->balance.sender, NULL) < 0)
        marie_warn("balance: cannot send the move of %s", m.component);
    am_status_changed(am);
}

/* Moves made while this manager was away (a failover) come back through the other managers'
 * statuses: it listens first, then starts what is still placed here. */
void am_balance_up_when_placed(am_t *am)
{
    if (!am->balance.b) {
        am_up(am);
        return;
    }
    double wait_s = am->balance.cfg.host_lost_s + 0.5;
    am->balance.adopt_until = am_now_us() + (int64_t)(wait_s * 1e6);
    marie_info("learning the current placement for %.1f s before starting anything", wait_s);
}

void am_balance_tick(am_t *am)
{
    if (am->balance.adopt_until && am_now_us() >= am->balance.adopt_until) {
        am->balance.adopt_until = 0;
        am_up(am);
    }
}

/* A system installed: placement as its balance: section says (the system outlives it). */
void am_balance_install(am_t *am, const marie_system_t *sys, const balance_cfg_t *cfg)
{
    MARIE_CLEAR(am->balance.b, balance_destroy);
    am->balance.cfg = *cfg;
    snprintf(am->balance.sender, sizeof am->balance.sender, "balance@%.128s", am->env.host);
    if (cfg->enabled && !(am->balance.b = balance_create(am->env.host, sys, &am->balance.cfg)))
        marie_error("automatic placement off: %s", strerror(errno));
}

void am_balance_placed(am_t *am, const char *component, const char *host)
{
    if (am->balance.b)
        balance_placed(am->balance.b, component, host, am_now_us());
}

void am_balance_status(const am_t *am, marie_am_status_t *st, int64_t now)
{
    st->balance_leader = "";
    st->balance_last = (char *)am->balance.last;
    if (am->balance.b) {
        st->balance_leader = (char *)(balance_leads(am->balance.b) ? am->env.host : balance_leader(am->balance.b, now));
        st->balance_term = balance_term(am->balance.b);
    }
}

void am_balance_free(am_t *am)
{
    MARIE_CLEAR(am->balance.b, balance_destroy);
}
