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

void am_event_quiet(am_t *am, int sev, const char *kind, const char *text)
{
    char source[160];
    snprintf(source, sizeof source, "marie-am@%s", am->env.host);
    marie_event_t ev = {
        .utime = marie_wall_us(), .source = source, .seq = ++am->status.event_seq,
        .severity = (int8_t)sev, .kind = (char *)kind, .text = (char *)text,
    };
    marie_bus_publish_msg(am->env.lcm, MARIE_CH_EVENT, &marie_type_event_t, &ev);
}

void am_event(am_t *am, int sev, const char *kind, const char *fmt, ...)
{
    char text[512];
    MARIE_VFORMAT(text, fmt);
    am_event_quiet(am, sev, kind, text);
    if (sev >= MARIE_EVENT_T_SEV_WARN)
        marie_warn("%s: %s", kind, text);
    else
        marie_info("%s: %s", kind, text);
}

void am_status_init(am_t *am)
{
    am->status.start_mono = am_now_us();
    am->status.hz = am->env.opt.status_hz;
    marie_ratelimit_init(&am->status.answer_rl, AM_STATUS_ANSWER_RATE, AM_STATUS_ANSWER_BURST);
}

static void on_status_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user);

static void arm_timer(am_t *am)
{
    marie_loop_remove_timer(am->env.loop, am->status.timer);
    am->status.timer = marie_loop_add_timer(am->env.loop, (int64_t)(1e6 / am->status.hz), on_status_timer, am);
}

void am_status_start(am_t *am)
{
    arm_timer(am);
}

void am_status_set_hz(am_t *am, double hz)
{
    if (hz == am->status.hz)
        return;
    am->status.hz = hz;
    if (am->status.timer)
        arm_timer(am);
}

/* A request (marie ps) asks only for what this manager broadcasts anyway, so it is not signed;
 * the rate limit is what keeps a flood of them from turning into a flood of statuses. */
void am_on_status_request(am_t *am, const marie_am_status_request_t *rq)
{
    if (strcmp(rq->host, "*") != 0 && strcmp(rq->host, am->env.host) != 0)
        return;
    if (!marie_ratelimit_take(&am->status.answer_rl, am_now_us())) {
        am->status.requests_unanswered++;
        marie_warn_ratelimited(5, "status requests beyond %d a second: %lld not answered (the periodic status "
                               "goes on; last from '%s')", AM_STATUS_ANSWER_RATE,
                               (long long)am->status.requests_unanswered, rq->sender);
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
    for (size_t i = 0; i < am_ncomps(am); i++) {
        const comp_t *c = am_comp_at((am_t *)am, i);
        marie_sv_state_t st = c->sv.st;
        if (c->sv.local && (st == MARIE_SV_WAITING || st == MARIE_SV_STARTING ||
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
    if (!am->env.loop)
        return;
    if (!am->status.settled && am_settled(am)) {
        am_publish_status(am, false);
        return;
    }
    if (am->status.pending)
        return;
    am->status.pending = true;
    marie_loop_add_oneshot(am->env.loop, 20000, on_status_soon, am);
}

void am_publish_status(am_t *am, bool sample)
{
    int64_t now = am_now_us();
    marie_am_status_t st = {0};
    marie_am_component_status_t *cs = calloc(am_ncomps(am) ? am_ncomps(am) : 1, sizeof *cs);
    char (*limits)[160] = calloc(am_ncomps(am) ? am_ncomps(am) : 1, sizeof *limits);
    if (!cs || !limits)
        goto out;
    int n = 0;
    for (size_t i = 0; i < am_ncomps(am); i++) {
        comp_t *c = am_comp_at(am, i);
        if (!c->sv.local)
            continue;
        if (sample && c->sv.pid > 0) {
            int64_t cpu_us, rss;
            if (marie_proc_usage(c->sv.pid, &cpu_us, &rss) == 0) {
                c->use.cpu = marie_cpu_percent(&c->use.cpu_prev, cpu_us, now);
                c->use.rss = rss;
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
        s->cpu = c->sv.pid > 0 ? c->use.cpu : 0;
        s->rss = c->sv.pid > 0 ? c->use.rss : 0;
        s->heartbeat_age_us = c->sv.pid > 0 && c->sv.hb_us ? now - c->sv.hb_us : -1;
        s->config_hash = (char *)marie_component_hash(c->cfg);
        s->log_drops = am_output_drops(c);
        s->limits = (char *)am_limits_text(c, limits[n - 1], sizeof limits[0]);
        s->limit_breaches = am_limits_breaches(c);
    }
    if (sample) {
        int64_t cpu_us, rss;
        if (marie_proc_usage(getpid(), &cpu_us, &rss) == 0) {
            am->status.self_cpu_pct = marie_cpu_percent(&am->status.self_cpu, cpu_us, now);
            am->status.self_rss = rss;
        }
    }
    st.am_cpu = am->status.self_cpu_pct;      /* between samples: the last one */
    st.am_rss = am->status.self_rss;
    float load[3] = {0};
    marie_host_load(load);
    st.utime = marie_wall_us();
    st.host = am->env.host;
    st.pid = getpid();
    st.seq = ++am->status.seq;
    st.uptime_us = now - am->status.start_mono;
    const marie_system_t *sys = am_system(am);
    st.system = sys && sys->name ? sys->name : "";
    st.system_hash = (char *)am_system_hash(am);
    st.profile = am_profile(am) ? (char *)am_profile(am) : "";
    st.load1 = load[0];
    st.load5 = load[1];
    st.load15 = load[2];
    st.ncpu = (int32_t)sysconf(_SC_NPROCESSORS_ONLN);
    st.orders_refused = am_orders_refused(am);
    st.nhosts = sys ? (int32_t)sys->nhosts : 0;
    st.hosts = sys ? sys->hosts : NULL;
    st.ncomponents = n;
    st.components = cs;
    am_balance_status(am, &st, now);
    marie_bus_publish_msg(am->env.lcm, MARIE_CH_AM_STATUS, &marie_type_am_status_t, &st);
    am->status.settled = am_settled(am);
out:
    free(limits);
    free(cs);
}

static void on_status_soon(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    am_t *am = user;
    am->status.pending = false;
    am_publish_status(am, false);
}

static void on_status_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    am_t *am = user;
    marie_spawner_sweep(am->env.spawner);   /* what started children no longer use */
    am_publish_status(user, true);
    am_balance_decide(user);
}

void am_status_usage_reset(comp_t *c)
{
    c->use = (am_usage_t){0};
}
