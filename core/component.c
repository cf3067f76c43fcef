/* component: lifecycle state machine, ports over LCM, params, heartbeat and events. */
#include "core/component.h"

#include <assert.h>
#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/auth.h"
#include "core/expand.h"
#include "core/typeinfo.h"
#include "core/spec.h"
#include "lcmtypes/marie_types.h"

#define EVENT_QUEUE_MAX 256

typedef struct {
    int64_t request_id;
    marie_port_t *port;
    marie_timer_t *timeout;
    marie_pull_cb_t cb;         /* NULL for a blocking pull */
    void *user;
    /* blocking pull result */
    void *msg;
    int64_t age_us;
    int status;
    int done;
} pull_t;

typedef struct {
    void *data;
    size_t len;
    int64_t recv_utime;
} queued_t;

struct marie_port {
    marie_component_t *c;
    const marie_port_spec_t *spec;
    char *channel;
    lcm_t *lcm;
    lcm_subscription_t *sub;
    marie_msg_cb_t cb;
    void *scratch;              /* decoded message */
    uint8_t *buf;               /* encode buffer */
    size_t bufcap;
    queued_t *queue;            /* event port: held while not running */
    size_t nqueue;
};

typedef struct {
    const marie_param_spec_t *spec;
    const marie_node_t *node;
    int64_t i;
    double d;
    bool b;
    const char *s;
    char *expanded;             /* s after ${VAR} expansion, when it differed */
} param_t;

typedef struct {
    char *name;
    int64_t value;
} counter_t;

typedef struct {
    marie_component_t *c;
    marie_tick_cb_t cb;
    marie_timer_t *timer;
} tick_t;

typedef struct {
    char *url;
    lcm_t *lcm;
} bus_t;

struct marie_component {
    const marie_component_def_t *def;
    void *user;
    char *name;
    char host[64];
    marie_system_t *sys;
    const marie_component_cfg_t *cfg;
    void *params_struct;        /* def->params_size bytes, filled from MARIE_PARAM_AT entries */
    marie_doc_t **docs;         /* defaults and --param values */
    size_t ndocs;
    param_t *params;
    size_t nparams;
    marie_port_t *ports;
    size_t nports;
    bus_t *buses;               /* buses[0] is the system bus */
    size_t nbuses;
    marie_loop_t *loop;
    marie_state_t state;
    bool initialised;           /* on_init succeeded and on_quit has not run */
    bool hold;
    char reason[400];
    char fail_reason[256];
    bool degraded;              /* heartbeat says degraded while running */
    char degraded_reason[256];
    int64_t start_mono;
    int64_t msgs_in, msgs_out, drops, bad_input, overruns;
    counter_t *counters;
    size_t ncounters;
    int64_t hb_seq, event_seq;
    tick_t **ticks;
    size_t nticks;
    pull_t **pulls;
    size_t npulls;
    int64_t next_request_id;
    char reply_channel[128];
    bool reply_subscribed;
    marie_auth_t *auth;         /* set: only signed, fresh lifecycle orders are obeyed */
    marie_replay_t *replay;
};

/* ---- names ---- */

static const char *const state_names[] = {"created", "ready", "running", "paused", "failed", "exited", "degraded"};
static const char *const cmd_names[] = {"?", "init", "start", "stop", "pause", "resume", "restart", "abort", "quit"};

const char *marie_state_name(marie_state_t s)
{
    return (unsigned)s < sizeof state_names / sizeof *state_names ? state_names[s] : "unknown";
}

const char *marie_cmd_name(marie_cmd_t c)
{
    return c >= MARIE_CMD_INIT && c <= MARIE_CMD_QUIT ? cmd_names[c] : "unknown";
}

int marie_cmd_parse(const char *name)
{
    for (int i = MARIE_CMD_INIT; i <= MARIE_CMD_QUIT; i++)
        if (strcmp(name, cmd_names[i]) == 0)
            return i;
    return -1;
}

/* ---- counters ---- */

static counter_t *find_counter(marie_component_t *c, const char *name, bool create)
{
    for (size_t i = 0; i < c->ncounters; i++)
        if (strcmp(c->counters[i].name, name) == 0)
            return &c->counters[i];
    if (!create)
        return NULL;
    counter_t *n = realloc(c->counters, (c->ncounters + 1) * sizeof *n);
    if (!n)
        return NULL;
    c->counters = n;
    c->counters[c->ncounters] = (counter_t){strdup(name), 0};
    if (!c->counters[c->ncounters].name)
        return NULL;
    return &c->counters[c->ncounters++];
}

void marie_component_count(marie_component_t *c, const char *counter, int64_t delta)
{
    counter_t *k = find_counter(c, counter, true);
    if (k)
        k->value += delta;
}

int64_t marie_component_counter(const marie_component_t *c, const char *counter)
{
    counter_t *k = find_counter((marie_component_t *)c, counter, false);
    return k ? k->value : 0;
}

