/* marie-am's orders: up, down, start, stop, restart, move, pause, resume, tail and ping, each
 * checked (signature, freshness, targets) and answered once. */

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/clear.h"
#include "core/component.h"
#include "core/bus/bus.h"
#include "core/log.h"
#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_lifecycle_command_t.h"
#include "lcmtypes/marie_types.h"
#include "managers/am.h"

typedef struct {
    am_t *am;
    const char *component;
    int64_t req;
} tail_ctx_t;

static void tail_line_cb(const char *line, size_t len, void *user)
{
    tail_ctx_t *t = user;
    char text[MARIE_LINE_MAX + 128];
    snprintf(text, sizeof text, "%.*s", (int)len, line);
    marie_log_line_t m = {
        .utime = marie_wall_us(), .host = t->am->env.host, .component = (char *)t->component,
        .stream = MARIE_LOG_LINE_T_STDOUT, .request_seq = t->req, .text = text,
    };
    marie_bus_publish_msg(t->am->env.lcm, MARIE_CH_LOG, &marie_type_log_line_t, &m);
}

static void reply(am_t *am, const marie_am_order_t *o, bool ok, int affected, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
static void reply(am_t *am, const marie_am_order_t *o, bool ok, int affected, const char *fmt, ...)
{
    char reason[1024];
    MARIE_VFORMAT(reason, fmt);
    marie_am_reply_t r = {
        .utime = marie_wall_us(), .host = am->env.host, .sender = o->sender, .seq = o->seq, .ok = ok,
        .reason = reason, .affected = affected,
    };
    const marie_system_t *sys = am_system(am);
    r.nhosts = sys ? (int32_t)sys->nhosts : 0;
    r.hosts = sys ? sys->hosts : NULL;
    marie_bus_publish_msg(am->env.lcm, MARIE_CH_AM_REPLY, &marie_type_am_reply_t, &r);
    am_status_changed(am);      /* a status soon after every answer, for marie's waits */
}

static void send_lifecycle(am_t *am, comp_t *c, int cmd, int64_t req)
{
    char sender[160];
    snprintf(sender, sizeof sender, "marie-am@%s", am->env.host);
    int64_t seq = marie_wall_us();
    if (seq <= am->orders.lc_seq)
        seq = am->orders.lc_seq + 1;
    am->orders.lc_seq = seq;
    marie_lifecycle_command_t m = {
        .utime = marie_wall_us(), .request_id = req, .sender = sender, .target = c->cfg->name,
        .command = (int8_t)cmd, .seq = seq,
    };
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    if (am->env.auth)
        marie_auth_sign_command(am->env.auth, &m, mac);
    marie_bus_publish_msg(am->env.lcm, MARIE_CH_LIFECYCLE, &marie_type_lifecycle_command_t, &m);
}

/* An up order's programs checked (am_check.c): load and start the system, or refuse it. */
static void up_checked(am_t *am, am_loading_t *l, bool ok, const char *errors, void *user)
{
    marie_am_order_t *o = user;
    if (!ok) {
        reply(am, o, false, 0, "system file refused:\n%s", errors);
        am_loading_free(l);
    } else if (am_any_running(am)) {
        char plan[900];
        int n = am_apply_start(am, l, plan, sizeof plan);
        reply(am, o, true, n, "%s", plan);
    } else {
        am_loading_install(am, l);
        am_up(am);
        int n = 0;
        for (size_t i = 0; i < am_ncomps(am); i++)
            n += am_comp_at(am, i)->sv.local;
        reply(am, o, true, n, "ok");
    }
    marie_am_order_t_destroy(o);
}

static void order_up(am_t *am, const marie_am_order_t *o)
{
    const char *profile = o->arg;
    if (am_apply_busy(am)) {
        reply(am, o, false, 0, "busy: the last up is being applied");
        return;
    }
    if (am_system_is(am, o->system_text, profile)) {
        am_up(am);
        reply(am, o, true, 0, "ok");
        return;
    }
    /* before the copy am_loading_sent makes: the pending check's system may be that very file */
    if (am_check_busy(am)) {
        reply(am, o, false, 0, "busy: the programs of the last up are being checked");
        return;
    }
    marie_errors_t errs = {0};
    am_loading_t *l = am_loading_sent(am, o->system_text, o->system_path, profile, &errs);
    if (!l) {
        char *msg = NULL;
        size_t ml = 0;
        FILE *m = open_memstream(&msg, &ml);
        if (m) {
            marie_errors_print(&errs, m);
            fclose(m);
        }
        reply(am, o, false, 0, "system file refused:\n%s", msg ? msg : "");
        free(msg);
        marie_errors_clear(&errs);
        return;
    }
    const char *running = am_any_running(am) ? am_system(am)->name : NULL, *next = am_loading_system(l)->name;
    if (running && strcmp(running, next ? next : "") != 0) {
        /* a change applies to the system that runs; another one replaces it only after a down */
        reply(am, o, false, 0, "another system (%s) is running here: marie down first", running);
        am_loading_free(l);
        return;
    }
    marie_am_order_t *copy = marie_am_order_t_copy(o);
    if (!copy) {
        am_loading_free(l);
        reply(am, o, false, 0, "out of memory");
    } else if (am_check_start(am, l, up_checked, copy) < 0) {
        marie_am_order_t_destroy(copy);
        reply(am, o, false, 0, "cannot check the programs: %s", strerror(errno));
    }
}

/* A refused order is counted always, but answered and announced within a rate limit, so a
 * flood of forgeries or replays cannot make the manager flood the bus; the answer says why
 * and nothing more (no hosts: the sender may not hold the key). */
static void refuse_order(am_t *am, const marie_am_order_t *o, marie_auth_result_t ar)
{
    am->orders.refused++;
    marie_warn_ratelimited(1, "refused %s order from '%s' (seq %lld): %s (%lld refused so far)",
                           marie_am_op_name(o->op), o->sender, (long long)o->seq, marie_auth_result_name(ar),
                           (long long)am->orders.refused);
    if (!marie_ratelimit_take(&am->orders.refusal_rl, am_now_us())) {
        am->orders.refusals_unannounced++;
        return;
    }
    char reason[200], text[200];
    int64_t now = marie_wall_us();
    if (ar == MARIE_AUTH_STALE || ar == MARIE_AUTH_FUTURE)
        snprintf(reason, sizeof reason, "refused: %s (utime %+.1f s, seq %+.1f s from this host's clock; "
                 "accepted: %+.1f..%+.1f s)", marie_auth_result_name(ar), (double)(o->utime - now) / 1e6,
                 (double)(o->seq - now) / 1e6, -(double)(am->orders.lifetime_us + am->orders.max_skew_us) / 1e6,
                 (double)am->orders.max_skew_us / 1e6);
    else
        snprintf(reason, sizeof reason, "refused: %s", marie_auth_result_name(ar));
    snprintf(text, sizeof text, "%s (%lld refused, %lld not announced)", marie_auth_result_name(ar),
             (long long)am->orders.refused, (long long)am->orders.refusals_unannounced);
    am_event_quiet(am, MARIE_EVENT_T_SEV_WARN, "order_refused", text);
    marie_am_reply_t r = {
        .utime = now, .host = am->env.host, .sender = o->sender, .seq = o->seq, .ok = false, .reason = reason,
    };
    marie_bus_publish_msg(am->env.lcm, MARIE_CH_AM_REPLY, &marie_type_am_reply_t, &r);
    am_status_changed(am);
}

static void order_down(am_t *am, const marie_am_order_t *o)
{
    am_check_cancel(am, "cancelled by a down order\n");
    am_apply_cancel(am);
    am_down(am);
    int n = 0;
    for (size_t i = 0; i < am_ncomps(am); i++)
        n += am_comp_at(am, i)->sv.local && am_comp_at(am, i)->sv.pid > 0;
    am_stop_all(am);
    am_progress_stops(am);
    reply(am, o, true, n, "ok");
}

static void order_move(am_t *am, const marie_am_order_t *o)
{
    if (o->ntargets != 1 || !am_host_known(am, o->arg)) {
        reply(am, o, false, 0, "move: unknown host '%s'", o->arg);
        return;
    }
    comp_t *c = am_comp_find(am, o->targets[0]);
    if (!c) {
        reply(am, o, false, 0, "move: '%s' is not a component", o->targets[0]);
        return;
    }
    bool affected = c->sv.local || strcmp(o->arg, am->env.host) == 0;
    am_apply_move(am, c, o->arg);
    am_save_up_state(am);
    am_try_start_waiting(am);
    am_status_changed(am);
    reply(am, o, true, affected, "ok");
}

/* One component named by a start/stop/restart/pause/resume/tail order; -1: not such an order. */
static int order_one(am_t *am, comp_t *c, const marie_am_order_t *o)
{
    switch (o->op) {
    case MARIE_AM_ORDER_T_OP_START:
        am_comp_open_log(c);
        am_comp_want(c);
        return 0;
    case MARIE_AM_ORDER_T_OP_STOP:
        am_comp_stop(c);
        return 0;
    case MARIE_AM_ORDER_T_OP_RESTART:
        am_comp_open_log(c);
        am_comp_restart(c);
        return 0;
    case MARIE_AM_ORDER_T_OP_PAUSE:
        send_lifecycle(am, c, MARIE_CMD_PAUSE, o->seq);
        return 0;
    case MARIE_AM_ORDER_T_OP_RESUME:
        send_lifecycle(am, c, MARIE_CMD_RESUME, o->seq);
        return 0;
    case MARIE_AM_ORDER_T_OP_TAIL: {
        char path[PATH_MAX];
        snprintf(path, sizeof path, "%s/logs/%s.log", am->env.state_dir, c->cfg->name);
        tail_ctx_t tc = {am, c->cfg->name, o->seq};
        int lines = atoi(o->arg);
        marie_logfile_tail(path, lines > 0 ? lines : 20, tail_line_cb, &tc);
        return 0;
    }
    default:
        return -1;
    }
}

void am_on_order(am_t *am, const marie_am_order_t *o)
{
    if (strcmp(o->host, "*") != 0 && strcmp(o->host, am->env.host) != 0)
        return;
    marie_auth_result_t ar = marie_auth_check_order(am->env.auth, am->orders.replay, o);
    if (ar != MARIE_AUTH_OK) {
        refuse_order(am, o, ar);
        return;
    }
    marie_info("order %s from %s (seq %lld)", marie_am_op_name(o->op), o->sender, (long long)o->seq);
    if (o->op == MARIE_AM_ORDER_T_OP_PING) {
        reply(am, o, true, 0, "ok");
        return;
    }
    if (o->op == MARIE_AM_ORDER_T_OP_UP) {
        order_up(am, o);
        return;
    }
    if (!am_system(am)) {
        reply(am, o, false, 0, "no system loaded: marie up FILE first");
        return;
    }
    if (o->op == MARIE_AM_ORDER_T_OP_DOWN) {
        order_down(am, o);
        return;
    }
    /* every target must name a component or a group of the system */
    for (int t = 0; t < o->ntargets; t++) {
        bool known = false;
        for (size_t i = 0; i < am_ncomps(am) && !known; i++)
            known = am_comp_matches(am_comp_at(am, i), o->targets[t]);
        if (!known) {
            reply(am, o, false, 0, "no component or group named '%s'", o->targets[t]);
            return;
        }
    }
    if (o->op == MARIE_AM_ORDER_T_OP_MOVE) {
        order_move(am, o);
        return;
    }
    int n = 0;
    for (size_t i = 0; i < am_ncomps(am); i++) {
        comp_t *c = am_comp_at(am, i);
        bool hit = false;
        for (int t = 0; t < o->ntargets; t++)
            hit |= am_comp_matches(c, o->targets[t]);
        if (!hit || !c->sv.local)
            continue;
        n++;
        if (order_one(am, c, o) < 0) {
            reply(am, o, false, 0, "unknown order %d", o->op);
            return;
        }
    }
    am_try_start_waiting(am);
    reply(am, o, true, n, "ok");
}

int am_orders_init(am_t *am)
{
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/order-seq", am->env.state_dir);
    am->orders.lifetime_us = am->env.opt.order_lifetime_us;
    am->orders.max_skew_us = am->env.opt.max_skew_us;
    am->orders.replay = marie_replay_create_window(path, am->orders.lifetime_us, am->orders.max_skew_us);
    if (!am->orders.replay) {
        marie_error("replay table %s: %s", path, strerror(errno));
        return -1;
    }
    marie_ratelimit_init(&am->orders.refusal_rl, 5, 10);
    return 0;
}

int64_t am_orders_refused(const am_t *am) { return am->orders.refused; }

void am_orders_free(am_t *am)
{
    MARIE_CLEAR(am->orders.replay, marie_replay_destroy);
}
