/* marie-am's voice on the bus: events, and the status of its components (on a timer, and
 * shortly after any change). */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/component.h"
#include "core/bus/bus.h"
#include "core/log.h"
#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_types.h"
#include "managers/am.h"

void am_event(am_t *am, int sev, const char *kind, const char *fmt, ...)
{
    char text[512], source[160];
    MARIE_VFORMAT(text, fmt);
    snprintf(source, sizeof source, "marie-am@%s", am->host);
    marie_event_t ev = {
        .utime = marie_wall_us(), .source = source, .seq = ++am->event_seq,
        .severity = (int8_t)sev, .kind = (char *)kind, .text = text,
    };
    marie_bus_publish_msg(am->lcm, MARIE_CH_EVENT, &marie_type_event_t, &ev);
    if (sev >= MARIE_EVENT_T_SEV_WARN)
        marie_warn("%s: %s", kind, text);
    else
        marie_info("%s: %s", kind, text);
}

/* A request (marie ps) asks only for what this manager broadcasts anyway, so it is not signed;
 * the rate limit is what keeps a flood of them from turning into a flood of statuses. */
void am_on_status_request(am_t *am, const marie_am_status_request_t *rq)
{
    if (strcmp(rq->host, "*") != 0 && strcmp(rq->host, am->host) != 0)
        return;
    if (!marie_ratelimit_take(&am->status_answer_rl, am_now_us())) {
        am->status_requests_unanswered++;
        marie_warn_ratelimited(5, "status requests beyond %d a second: %lld not answered (the periodic status "
                               "goes on; last from '%s')", AM_STATUS_ANSWER_RATE,
                               (long long)am->status_requests_unanswered, rq->sender);
        return;
    }
    marie_debug("status requested by '%s'", rq->sender);
    am_publish_status(am, false);
}

static void on_status_soon(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user);
static bool am_settled(const am_t *am);

/* No component between two states (waiting, starting, stopping, in backoff): what `marie up`,
 * `marie down` and a restart wait for. */
static bool am_settled(const am_t *am)
{
    for (size_t i = 0; i < am->ncomps; i++) {
        marie_sv_state_t st = am->comps[i].sv.st;
        if (am->comps[i].sv.local && (st == MARIE_SV_WAITING || st == MARIE_SV_STARTING ||
                                      st == MARIE_SV_STOPPING || st == MARIE_SV_BACKOFF))
            return false;
    }
    return true;
}

/* Changes are gathered for 20 ms (a bring-up of 45 components is 135 of them), but a host
 * that has just settled says so at once: waiting out the window was a fifth of a one-host
 * bring-up. Only the change into a settled state skips the window, so a flood of changes
 * (states shown in the heartbeats) still costs one status per window. */
void am_status_changed(am_t *am)
{
    if (!am->loop)
        return;
    if (!am->status_settled && am_settled(am)) {
        am_publish_status(am, false);
        return;
    }
    if (am->status_pending)
        return;
    am->status_pending = true;
    marie_loop_add_oneshot(am->loop, 20000, on_status_soon, am);
}

void am_publish_status(am_t *am, bool sample)
{
    int64_t now = am_now_us();
    marie_am_status_t st = {0};
    marie_am_component_status_t *cs = calloc(am->ncomps ? am->ncomps : 1, sizeof *cs);
    char (*limits)[160] = calloc(am->ncomps ? am->ncomps : 1, sizeof *limits);
    if (!cs || !limits)
        goto out;
    int n = 0;
    for (size_t i = 0; i < am->ncomps; i++) {
        comp_t *c = &am->comps[i];
        if (!c->sv.local)
            continue;
        if (sample && c->sv.pid > 0) {
            int64_t cpu_us, rss;
            if (marie_proc_usage(c->sv.pid, &cpu_us, &rss) == 0) {
                c->cpu = marie_cpu_percent(&c->cpu_prev, cpu_us, now);
                c->rss = rss;
            }
        }
        marie_am_component_status_t *s = &cs[n++];
        const char *name = marie_sv_state_name(c->sv.st);
        if (c->sv.st == MARIE_SV_RUNNING && c->sv.hb_state == MARIE_STATE_PAUSED)
            name = "paused";
        else if (c->sv.st == MARIE_SV_RUNNING && c->sv.hb_state == MARIE_STATE_READY)
            name = "ready";
        else if (c->sv.st == MARIE_SV_RUNNING && c->sv.hb_state == MARIE_STATE_DEGRADED)
            name = "degraded";
        s->name = c->cfg->name;
        s->group = c->cfg->group ? c->cfg->group : "";
        s->state = (char *)name;
        s->comp_state = (int8_t)(c->sv.pid > 0 ? c->sv.hb_state : -1);
        s->pid = c->sv.pid;
        s->uptime_us = c->sv.pid > 0 ? now - c->sv.started_us : 0;
        s->restarts = c->sv.restarts;
        s->last_exit = c->sv.last_exit;
        s->cpu = c->sv.pid > 0 ? c->cpu : 0;
        s->rss = c->sv.pid > 0 ? c->rss : 0;
        s->heartbeat_age_us = c->sv.pid > 0 && c->sv.hb_us ? now - c->sv.hb_us : -1;
        s->config_hash = (char *)marie_component_hash(c->cfg);
        s->log_drops = c->drops_total;
        s->limits = (char *)am_limits_text(c, limits[n - 1], sizeof limits[0]);
        s->limit_breaches = c->lim.breaches;
    }
    if (sample) {
        int64_t cpu_us, rss;
        if (marie_proc_usage(getpid(), &cpu_us, &rss) == 0) {
            am->self_cpu_pct = marie_cpu_percent(&am->self_cpu, cpu_us, now);
            am->self_rss = rss;
        }
    }
    st.am_cpu = am->self_cpu_pct;      /* between samples: the last one */
    st.am_rss = am->self_rss;
    float load[3] = {0};
    marie_host_load(load);
    st.utime = marie_wall_us();
    st.host = am->host;
    st.pid = getpid();
    st.seq = ++am->status_seq;
    st.uptime_us = now - am->start_mono;
    st.system = am->sys && am->sys->name ? am->sys->name : "";
    st.system_hash = am->sys ? am->sys_hash : "";
    st.profile = am->profile ? am->profile : "";
    st.load1 = load[0];
    st.load5 = load[1];
    st.load15 = load[2];
    st.ncpu = (int32_t)sysconf(_SC_NPROCESSORS_ONLN);
    st.orders_refused = am->orders_refused;
    st.nhosts = am->sys ? (int32_t)am->sys->nhosts : 0;
    st.hosts = am->sys ? am->sys->hosts : NULL;
    st.ncomponents = n;
    st.components = cs;
    st.balance_leader = "";
    st.balance_last = am->bal_last;
    if (am->bal) {
        st.balance_leader = (char *)(balance_leads(am->bal) ? am->host : balance_leader(am->bal, now));
        st.balance_term = balance_term(am->bal);
    }
    marie_bus_publish_msg(am->lcm, MARIE_CH_AM_STATUS, &marie_type_am_status_t, &st);
    am->status_settled = am_settled(am);
out:
    free(limits);
    free(cs);
}

static void on_status_soon(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    am_t *am = user;
    am->status_pending = false;
    am_publish_status(am, false);
}

void am_on_status_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    am_t *am = user;
    marie_spawner_sweep(am->spawner);   /* what started children no longer use */
    am_publish_status(user, true);
    am_balance_decide(user);
}