void marie_component_bad_input(marie_component_t *c, const char *counter, const char *fmt, ...)
{
    char msg[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    c->bad_input++;
    if (counter)
        marie_component_count(c, counter, 1);
    marie_warn_ratelimited(5, "%s: bad input (%s, %lld so far): %s", c->name, counter ? counter : "bad_input",
                           (long long)c->bad_input, msg);
}

void marie_component_drop(marie_component_t *c, int64_t n) { c->drops += n; }

void marie_component_count_io(marie_component_t *c, int64_t in, int64_t out)
{
    c->msgs_in += in;
    c->msgs_out += out;
}

/* ---- heartbeat and events ---- */

void marie_component_heartbeat(marie_component_t *c)
{
    marie_heartbeat_t hb;
    memset(&hb, 0, sizeof hb);
    marie_counter_t counters[64];
    hb.utime = marie_wall_us();
    hb.component = c->name;
    hb.host = c->host;
    hb.pid = (int32_t)getpid();
    hb.seq = ++c->hb_seq;
    bool degraded = c->degraded && c->state == MARIE_STATE_RUNNING;
    hb.state = (int8_t)(degraded ? MARIE_STATE_DEGRADED : c->state);
    hb.reason = degraded ? c->degraded_reason : c->reason;
    hb.uptime_us = marie_mono_us() - c->start_mono;
    hb.msgs_in = c->msgs_in;
    hb.msgs_out = c->msgs_out;
    hb.drops = c->drops;
    hb.bad_input = c->bad_input;
    hb.overruns = c->overruns;
    hb.ncounters = (int32_t)(c->ncounters < 64 ? c->ncounters : 64);
    for (int i = 0; i < hb.ncounters; i++)
        counters[i] = (marie_counter_t){c->counters[i].name, c->counters[i].value};
    hb.counters = counters;
    marie_heartbeat_t_publish(c->buses[0].lcm, MARIE_CH_HEARTBEAT, &hb);
}

void marie_component_event(marie_component_t *c, int severity, const char *kind, const char *fmt, ...)
{
    char text[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    marie_event_t ev = {
        .utime = marie_wall_us(), .source = c->name, .seq = ++c->event_seq,
        .severity = (int8_t)severity, .kind = (char *)kind, .text = text,
    };
    if (marie_event_t_publish(c->buses[0].lcm, MARIE_CH_EVENT, &ev) != 0)
        c->drops++;
    marie_log_level_t lvl = severity >= MARIE_EVENT_T_SEV_ERROR  ? MARIE_LOG_ERROR
                            : severity >= MARIE_EVENT_T_SEV_WARN ? MARIE_LOG_WARN
                                                                 : MARIE_LOG_INFO;
    MARIE_LOG_AT(lvl, "event %s: %s", kind, text);
}

void marie_component_set_degraded(marie_component_t *c, bool degraded, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->degraded_reason, sizeof c->degraded_reason, fmt, ap);
    va_end(ap);
    if (degraded == c->degraded)
        return;
    c->degraded = degraded;
    MARIE_LOG_AT(degraded ? MARIE_LOG_WARN : MARIE_LOG_INFO, "%s: %s (%s)", c->name,
                 degraded ? "degraded" : "no longer degraded", c->degraded_reason);
    marie_component_heartbeat(c);
}

/* ---- lifecycle ---- */

static void flush_event_queues(marie_component_t *c);

static void set_state(marie_component_t *c, marie_state_t s, const char *why)
{
    c->state = s;
    if (why != c->reason)
        snprintf(c->reason, sizeof c->reason, "%s", why);
    marie_debug("%s: now %s (%s)", c->name, marie_state_name(s), why);
    marie_component_heartbeat(c);
}

void marie_component_fail_reason(marie_component_t *c, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->fail_reason, sizeof c->fail_reason, fmt, ap);
    va_end(ap);
}

/* Runs a hook; on refusal leaves the reason in c->reason. */
static int hook(marie_component_t *c, int (*fn)(marie_component_t *), const char *what)
{
    if (!fn)
        return 0;
    c->fail_reason[0] = 0;
    if (fn(c) == 0)
        return 0;
    snprintf(c->reason, sizeof c->reason, "%s failed: %s", what, c->fail_reason[0] ? c->fail_reason : "refused");
    return -1;
}

static void quit_hook(marie_component_t *c)
{
    if (c->initialised && c->def->on_quit)
        c->def->on_quit(c);
    c->initialised = false;
}

