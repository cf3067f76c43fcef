/* component: the lifecycle state machine, lifecycle orders, heartbeat, events and counters,
 * and creating, running and destroying a component. */
#include "core/component.h"

#include <assert.h>
#include <errno.h>
#include <signal.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/auth.h"
#include "core/bus/bus.h"
#include "core/err.h"
#include "core/file.h"
#include "core/log.h"
#include "core/typeinfo.h"
#include "core/spec.h"
#include "lcmtypes/marie_types.h"
#include "core/component_priv.h"

/* ---- names ---- */

static const char *const state_names[] = {"created", "ready", "running", "paused", "failed", "exited", "degraded"};
static const char *const cmd_names[] = {"?", "init", "start", "stop", "pause", "resume", "restart", "abort", "quit"};

const char *marie_state_name(marie_state_t s)
{
    return (unsigned)s < sizeof state_names / sizeof *state_names ? state_names[s] : "unknown";
}

static const char *marie_cmd_name(marie_cmd_t c)
{
    return c >= MARIE_CMD_INIT && c <= MARIE_CMD_QUIT ? cmd_names[c] : "unknown";
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
    MARIE_VFORMAT(msg, fmt);
    c->bad_input++;
    if (counter)
        marie_component_count(c, counter, 1);
    marie_warn_ratelimited(5, "%s: bad input (%s, %lld so far): %s", c->name, counter ? counter : "bad_input",
                           (long long)c->bad_input, msg);
}

void marie_component_drop(marie_component_t *c, int64_t n) { c->drops += n; }

/* ---- heartbeat and events ---- */

void marie_component_heartbeat(marie_component_t *c)
{
    marie_heartbeat_t hb;
    memset(&hb, 0, sizeof hb);
    marie_counter_t counters[64];
    marie_port_status_t ports[64];
    marie_comp_count_shm_losses(c);
    marie_comp_count_bus_losses(c);
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
    hb.nports = (int32_t)(c->nports < 64 ? c->nports : 64);
    for (int i = 0; i < hb.nports; i++) {
        const marie_port_t *p = &c->ports[i];
        ports[i] = (marie_port_status_t){(char *)p->spec->name, p->channel ? p->channel : "",
                                         (char *)(p->spec->type ? p->spec->type->name : ""),
                                         p->spec->dir == MARIE_OUT ? MARIE_PORT_STATUS_T_OUT : MARIE_PORT_STATUS_T_IN,
                                         p->msgs};
    }
    hb.ports = ports;
    marie_bus_publish_msg(c->buses[0].lcm, MARIE_CH_HEARTBEAT, &marie_type_heartbeat_t, &hb);
}

void marie_component_event(marie_component_t *c, int severity, const char *kind, const char *fmt, ...)
{
    char text[1024];
    MARIE_VFORMAT(text, fmt);
    marie_event_t ev = {
        .utime = marie_wall_us(), .source = c->name, .seq = ++c->event_seq,
        .severity = (int8_t)severity, .kind = (char *)kind, .text = text,
    };
    if (marie_bus_publish_msg(c->buses[0].lcm, MARIE_CH_EVENT, &marie_type_event_t, &ev) != 0)
        c->drops++;
    marie_log_level_t lvl = severity >= MARIE_EVENT_T_SEV_ERROR  ? MARIE_LOG_ERROR
                            : severity >= MARIE_EVENT_T_SEV_WARN ? MARIE_LOG_WARN
                                                                 : MARIE_LOG_INFO;
    MARIE_LOG_AT(lvl, "event %s: %s", kind, text);
}

void marie_component_set_degraded(marie_component_t *c, bool degraded, const char *fmt, ...)
{
    MARIE_VFORMAT(c->degraded_reason, fmt);
    if (degraded == c->degraded)
        return;
    c->degraded = degraded;
    MARIE_LOG_AT(degraded ? MARIE_LOG_WARN : MARIE_LOG_INFO, "%s: %s (%s)", c->name,
                 degraded ? "degraded" : "no longer degraded", c->degraded_reason);
    marie_component_heartbeat(c);
}

/* ---- lifecycle ---- */


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
    MARIE_VFORMAT(c->fail_reason, fmt);
}

