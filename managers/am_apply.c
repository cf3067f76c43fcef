/* marie-am: an up order of a changed system while its components run applies the difference.
 * The components whose configuration hash changed and those the new file drops are stopped;
 * once they have exited the new system is installed around the others, which go on running
 * untouched (am_loading_install carries them over), and the changed and new ones start. */
#include <stdio.h>
#include <string.h>

#include "core/buf.h"
#include "core/clear.h"
#include "core/log.h"
#include "proto/am_proto.h"
#include "managers/am.h"

bool am_apply_busy(const am_t *am) { return am->applying != NULL; }

bool am_any_running(const am_t *am)
{
    for (size_t i = 0; i < am_ncomps(am); i++)
        if (am_comp_at(am, i)->sv.local && am_comp_at(am, i)->sv.pid > 0)
            return true;
    return false;
}

/* What the new system does here, as text: "applied the changes: restart a (configuration
 * changed); start b (new); stop c (removed); 4 unchanged". Returns how many it starts or stops. */
static int plan(am_t *am, const marie_system_t *next, char *out, size_t len)
{
    enum { RESTART, START, STOP, KEEP };
    static const char *const what[] = {"restart %s (configuration changed); ", "start %s (new); ",
                                       "stop %s (removed); "};
    marie_buf_t names[3] = {{0}}, text = {0};
    int n[4] = {0};
    for (size_t i = 0; i < am_ncomps(am); i++) {
        const comp_t *c = am_comp_at(am, i);
        if (!c->sv.local)
            continue;
        int k = am_comp_carried(c, next) ? KEEP : marie_system_component(next, c->cfg->name) ? RESTART : STOP;
        if (k != KEEP)
            marie_buf_printf(&names[k], "%s%s", n[k] ? ", " : "", c->cfg->name);
        n[k]++;
    }
    for (size_t i = 0; i < next->ncomponents; i++) {
        const marie_component_cfg_t *cfg = &next->components[i];
        if (!marie_system_component(am_system(am), cfg->name) &&
            strcmp(marie_am_component_host(next, cfg, am->env.host), am->env.host) == 0)
            marie_buf_printf(&names[START], "%s%s", n[START]++ ? ", " : "", cfg->name);
    }
    marie_buf_puts(&text, "applied the changes: ");
    for (int k = RESTART; k <= STOP; k++) {
        if (n[k])
            marie_buf_printf(&text, what[k], names[k].data);
        marie_buf_free(&names[k]);
    }
    marie_buf_printf(&text, "%d unchanged", n[KEEP]);
    snprintf(out, len, "%s", text.data ? text.data : "out of memory");
    marie_buf_free(&text);
    return n[RESTART] + n[START] + n[STOP];
}

/* Stop what the new system changes or drops; the order's answer says what it does here. */
int am_apply_start(am_t *am, am_loading_t *l, char *plan_text, size_t plan_len)
{
    const marie_system_t *next = am_loading_system(l);
    int n = plan(am, next, plan_text, plan_len);
    marie_info("%s", plan_text);
    for (size_t i = 0; i < am_ncomps(am); i++) {
        comp_t *c = am_comp_at(am, i);
        if (!c->sv.local || am_comp_carried(c, next))
            continue;
        if (marie_system_component(next, c->cfg->name)) {
            am_comp_stop(c);    /* changed: at once, whatever depends on it goes on */
        } else {                /* removed: after what depends on it, as a down does */
            marie_sv_state_t before = c->sv.st;
            marie_sv_action_t act;
            marie_sv_stop_later(&c->sv, am_now_us(), &act);
            am_comp_apply(c, before, &act);
        }
    }
    am->applying = l;
    am_progress_stops(am);
    am_apply_progress(am);
    return n;
}

/* Once every component the change stops has exited: the new system, the others carried over. */
void am_apply_progress(am_t *am)
{
    am_loading_t *l = am->applying;
    if (!l)
        return;
    const marie_system_t *next = am_loading_system(l);
    for (size_t i = 0; i < am_ncomps(am); i++) {
        comp_t *c = am_comp_at(am, i);
        if (!c->sv.local || c->sv.pid <= 0 || am_comp_carried(c, next))
            continue;
        if (c->sv.wanted)       /* started again by an order meanwhile */
            am_comp_stop(c);
        return;
    }
    am->applying = NULL;
    am_loading_install(am, l);
    am_up(am);
}

void am_apply_cancel(am_t *am)
{
    MARIE_CLEAR(am->applying, am_loading_free);
}