int marie_component_command(marie_component_t *c, marie_cmd_t cmd, const char **reason)
{
    marie_state_t s = c->state;
    const marie_component_def_t *d = c->def;
    int rc = -1;
    *reason = c->reason;
    if (s == MARIE_STATE_EXITED) {
        snprintf(c->reason, sizeof c->reason, "%s refused: the component has exited", marie_cmd_name(cmd));
        return -1;
    }
    switch (cmd) {
    case MARIE_CMD_INIT:
        if (s != MARIE_STATE_CREATED && s != MARIE_STATE_FAILED)
            break;
        if (s == MARIE_STATE_FAILED)
            quit_hook(c);
        if (hook(c, d->on_init, "init") < 0)
            return -1;
        c->initialised = true;
        set_state(c, MARIE_STATE_READY, "init");
        return 0;
    case MARIE_CMD_START:
        if (s != MARIE_STATE_READY)
            break;
        if (hook(c, d->on_start, "start") < 0)
            return -1;
        set_state(c, MARIE_STATE_RUNNING, "start");
        flush_event_queues(c);
        return 0;
    case MARIE_CMD_STOP:
        if (s != MARIE_STATE_RUNNING && s != MARIE_STATE_PAUSED)
            break;
        if (hook(c, d->on_stop, "stop") < 0)
            return -1;
        set_state(c, MARIE_STATE_READY, "stop");
        return 0;
    case MARIE_CMD_PAUSE:
        if (s != MARIE_STATE_RUNNING)
            break;
        if (hook(c, d->on_pause, "pause") < 0)
            return -1;
        set_state(c, MARIE_STATE_PAUSED, "pause");
        return 0;
    case MARIE_CMD_RESUME:
        if (s != MARIE_STATE_PAUSED)
            break;
        if (hook(c, d->on_resume, "resume") < 0)
            return -1;
        set_state(c, MARIE_STATE_RUNNING, "resume");
        flush_event_queues(c);
        return 0;
    case MARIE_CMD_RESTART:
        if (s == MARIE_STATE_CREATED)
            break;
        if ((s == MARIE_STATE_RUNNING || s == MARIE_STATE_PAUSED) && hook(c, d->on_stop, "stop") < 0)
            return -1;
        if (s == MARIE_STATE_FAILED) {
            quit_hook(c);
            if (hook(c, d->on_init, "init") < 0) {
                set_state(c, MARIE_STATE_FAILED, c->reason);
                return -1;
            }
            c->initialised = true;
        }
        if (hook(c, d->on_start, "start") < 0) {
            set_state(c, MARIE_STATE_READY, c->reason);
            return -1;
        }
        set_state(c, MARIE_STATE_RUNNING, "restart");
        flush_event_queues(c);
        return 0;
    case MARIE_CMD_ABORT:
        if (d->on_abort && c->initialised)
            d->on_abort(c);
        set_state(c, MARIE_STATE_FAILED, "abort");
        return 0;
    case MARIE_CMD_QUIT:
        if ((s == MARIE_STATE_RUNNING || s == MARIE_STATE_PAUSED) && d->on_stop)
            d->on_stop(c);
        quit_hook(c);
        set_state(c, MARIE_STATE_EXITED, "quit");
        marie_loop_quit(c->loop);
        return 0;
    default:
        snprintf(c->reason, sizeof c->reason, "unknown command %d", (int)cmd);
        return -1;
    }
    rc = -1;
    snprintf(c->reason, sizeof c->reason, "%s refused in state %s", marie_cmd_name(cmd), marie_state_name(s));
    return rc;
}

static void reply(marie_component_t *c, int64_t request_id, int cmd, bool ok, const char *why)
{
    marie_lifecycle_reply_t r = {
        .utime = marie_wall_us(), .request_id = request_id, .component = c->name,
        .command = (int8_t)cmd, .ok = ok, .state = (int8_t)c->state, .reason = (char *)why,
    };
    marie_lifecycle_reply_t_publish(c->buses[0].lcm, MARIE_CH_LIFECYCLE_REPLY, &r);
}

static bool targets_me(const marie_component_t *c, const char *target)
{
    return strcmp(target, "*") == 0 || strcmp(target, c->name) == 0 ||
           (c->cfg && c->cfg->group && strcmp(target, c->cfg->group) == 0);
}

static void on_lifecycle(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_component_t *c = user;
    marie_lifecycle_command_t cmd;
    if (marie_decode_checked(&marie_type_lifecycle_command_t, rbuf->data, rbuf->data_size, &cmd) < 0) {
        marie_component_bad_input(c, "bad_lifecycle", "undecodable lifecycle command (%u bytes)", rbuf->data_size);
        reply(c, -1, 0, false, "malformed lifecycle command");
        return;
    }
    if (targets_me(c, cmd.target)) {
        const char *why = "ok";
        int rc = -1;
        marie_auth_result_t auth = c->auth ? marie_auth_check_command(c->auth, c->replay, &cmd) : MARIE_AUTH_OK;
        char refused[64];
        if (auth != MARIE_AUTH_OK) {
            /* Anyone on the robot's LAN can send multicast: with a key, only signed orders count. */
            snprintf(refused, sizeof refused, "order refused: %s", marie_auth_result_name(auth));
            marie_component_bad_input(c, "refused_orders", "%s %s from %s", refused, marie_cmd_name(cmd.command),
                                      cmd.sender);
            why = refused;
        } else if (cmd.command < MARIE_CMD_INIT || cmd.command > MARIE_CMD_QUIT) {
            marie_component_bad_input(c, "bad_lifecycle", "unknown lifecycle command %d", cmd.command);
            why = "unknown command";
        } else {
            rc = marie_component_command(c, (marie_cmd_t)cmd.command, &why);
            if (rc < 0)
                marie_component_count(c, "refused_commands", 1);
        }
        if (auth == MARIE_AUTH_OK)      /* refusals: logged above, at most every 5 s (floods) */
            marie_info("%s: %s from %s: %s", c->name, marie_cmd_name(cmd.command), cmd.sender, rc == 0 ? "ok" : why);
        reply(c, cmd.request_id, cmd.command, rc == 0, rc == 0 ? "ok" : why);
    }
    marie_lifecycle_command_t_decode_cleanup(&cmd);
}

static void on_clock(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_component_t *c = user;
    marie_sim_clock_t clk;
    if (marie_decode_input(&marie_type_sim_clock_t, rbuf->data, rbuf->data_size, &clk, NULL) < 0) {
        marie_component_bad_input(c, "bad_clock", "malformed or non-finite clock message (%u bytes)", rbuf->data_size);
        return;
    }
    marie_loop_set_sim_time(c->loop, clk.utime);
    marie_sim_clock_t_decode_cleanup(&clk);
}

static void on_heartbeat_timer(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    marie_component_heartbeat(user);
}

static void on_signal(marie_loop_t *loop, int signo, void *user)
{
    marie_component_t *c = user;
    const char *why;
    marie_info("%s: signal %d: quit", c->name, signo);
    marie_component_command(c, MARIE_CMD_QUIT, &why);
}

/* ---- ports ---- */