/* Runs a hook; on refusal leaves the reason in c->reason and fails with ECANCELED. */
static int hook(marie_component_t *c, int (*fn)(marie_component_t *), const char *what)
{
    if (!fn)
        return 0;
    c->fail_reason[0] = 0;
    if (fn(c) == 0)
        return 0;
    snprintf(c->reason, sizeof c->reason, "%s failed: %s", what, c->fail_reason[0] ? c->fail_reason : "refused");
    return marie_fail(ECANCELED);
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
    *reason = c->reason;
    if (s == MARIE_STATE_EXITED) {
        snprintf(c->reason, sizeof c->reason, "%s refused: the component has exited", marie_cmd_name(cmd));
        return marie_fail(EINVAL);
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
        marie_comp_flush_events(c);
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
        marie_comp_flush_events(c);
        return 0;
    case MARIE_CMD_RESTART:
        if (s == MARIE_STATE_CREATED)
            break;
        if ((s == MARIE_STATE_RUNNING || s == MARIE_STATE_PAUSED) && hook(c, d->on_stop, "stop") < 0)
            return -1;
        if (s == MARIE_STATE_FAILED) {
            quit_hook(c);
            if (hook(c, d->on_init, "init") < 0) {
                MARIE_KEEP_ERRNO(set_state(c, MARIE_STATE_FAILED, c->reason));
                return -1;
            }
            c->initialised = true;
        }
        if (hook(c, d->on_start, "start") < 0) {
            MARIE_KEEP_ERRNO(set_state(c, MARIE_STATE_READY, c->reason));
            return -1;
        }
        set_state(c, MARIE_STATE_RUNNING, "restart");
        marie_comp_flush_events(c);
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
        return marie_fail(EINVAL);
    }
    snprintf(c->reason, sizeof c->reason, "%s refused in state %s", marie_cmd_name(cmd), marie_state_name(s));
    return marie_fail(EINVAL);
}