/* Decodes a payload for port p; on success calls the handler. Returns 0 or -1 (counted). */
static int deliver(marie_port_t *p, const void *data, size_t len, int64_t recv_utime)
{
    marie_component_t *c = p->c;
    const marie_type_t *t = p->spec->type;
    marie_msg_info_t info = {p->channel, recv_utime, data, len};
    if (!t) {
        c->msgs_in++;
        p->cb(c, p, NULL, &info);
        return 0;
    }
    const char *why;
    if (marie_decode_input(t, data, len, p->scratch, &why) < 0) {
        marie_component_bad_input(c, why, "port %s: %zu bytes on %s: not a well-formed, finite %s", p->spec->name,
                                  len, p->channel, t->name);
        return -1;
    }
    c->msgs_in++;
    p->cb(c, p, p->scratch, &info);
    t->decode_cleanup(p->scratch);
    return 0;
}

static void flush_event_queues(marie_component_t *c)
{
    for (size_t i = 0; i < c->nports; i++) {
        marie_port_t *p = &c->ports[i];
        /* A handler may stop the component: keep the rest queued then. */
        size_t done = 0;
        for (; done < p->nqueue && c->state == MARIE_STATE_RUNNING; done++) {
            deliver(p, p->queue[done].data, p->queue[done].len, p->queue[done].recv_utime);
            free(p->queue[done].data);
        }
        if (done) {
            memmove(p->queue, p->queue + done, (p->nqueue - done) * sizeof *p->queue);
            p->nqueue -= done;
        }
    }
}

static void on_port_message(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_port_t *p = user;
    marie_component_t *c = p->c;
    if (!p->cb)
        return;
    if (c->state == MARIE_STATE_RUNNING) {
        deliver(p, rbuf->data, rbuf->data_size, rbuf->recv_utime);
        return;
    }
    if (p->spec->mech != MARIE_EVENT) {
        marie_component_count(c, "ignored_not_running", 1);
        return;
    }
    /* Events wait for the component to run again; an overflow is a counted loss. */
    if (p->nqueue == EVENT_QUEUE_MAX) {
        free(p->queue[0].data);
        memmove(p->queue, p->queue + 1, (p->nqueue - 1) * sizeof *p->queue);
        p->nqueue--;
        c->drops++;
        marie_component_count(c, "events_lost", 1);
    }
    void *copy = malloc(rbuf->data_size ? rbuf->data_size : 1);
    if (!copy) {
        c->drops++;
        marie_component_count(c, "events_lost", 1);
        return;
    }
    memcpy(copy, rbuf->data, rbuf->data_size);
    p->queue[p->nqueue++] = (queued_t){copy, rbuf->data_size, rbuf->recv_utime};
}

marie_port_t *marie_port(marie_component_t *c, const char *name)
{
    for (size_t i = 0; i < c->nports; i++)
        if (strcmp(c->ports[i].spec->name, name) == 0)
            return &c->ports[i];
    assert(!"marie_port: no such port declared");
    return NULL;
}

const char *marie_port_channel(const marie_port_t *p) { return p->channel; }
const char *marie_port_name(const marie_port_t *p) { return p->spec->name; }

int marie_port_publish_raw(marie_port_t *p, const void *data, size_t len)
{
    if (lcm_publish(p->lcm, p->channel, data, (unsigned int)len) != 0) {
        int err = errno ? errno : EIO;
        p->c->drops++;
        marie_component_count(p->c, "publish_failed", 1);
        marie_warn_ratelimited(5, "%s: publish on %s failed: %s", p->c->name, p->channel, strerror(err));
        return -err;
    }
    p->c->msgs_out++;
    return 0;
}

int marie_port_publish(marie_port_t *p, const void *msg)
{
    const marie_type_t *t = p->spec->type;
    assert(t && "marie_port_publish on a raw port");
    int size = t->encoded_size(msg);
    if (size < 0)
        return -EINVAL;
    if ((size_t)size > p->bufcap) {
        uint8_t *n = realloc(p->buf, (size_t)size);
        if (!n)
            return -ENOMEM;
        p->buf = n;
        p->bufcap = (size_t)size;
    }
    if (t->encode(p->buf, 0, size, msg) != size)
        return -EINVAL;
    return marie_port_publish_raw(p, p->buf, (size_t)size);
}

int marie_port_on_message(marie_port_t *p, marie_msg_cb_t cb)
{
    if (p->spec->dir != MARIE_IN || p->spec->mech == MARIE_PULL)
        return -EINVAL;
    p->cb = cb;
    if (!p->sub) {
        p->sub = lcm_subscribe(p->lcm, p->channel, on_port_message, p);
        if (!p->sub)
            return -EIO;
        /* LCM drops silently past a subscription's queue capacity (30 by default):
         * events must not be lost there, so give their ports room for bursts. */
        if (p->spec->mech == MARIE_EVENT)
            lcm_subscription_set_queue_capacity(p->sub, EVENT_QUEUE_MAX * 4);
    }
    return 0;
}

/* ---- pull ---- */

static void pull_finish(marie_component_t *c, pull_t *pl, int status, const void *msg, int64_t age)
{
    for (size_t i = 0; i < c->npulls; i++) {
        if (c->pulls[i] == pl) {
            c->pulls[i] = c->pulls[--c->npulls];
            break;
        }
    }
    if (pl->timeout)
        marie_loop_remove_timer(c->loop, pl->timeout);
    pl->timeout = NULL;
    if (pl->cb) {
        pl->cb(c, pl->port, status, msg, age, pl->user);
        free(pl);
    } else {
        pl->status = status;
        pl->age_us = age;
        pl->done = 1;
    }
}

static void on_pull_timeout(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    pull_t *pl = user;
    pl->timeout = NULL;  /* one-shot: already freed by the loop */
    marie_component_count(pl->port->c, "pull_timeouts", 1);
    pull_finish(pl->port->c, pl, -ETIMEDOUT, NULL, 0);
}

static void on_pull_reply(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_component_t *c = user;
    marie_pull_reply_t r;
    if (marie_decode_checked(&marie_type_pull_reply_t, rbuf->data, rbuf->data_size, &r) < 0) {
        marie_component_bad_input(c, "bad_pull_reply", "undecodable pull reply");
        return;
    }
    pull_t *pl = NULL;
    for (size_t i = 0; i < c->npulls && !pl; i++)
        if (c->pulls[i]->request_id == r.request_id)
            pl = c->pulls[i];
    if (!pl) {
        marie_component_count(c, "late_pull_replies", 1);
        marie_pull_reply_t_decode_cleanup(&r);
        return;
    }
    const marie_type_t *t = pl->port->spec->type;
    int status = 0;
    void *msg = NULL;
    if (r.status == MARIE_PULL_REPLY_T_STATUS_EMPTY || r.status == MARIE_PULL_REPLY_T_STATUS_TIMEOUT) {
        status = -ENODATA;
    } else if (r.status != MARIE_PULL_REPLY_T_STATUS_OK) {
        status = r.status == MARIE_PULL_REPLY_T_STATUS_UNKNOWN_CHANNEL ? -ENOENT : -EBADMSG;
    } else if (t) {
        const char *why;
        msg = pl->cb ? pl->port->scratch : pl->msg;
        if (marie_decode_input(t, r.data, (size_t)r.size, msg, &why) < 0) {
            marie_component_bad_input(c, why, "pull reply on %s: %d bytes: not a well-formed, finite %s", r.channel,
                                      r.size, t->name);
            status = -EBADMSG;
            msg = NULL;
        }
    }
    if (status == 0)
        c->msgs_in++;
    bool async = pl->cb != NULL;
    pull_finish(c, pl, status, msg, r.age_us);
    if (async && msg && t)
        t->decode_cleanup(msg);
    marie_pull_reply_t_decode_cleanup(&r);
}

static pull_t *pull_send(marie_port_t *p, int timeout_ms, marie_pull_cb_t cb, void *user, void *msg)
{
    marie_component_t *c = p->c;
    if (p->spec->mech != MARIE_PULL || timeout_ms < 0) {
        errno = EINVAL;
        return NULL;
    }
    if (!c->reply_subscribed) {
        if (!lcm_subscribe(p->lcm, c->reply_channel, on_pull_reply, c)) {
            errno = EIO;
            return NULL;
        }
        c->reply_subscribed = true;
    }
    pull_t **n = realloc(c->pulls, (c->npulls + 1) * sizeof *n);
    pull_t *pl = calloc(1, sizeof *pl);
    if (!n || !pl) {
        free(pl);
        if (n)
            c->pulls = n;
        errno = ENOMEM;
        return NULL;
    }
    c->pulls = n;
    *pl = (pull_t){.request_id = ++c->next_request_id, .port = p, .cb = cb, .user = user, .msg = msg};
    char req_channel[256];
    snprintf(req_channel, sizeof req_channel, "%s%s", p->channel, MARIE_PULL_SUFFIX);
    marie_pull_request_t req = {
        .utime = marie_wall_us(), .request_id = pl->request_id, .requester = c->name,
        .channel = p->channel, .reply_channel = c->reply_channel, .timeout_ms = timeout_ms,
    };
    if (marie_pull_request_t_publish(p->lcm, req_channel, &req) != 0) {
        c->drops++;
        free(pl);
        errno = EIO;
        return NULL;
    }
    c->msgs_out++;
    /* An asynchronous pull waits on the component's clock (simulated time under --clock sim,
     * where a paused or lockstepped simulator must not time it out); a blocking one on the
     * wall clock, so that it always returns. */
    pl->timeout = (cb ? marie_loop_add_oneshot : marie_loop_add_wall_oneshot)(c->loop, (int64_t)timeout_ms * 1000,
                                                                             on_pull_timeout, pl);
    c->pulls[c->npulls++] = pl;
    return pl;
}

int marie_port_pull_async(marie_port_t *p, int timeout_ms, marie_pull_cb_t cb, void *user)
{
    if (!cb)
        return -EINVAL;
    return pull_send(p, timeout_ms, cb, user, NULL) ? 0 : -errno;
}

int marie_port_pull(marie_port_t *p, void *msg, int timeout_ms, int64_t *age_us)
{
    pull_t *pl = pull_send(p, timeout_ms, NULL, NULL, msg);
    if (!pl)
        return -errno;
    /* Other messages keep being handled while we wait for this reply. */
    while (!pl->done && !marie_loop_quitting(p->c->loop)) {
        int rc = marie_loop_run_once(p->c->loop, 10);
        if (rc < 0) {
            pull_finish(p->c, pl, rc, NULL, 0);
            break;
        }
    }
    if (!pl->done)
        pull_finish(p->c, pl, -ECANCELED, NULL, 0);
    int status = pl->status;
    if (age_us)
        *age_us = pl->age_us;
    free(pl);
    return status;
}

/* ---- ticks ---- */