static void reply(marie_component_t *c, int64_t request_id, int cmd, bool ok, const char *why)
{
    marie_lifecycle_reply_t r = {
        .utime = marie_wall_us(), .request_id = request_id, .component = c->name,
        .command = (int8_t)cmd, .ok = ok, .state = (int8_t)c->state, .reason = (char *)why,
    };
    marie_bus_publish_msg(c->buses[0].lcm, MARIE_CH_LIFECYCLE_REPLY, &marie_type_lifecycle_reply_t, &r);
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
            marie_yaml_unload();    /* an init may have read YAML (a map's description) */
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

/* ---- accessors ---- */

void *marie_component_user(const marie_component_t *c) { return c->user; }
void marie_component_set_user(marie_component_t *c, void *user) { c->user = user; }
const char *marie_component_name(const marie_component_t *c) { return c->name; }
marie_state_t marie_component_state(const marie_component_t *c) { return c->state; }
marie_loop_t *marie_component_loop(marie_component_t *c) { return c->loop; }
lcm_t *marie_component_lcm(marie_component_t *c) { return c->buses[0].lcm; }

size_t marie_component_shm_max(const marie_component_t *c, const char *channel)
{
    const marie_transport_cfg_t *tr = marie_system_transport(c->sys, channel);
    return tr && tr->shm ? tr->max_size : 0;
}
int64_t marie_component_now(const marie_component_t *c) { return marie_loop_now(c->loop); }
const marie_component_cfg_t *marie_component_cfg(const marie_component_t *c) { return c->cfg; }
const marie_system_t *marie_component_system(const marie_component_t *c) { return c->sys; }

/* 1 Hz, or four beats within the manager's heartbeat_timeout when that is shorter than 4 s, so
 * a quick detection (down to a few hundred ms) never sees a silence that is only the period. */
static int64_t heartbeat_period_us(const marie_component_t *c)
{
    double t = c->cfg ? c->cfg->heartbeat_timeout_s : 0;
    int64_t p = t > 0 && t < 4 ? (int64_t)(t / 4 * 1e6) : 1000000;
    return p < 20000 ? 20000 : p;
}

/* The system file. A manager that runs its own copy of the user's file (filled in with launch
 * arguments, or sent to a host that cannot read it) names the original in MARIE_SYSTEM_ORIGIN:
 * the copy is read under that name, so its relative paths (types:) start from the user's folder
 * and its messages name the user's file. A component the manager started reads its own entry
 * alone (MARIE_SYSTEM_ENTRY, core/config_entry.c) unless that fails. */
static marie_system_t *load_system(const options_t *o, marie_errors_t *errs)
{
    const char *origin = getenv("MARIE_SYSTEM_ORIGIN"), *given = getenv("MARIE_SYSTEM");
    bool managers = given && strcmp(given, o->system) == 0;
    /* its own entry alone, where the manager says which lines it is (else the whole file) */
    marie_system_t *sys = managers ? marie_system_load_entry(o->system, origin && *origin ? origin : NULL, o->profile,
                                                             o->name, getenv("MARIE_SYSTEM_ENTRY")) : NULL;
    if (sys)
        return sys;
    if (!origin || !*origin || !managers)
        return marie_system_load(o->system, o->profile, errs);
    size_t len;
    char *text = marie_file_read(o->system, 16 << 20, &len);
    if (!text) {
        marie_errors_add(errs, o->system, 0, 0, "%s", strerror(errno));
        return NULL;
    }
    sys = marie_system_load_text(origin, text, len, o->profile, errs);
    free(text);
    return sys;
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
    if (marie_comp_parse_options(def, argc, argv, &o, errs) < 0)
        goto err;
    c->hold = o.hold;
    if (o.system) {
        c->sys = load_system(&o, errs);
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
    /* Users' types (marie-types-gen) before anything decodes: ports, the XML bridge, the CAs. */
    if (marie_system_load_types(c->sys, errs) < 0)
        goto err;
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
    if (!(c->loop = marie_loop_create()) || !marie_comp_bus_for(c, url)) {
        marie_errors_add(errs, "bus", 0, 0, "cannot open the LCM bus '%s'", url);
        goto err_runtime;
    }
    if (o.clock ? strcmp(o.clock, "sim") == 0 : (c->sys && c->sys->clock == MARIE_CLOCK_SIM))
        marie_loop_set_clock(c->loop, MARIE_CLOCK_SIM);
    if (c->cfg)
        marie_loop_set_spin(c->loop, c->cfg->sched.spin_us);
    int rc = marie_comp_bind_params(c, &o, errs);
    if (rc == 0 && marie_comp_fill_params(c) < 0)
        rc = -1;
    rc |= marie_comp_bind_ports(c, &o, errs);
    if (rc)
        goto err;
    snprintf(c->reply_channel, sizeof c->reply_channel, "MARIE_REPLY.%s.%d", c->name, (int)getpid());
    for (size_t i = 0; i < c->nbuses; i++)
        if (marie_loop_add_bus(c->loop, c->buses[i].lcm, 1) < 0)
            goto err_runtime;
    if (!marie_bus_subscribe(c->buses[0].lcm, MARIE_CH_LIFECYCLE, on_lifecycle, c) ||
        !marie_bus_subscribe(c->buses[0].lcm, MARIE_CH_PARAM, marie_comp_on_param_request, c) ||
        !marie_loop_add_wall_timer(c->loop, heartbeat_period_us(c), on_heartbeat_timer, c))
        goto err_runtime;
    if (marie_loop_clock(c->loop) == MARIE_CLOCK_SIM) {
        /* A fast simulator sends clock bursts; LCM's default queue (30) would drop ticks. */
        if (!marie_bus_subscribe(c->buses[0].lcm, MARIE_CH_CLOCK, on_clock, c))
            goto err_runtime;
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
    /* Parameters, the system file and what init read are in memory now. */
    marie_yaml_unload();
    int rc = marie_loop_run(c->loop);
    MARIE_KEEP_ERRNO(marie_loop_catch_signals(c->loop, NULL, NULL));
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
        marie_comp_port_close(p);
        free(p->channel);
        free(p->scratch);
        free(p->buf);
    }
    free(c->ports);
    for (size_t i = 0; i < c->nbuses; i++) {
        marie_bus_destroy(c->buses[i].lcm);
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