static void on_tick(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    tick_t *k = user;
    if (k->c->state != MARIE_STATE_RUNNING)
        return;
    k->c->overruns += overruns;
    k->cb(k->c, overruns);
}

marie_timer_t *marie_component_every(marie_component_t *c, double hz, marie_tick_cb_t cb)
{
    if (hz <= 0 || !cb) {
        errno = EINVAL;
        return NULL;
    }
    for (size_t i = 0; i < c->nticks; i++)
        if (c->ticks[i]->cb == cb) {
            marie_timer_set_period(c->ticks[i]->timer, (int64_t)(1e6 / hz + 0.5));
            return c->ticks[i]->timer;
        }
    tick_t **n = realloc(c->ticks, (c->nticks + 1) * sizeof *n);
    tick_t *k = calloc(1, sizeof *k);
    if (!n || !k) {
        free(k);
        if (n)
            c->ticks = n;
        errno = ENOMEM;
        return NULL;
    }
    c->ticks = n;
    *k = (tick_t){c, cb, NULL};
    k->timer = marie_loop_add_timer(c->loop, (int64_t)(1e6 / hz + 0.5), on_tick, k);
    if (!k->timer) {
        free(k);
        return NULL;
    }
    c->ticks[c->nticks++] = k;
    return k->timer;
}

/* ---- accessors ---- */

void *marie_component_user(const marie_component_t *c) { return c->user; }
void marie_component_set_user(marie_component_t *c, void *user) { c->user = user; }
const char *marie_component_name(const marie_component_t *c) { return c->name; }
marie_state_t marie_component_state(const marie_component_t *c) { return c->state; }
marie_loop_t *marie_component_loop(marie_component_t *c) { return c->loop; }
lcm_t *marie_component_lcm(marie_component_t *c) { return c->buses[0].lcm; }
int64_t marie_component_now(const marie_component_t *c) { return marie_loop_now(c->loop); }
const marie_component_cfg_t *marie_component_cfg(const marie_component_t *c) { return c->cfg; }

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

/* Copies every bound parameter's value into the component's params struct. */
static int fill_params_struct(marie_component_t *c)
{
    if (!c->def->params_size)
        return 0;
    c->params_struct = calloc(1, c->def->params_size);
    if (!c->params_struct)
        return -1;
    char *base = c->params_struct;
    for (size_t i = 0; i < c->nparams; i++) {
        const param_t *pa = &c->params[i];
        if (!pa->spec->bound)
            continue;
        assert(pa->spec->offset < c->def->params_size && "MARIE_PARAM_AT outside params_size");
        void *at = base + pa->spec->offset;
        switch (pa->spec->type) {
        case MARIE_PARAM_INT: memcpy(at, &pa->i, sizeof pa->i); break;
        case MARIE_PARAM_DOUBLE: memcpy(at, &pa->d, sizeof pa->d); break;
        case MARIE_PARAM_BOOL: memcpy(at, &pa->b, sizeof pa->b); break;
        case MARIE_PARAM_STRING: memcpy(at, &pa->s, sizeof pa->s); break;
        case MARIE_PARAM_NODE: memcpy(at, &pa->node, sizeof pa->node); break;
        }
    }
    return 0;
}

/* ---- creation ---- */

typedef struct {
    const char *system, *name, *profile, *url, *clock;
    char **params;   /* KEY=VALUE */
    size_t nparams;
    char **ports;    /* PORT=CHANNEL */
    size_t nports;
    bool hold;
} options_t;

static void usage(const marie_component_def_t *def, FILE *out)
{
    fprintf(out, "usage: %s [--system FILE] [--name NAME] [--profile P] [--url URL] [--clock wall|sim]\n"
                 "       [--param KEY=VALUE]... [--port PORT=CHANNEL]... [--hold] [--describe]\n", def->kind);
    fprintf(out, "ports:\n");
    for (const marie_port_spec_t *p = def->ports; p && p->name; p++)
        fprintf(out, "  %-16s %-4s %-6s %-28s default channel %s\n", p->name, p->dir == MARIE_IN ? "in" : "out",
                p->mech == MARIE_PUSH ? "push" : p->mech == MARIE_PULL ? "pull" : "event",
                p->type ? p->type->name : "raw", p->channel ? p->channel : "(must be bound)");
    fprintf(out, "params:\n");
    for (const marie_param_spec_t *p = def->params; p && p->name; p++)
        fprintf(out, "  %-20s default %-12s %s\n", p->name, p->def ? p->def : "(required)", p->help ? p->help : "");
}

static int parse_options(const marie_component_def_t *def, int argc, char **argv, options_t *o, marie_errors_t *errs)
{
    static const struct option longopts[] = {
        {"system", required_argument, 0, 's'}, {"name", required_argument, 0, 'n'},
        {"profile", required_argument, 0, 'p'}, {"url", required_argument, 0, 'u'},
        {"clock", required_argument, 0, 'c'}, {"param", required_argument, 0, 'P'},
        {"port", required_argument, 0, 'o'}, {"hold", no_argument, 0, 'H'},
        {"help", no_argument, 0, 'h'}, {"describe", no_argument, 0, 'D'}, {0, 0, 0, 0},
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
        case 'h': usage(def, stdout); exit(0);
        case 'D': marie_spec_describe(def, stdout); exit(0);   /* for the managers' checks */
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

static int bind_params(marie_component_t *c, const options_t *o, marie_errors_t *errs)
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

static lcm_t *bus_for(marie_component_t *c, const char *url)
{
    for (size_t i = 0; i < c->nbuses; i++)
        if (strcmp(c->buses[i].url, url) == 0)
            return c->buses[i].lcm;
    bus_t *n = realloc(c->buses, (c->nbuses + 1) * sizeof *n);
    if (!n)
        return NULL;
    c->buses = n;
    lcm_t *lcm = lcm_create(url);
    if (!lcm) {
        marie_error("%s: cannot open the LCM bus '%s'", c->name, url);
        return NULL;
    }
    c->buses[c->nbuses++] = (bus_t){strdup(url), lcm};
    return lcm;
}

static int bind_ports(marie_component_t *c, const options_t *o, marie_errors_t *errs)
{
    size_t n = 0;
    for (const marie_port_spec_t *p = c->def->ports; p && p->name; p++)
        n++;
    c->ports = calloc(n ? n : 1, sizeof *c->ports);
    if (!c->ports)
        return -1;
    c->nports = n;
    int rc = 0;
    const marie_component_cfg_t *cfg = c->cfg;
    for (size_t i = 0; cfg && i < cfg->nports; i++) {
        bool known = false;
        for (size_t k = 0; k < n && !known; k++)
            known = strcmp(c->def->ports[k].name, cfg->ports[i].name) == 0;
        if (!known) {
            marie_errors_add(errs, cfg->file, cfg->ports[i].line, cfg->ports[i].col, "%s '%s' has no port '%s'",
                             c->def->kind, c->name, cfg->ports[i].name);
            rc = -1;
        }
    }
    for (size_t k = 0; k < n; k++) {
        marie_port_t *p = &c->ports[k];
        p->c = c;
        p->spec = &c->def->ports[k];
        const char *channel = p->spec->channel, *url = c->buses[0].url;
        for (size_t i = 0; cfg && i < cfg->nports; i++) {
            if (strcmp(cfg->ports[i].name, p->spec->name) == 0) {
                channel = cfg->ports[i].channel;
                if (cfg->ports[i].url)
                    url = cfg->ports[i].url;
            }
        }
        size_t nlen = strlen(p->spec->name);
        for (size_t i = 0; i < o->nports; i++)
            if (strncmp(o->ports[i], p->spec->name, nlen) == 0 && o->ports[i][nlen] == '=')
                channel = o->ports[i] + nlen + 1;
        if (!channel || !*channel) {
            marie_errors_add(errs, cfg ? cfg->file : "command line", cfg ? cfg->line : 0, cfg ? cfg->col : 0,
                             "%s '%s': port '%s' is not bound to a channel", c->def->kind, c->name, p->spec->name);
            rc = -1;
            continue;
        }
        p->channel = strdup(channel);
        p->lcm = bus_for(c, url);
        if (!p->lcm || !p->channel)
            return -1;
        if (p->spec->type && !(p->scratch = calloc(1, p->spec->type->size)))
            return -1;
        if (p->spec->mech == MARIE_EVENT && p->spec->dir == MARIE_IN &&
            !(p->queue = calloc(EVENT_QUEUE_MAX, sizeof *p->queue)))
            return -1;
    }
    for (size_t i = 0; i < o->nports; i++) {
        const char *eq = strchr(o->ports[i], '=');
        bool known = false;
        for (size_t k = 0; eq && k < n && !known; k++)
            known = strlen(c->def->ports[k].name) == (size_t)(eq - o->ports[i]) &&
                    strncmp(c->def->ports[k].name, o->ports[i], (size_t)(eq - o->ports[i])) == 0;
        if (!known) {
            marie_errors_add(errs, "command line", 0, 0, "--port %s: %s", o->ports[i],
                             eq ? "no such port" : "expected PORT=CHANNEL");
            rc = -1;
        }
    }
    return rc;
}

static void on_lcm_readable(marie_loop_t *loop, int fd, short revents, void *user)
{
    /* The fd is readable, so this does not block; one message per poll round keeps
     * timers and other fds served between messages. */
    lcm_handle(user);
}

marie_component_t *marie_component_create(const marie_component_def_t *def, int argc, char **argv, void *user,
                                          marie_errors_t *errs)
{
    options_t o;
    marie_component_t *c = calloc(1, sizeof *c);
    if (!c)
        return NULL;
    c->def = def;
    c->user = user;
    c->start_mono = marie_mono_us();
    if (parse_options(def, argc, argv, &o, errs) < 0)
        goto err;
    c->hold = o.hold;
    if (o.system) {
        c->sys = marie_system_load(o.system, o.profile, errs);
        if (!c->sys)
            goto err;
        if (!o.name) {
            marie_errors_add(errs, o.system, 0, 0, "a component started with a system file needs --name");
            goto err;
        }
        c->cfg = marie_system_component(c->sys, o.name);
        if (!c->cfg) {
            marie_errors_add(errs, o.system, 0, 0, "no component named '%s'%s%s", o.name,
                             o.profile ? " in profile " : "", o.profile ? o.profile : "");
            goto err;
        }
    }
    c->name = strdup(o.name ? o.name : def->kind);
    marie_log_set_name(c->name);
    const char *key = getenv("MARIE_KEY") && *getenv("MARIE_KEY") ? getenv("MARIE_KEY") : c->sys ? c->sys->key_file : NULL;
    if (key) {
        /* The replay table may live in memory: its epoch (this start) refuses every order
         * signed before, and the local manager that signs lifecycle orders shares our clock. */
        char why[512] = "cannot keep a replay table";
        if (!(c->auth = marie_auth_load(key, why, sizeof why)) || !(c->replay = marie_replay_create(NULL))) {
            marie_errors_add(errs, key, 0, 0, "order key: %s", why);
            goto err;
        }
    }
    const char *host = getenv("MARIE_HOST");
    if (host)
        snprintf(c->host, sizeof c->host, "%s", host);
    else if (c->cfg && c->cfg->host)
        snprintf(c->host, sizeof c->host, "%s", c->cfg->host);
    else
        gethostname(c->host, sizeof c->host - 1);
    const char *url = o.url ? o.url : c->sys ? c->sys->lcm_url : marie_default_url();
    if (!(c->loop = marie_loop_create()) || !bus_for(c, url)) {
        marie_errors_add(errs, "bus", 0, 0, "cannot open the LCM bus '%s'", url);
        goto err_runtime;
    }
    if (o.clock ? strcmp(o.clock, "sim") == 0 : (c->sys && c->sys->clock == MARIE_CLOCK_SIM))
        marie_loop_set_clock(c->loop, MARIE_CLOCK_SIM);
    int rc = bind_params(c, &o, errs);
    if (rc == 0 && fill_params_struct(c) < 0)
        rc = -1;
    rc |= bind_ports(c, &o, errs);
    if (rc)
        goto err;
    snprintf(c->reply_channel, sizeof c->reply_channel, "MARIE_REPLY.%s.%d", c->name, (int)getpid());
    for (size_t i = 0; i < c->nbuses; i++)
        if (marie_loop_add_fd(c->loop, lcm_get_fileno(c->buses[i].lcm), POLLIN, on_lcm_readable, c->buses[i].lcm) < 0)
            goto err_runtime;
    if (!lcm_subscribe(c->buses[0].lcm, MARIE_CH_LIFECYCLE, on_lifecycle, c) ||
        !marie_loop_add_wall_timer(c->loop, 1000000, on_heartbeat_timer, c))
        goto err_runtime;
    if (marie_loop_clock(c->loop) == MARIE_CLOCK_SIM) {
        /* A fast simulator sends clock bursts; LCM's default queue (30) would drop ticks. */
        lcm_subscription_t *clk = lcm_subscribe(c->buses[0].lcm, MARIE_CH_CLOCK, on_clock, c);
        if (!clk)
            goto err_runtime;
        lcm_subscription_set_queue_capacity(clk, 1000);
    }
    free(o.params);
    free(o.ports);
    return c;
err_runtime:
    marie_errors_add(errs, "runtime", 0, 0, "cannot set up the component: %s", strerror(errno ? errno : EIO));
err:
    free(o.params);
    free(o.ports);
    marie_component_destroy(c);
    return NULL;
}

int marie_component_run(marie_component_t *c)
{
    marie_loop_catch_signals(c->loop, on_signal, c);
    marie_component_heartbeat(c);
    if (!c->hold) {
        const char *why;
        if (marie_component_command(c, MARIE_CMD_INIT, &why) < 0 ||
            marie_component_command(c, MARIE_CMD_START, &why) < 0) {
            marie_error("%s: %s", c->name, why);
            marie_component_event(c, MARIE_EVENT_T_SEV_ERROR, "start_failed", "%s", why);
            /* Stay up as failed so the manager sees why; it decides about restarts. */
            if (c->state != MARIE_STATE_FAILED)
                set_state(c, MARIE_STATE_FAILED, why);
        }
    }
    int rc = marie_loop_run(c->loop);
    marie_loop_catch_signals(c->loop, NULL, NULL);
    return rc;
}

void marie_component_destroy(marie_component_t *c)
{
    if (!c)
        return;
    if (c->initialised && c->state != MARIE_STATE_EXITED)
        quit_hook(c);
    for (size_t i = 0; i < c->npulls; i++)
        free(c->pulls[i]);
    free(c->pulls);
    for (size_t i = 0; i < c->nticks; i++)
        free(c->ticks[i]);
    free(c->ticks);
    for (size_t i = 0; i < c->nports; i++) {
        marie_port_t *p = &c->ports[i];
        for (size_t k = 0; k < p->nqueue; k++)
            free(p->queue[k].data);
        free(p->queue);
        free(p->channel);
        free(p->scratch);
        free(p->buf);
    }
    free(c->ports);
    for (size_t i = 0; i < c->nbuses; i++) {
        lcm_destroy(c->buses[i].lcm);
        free(c->buses[i].url);
    }
    free(c->buses);
    marie_loop_destroy(c->loop);
    for (size_t i = 0; i < c->ncounters; i++)
        free(c->counters[i].name);
    free(c->counters);
    for (size_t i = 0; i < c->ndocs; i++)
        marie_doc_destroy(c->docs[i]);
    free(c->docs);
    for (size_t i = 0; c->params && i < c->nparams; i++)
        free(c->params[i].expanded);
    free(c->params);
    free(c->params_struct);
    marie_system_destroy(c->sys);
    marie_auth_destroy(c->auth);
    marie_replay_destroy(c->replay);
    free(c->name);
    free(c);
}

int marie_main(const marie_component_def_t *def, int argc, char **argv, void *user)
{
    marie_errors_t errs = {0};
    marie_component_t *c = marie_component_create(def, argc, argv, user, &errs);
    if (!c) {
        marie_errors_print(&errs, stderr);
        marie_errors_clear(&errs);
        return 2;
    }
    int rc = marie_component_run(c);
    marie_component_destroy(c);
    return rc < 0 ? 1 : 0;
}
