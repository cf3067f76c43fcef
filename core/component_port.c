/* component ports: publish and subscribe over LCM (or same-host shared memory where the system
 * file says so), event queues, pull requests and ticks. */
#include "core/component.h"

#include <assert.h>
#include <errno.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/err.h"
#include "core/bus/bus.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_types.h"
#include "core/component_priv.h"

/* ---- ports ---- */

static void bad_payload(marie_port_t *p, const char *why, size_t len)
{
    marie_component_bad_input(p->c, why, "port %s: %zu bytes on %s: not a well-formed, finite %s", p->spec->name, len,
                              p->channel, p->spec->type->name);
}

/* Hands the message decoded in p->scratch to the handler, then frees what decoding made
 * (viewed: marie_decode_view() said its tail points into the bytes). */
static void hand_over(marie_port_t *p, const marie_msg_info_t *info, int viewed)
{
    marie_component_t *c = p->c;
    c->msgs_in++;
    p->msgs++;
    p->cb(c, p, p->scratch, info);
    marie_decode_cleanup_view(p->spec->type, p->scratch, viewed);
}

/* Decodes a payload for port p; on success calls the handler. Returns 0 or -1 (counted). */
static int deliver(marie_port_t *p, const void *data, size_t len, int64_t recv_utime)
{
    marie_component_t *c = p->c;
    const marie_type_t *t = p->spec->type;
    marie_msg_info_t info = {p->channel, recv_utime, data, len};
    if (!t) {
        c->msgs_in++;
        p->msgs++;
        p->cb(c, p, NULL, &info);
        return 0;
    }
    const char *why;
    if (marie_decode_input(t, data, len, p->scratch, &why) < 0) {
        bad_payload(p, why, len);
        return -1;
    }
    hand_over(p, &info, 0);
    return 0;
}

void marie_comp_flush_events(marie_component_t *c)
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

/* A message for port p from its transport: delivered now, held (an event port not running) or
 * counted as ignored. Returns true when it was held (a copy at the end of the queue). */
static bool port_receive(marie_port_t *p, const void *data, size_t len, int64_t recv_utime)
{
    marie_component_t *c = p->c;
    if (!p->cb)
        return false;
    if (c->state == MARIE_STATE_RUNNING) {
        deliver(p, data, len, recv_utime);
        return false;
    }
    if (p->spec->mech != MARIE_EVENT) {
        marie_component_count(c, "ignored_not_running", 1);
        return false;
    }
    /* Events wait for the component to run again; an overflow is a counted loss. */
    if (p->nqueue == EVENT_QUEUE_MAX) {
        free(p->queue[0].data);
        memmove(p->queue, p->queue + 1, (p->nqueue - 1) * sizeof *p->queue);
        p->nqueue--;
        c->drops++;
        marie_component_count(c, "events_lost", 1);
    }
    void *copy = malloc(len ? len : 1);
    if (!copy) {
        c->drops++;
        marie_component_count(c, "events_lost", 1);
        return false;
    }
    memcpy(copy, data, len);
    p->queue[p->nqueue++] = (queued_t){copy, len, recv_utime};
    return true;
}

static void on_port_message(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    port_receive(user, rbuf->data, rbuf->data_size, rbuf->recv_utime);
}

/* Typed ports read shared memory in place: the message is decoded where the writer put it, and
 * handed over only once the ring says the bytes stayed intact throughout (else it is a counted
 * loss, never a torn message). A port not running keeps a copy, taken back the same way. */
static void on_shm_in_place(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_port_t *p = user;
    p->peek.len = rbuf->data_size;
    p->peek.at = rbuf->recv_utime;
    p->peek.decoded = p->peek.queued = false;
    p->peek.viewed = 0;
    p->peek.data = NULL;
    if (p->c->state != MARIE_STATE_RUNNING || !p->cb)
        p->peek.queued = port_receive(p, rbuf->data, rbuf->data_size, rbuf->recv_utime);
    else
        p->peek.decoded = marie_decode_input(p->spec->type, rbuf->data, rbuf->data_size, p->scratch, &p->peek.why) == 0;
}

/* The same, the slot held by the ring until the verdict returns: the message's tail (an image's
 * pixels) is not copied but points into the slot while the handler runs, and its bytes are
 * the handler's raw ones. A port not running keeps a copy, as above. */
static void on_shm_held(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    marie_port_t *p = user;
    if (p->c->state != MARIE_STATE_RUNNING || !p->cb) {
        on_shm_in_place(rbuf, channel, user);
        return;
    }
    p->peek.len = rbuf->data_size;
    p->peek.at = rbuf->recv_utime;
    p->peek.queued = false;
    p->peek.data = rbuf->data;
    p->peek.viewed = marie_decode_view(p->spec->type, rbuf->data, rbuf->data_size, p->scratch, &p->peek.why);
    p->peek.decoded = p->peek.viewed >= 0;
}

static void on_shm_verdict(bool intact, void *user)
{
    marie_port_t *p = user;
    if (!intact) {
        if (p->peek.decoded)
            marie_decode_cleanup_view(p->spec->type, p->scratch, p->peek.viewed);
        else if (p->peek.queued)
            free(p->queue[--p->nqueue].data);
        return;
    }
    if (p->peek.queued || p->c->state != MARIE_STATE_RUNNING || !p->cb) {
        if (p->peek.decoded)        /* stopped by another subscription's handler meanwhile */
            marie_decode_cleanup_view(p->spec->type, p->scratch, p->peek.viewed);
        return;
    }
    if (!p->peek.decoded) {
        bad_payload(p, p->peek.why, p->peek.len);
        return;
    }
    /* raw stays NULL unless the slot is held: else the bytes are the writer's again by now. */
    marie_msg_info_t info = {p->channel, p->peek.at, p->peek.data, p->peek.data ? p->peek.len : 0};
    hand_over(p, &info, p->peek.viewed);
}

void marie_comp_count_shm_losses(marie_component_t *c)
{
    for (size_t i = 0; i < c->nports; i++) {
        marie_port_t *p = &c->ports[i];
        if (!p->shm || !p->sub)
            continue;
        marie_bus_sub_stats_t st = marie_bus_sub_stats(p->lcm, p->sub);
        if (st.lost > p->counted.lost) {
            c->drops += st.lost - p->counted.lost;
            marie_component_count(c, "shm_overwritten", st.lost - p->counted.lost);
        }
        if (st.bad > p->counted.bad)
            marie_component_bad_input(c, "bad_shm_notice", "port %s: %lld malformed or mismatched notices on %s.SHM",
                                      p->spec->name, (long long)(st.bad - p->counted.bad), p->channel);
        p->counted = st;
    }
}

/* What the buses' receivers saw since the last heartbeat: datagrams that are not LCM's are bad
 * input, messages lost in the kernel or given up with fragments missing are drops. */
void marie_comp_count_bus_losses(marie_component_t *c)
{
    for (size_t i = 0; i < c->nbuses; i++) {
        bus_t *b = &c->buses[i];
        marie_bus_stats_t st;
        marie_bus_stats(b->lcm, &st);
        int64_t bad = st.malformed - b->counted.malformed, lost = st.dropped - b->counted.dropped,
                gaps = st.incomplete - b->counted.incomplete;
        if (bad > 0) {
            c->bad_input += bad;
            marie_component_count(c, "bus_malformed", bad);
            marie_warn_ratelimited(5, "%s: %lld datagrams on %s that are not LCM messages", c->name, (long long)bad, b->url);
        }
        if (lost > 0)
            marie_component_count(c, "bus_dropped", lost);
        if (gaps > 0)
            marie_component_count(c, "bus_incomplete", gaps);
        if (lost + gaps > 0)
            c->drops += lost + gaps;
        b->counted = st;
    }
}

void marie_comp_port_close(marie_port_t *p)
{
    marie_bus_unsubscribe(p->lcm, p->sub);
    p->sub = NULL;
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

static bool grow_buf(marie_port_t *p, size_t size)
{
    uint8_t *n = realloc(p->buf, size);
    if (!n)
        return false;
    p->buf = n;
    p->bufcap = size;
    return true;
}

/* Counts a publication on p: done, or failed with errno err (a drop). 0 or -err. */
static int published(marie_port_t *p, int err, size_t len)
{
    p->loan = NULL;             /* taken up by this publish, whatever it was */
    if (err) {
        p->c->drops++;
        marie_component_count(p->c, err == EMSGSIZE ? "publish_too_big" : "publish_failed", 1);
        if (err == EMSGSIZE)
            marie_warn_ratelimited(5, "%s: %zu bytes on %s: larger than its transport's max_size (%zu)", p->c->name,
                                   len, p->channel, p->shm->max_size);
        else
            marie_warn_ratelimited(5, "%s: publish on %s failed: %s", p->c->name, p->channel, strerror(err));
        return marie_fail(err);
    }
    p->c->msgs_out++;
    p->msgs++;
    return 0;
}

void *marie_port_loan(marie_port_t *p, size_t n)
{
    if (!p->loanable)
        return marie_fail_null(ENOTSUP);
    if (n > INT32_MAX || p->tail.wire_off + n > p->shm->max_size)
        return marie_fail_null(EMSGSIZE);
    uint8_t *slot = marie_bus_loan(p->lcm, p->channel);
    if (!slot)
        return NULL;
    p->loan = slot + p->tail.wire_off;
    p->loan_cap = n;
    return p->loan;
}

/* msg's array is the loan, its bytes already in the ring: only the fields before them are
 * encoded, in front of them (a copy of msg with an empty array, then its length patched in). */
static int publish_loaned(marie_port_t *p, const void *msg)
{
    const marie_type_t *t = p->spec->type;
    const marie_tail_t *tl = &p->tail;
    int32_t n;
    memcpy(&n, (const uint8_t *)msg + tl->len_off, sizeof n);
    if (n < 0 || (size_t)n > p->loan_cap || (t->size > p->bufcap && !grow_buf(p, t->size)))
        return published(p, EINVAL, 0);
    memcpy(p->buf, msg, t->size);
    memset(p->buf + tl->len_off, 0, sizeof n);
    memset(p->buf + tl->ptr_off, 0, sizeof(void *));
    uint8_t *head = p->loan - tl->wire_off;
    if (t->encode(head, 0, (int)tl->wire_off, p->buf) != (int)tl->wire_off)
        return published(p, EINVAL, 0);
    for (int i = 0; i < 4; i++)     /* big-endian, as LCM writes it */
        head[tl->len_wire_off + (size_t)i] = (uint8_t)((uint32_t)n >> (24 - 8 * i));
    size_t len = tl->wire_off + (size_t)n;
    return published(p, marie_bus_commit(p->lcm, p->channel, len) ? errno : 0, len);
}

int marie_port_publish_raw(marie_port_t *p, const void *data, size_t len)
{
    return published(p, marie_bus_publish(p->lcm, p->channel, data, len) ? errno : 0, len);
}

typedef struct {
    const marie_type_t *t;
    const void *msg;
} encoding_t;

static int encode_into(void *dst, size_t len, void *user)
{
    const encoding_t *e = user;
    return e->t->encode(dst, 0, (int)len, e->msg) == (int)len ? 0 : -1;
}

int marie_port_publish(marie_port_t *p, const void *msg)
{
    const marie_type_t *t = p->spec->type;
    assert(t && "marie_port_publish on a raw port");
    if (p->loan && *(uint8_t *const *)((const uint8_t *)msg + p->tail.ptr_off) == p->loan)
        return publish_loaned(p, msg);
    int size = t->encoded_size(msg);
    if (size < 0)
        return marie_fail(EINVAL);
    if (p->shm)         /* encoded straight into the ring */
        return published(p, marie_bus_publish_with(p->lcm, p->channel, (size_t)size, encode_into,
                                                   &(encoding_t){t, msg}) ? errno : 0, (size_t)size);
    if ((size_t)size > p->bufcap && !grow_buf(p, (size_t)size))
        return marie_fail(ENOMEM);
    if (t->encode(p->buf, 0, size, msg) != size)
        return marie_fail(EINVAL);
    return marie_port_publish_raw(p, p->buf, (size_t)size);
}

int marie_port_on_message(marie_port_t *p, marie_msg_cb_t cb)
{
    if (p->spec->dir != MARIE_IN || p->spec->mech == MARIE_PULL)
        return marie_fail(EINVAL);
    p->cb = cb;
    if (!p->sub)        /* typed messages in shared memory are decoded where they lie */
        p->sub = p->shm && p->spec->type ? marie_bus_subscribe_in_place(p->lcm, p->channel, on_shm_in_place,
                                                                         on_shm_held, on_shm_verdict, p)
                                         : marie_bus_subscribe(p->lcm, p->channel, on_port_message, p);
    return p->sub ? 0 : marie_fail(EIO);
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
    pull_finish(pl->port->c, pl, ETIMEDOUT, NULL, 0);
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
        status = ENODATA;
    } else if (r.status != MARIE_PULL_REPLY_T_STATUS_OK) {
        status = r.status == MARIE_PULL_REPLY_T_STATUS_UNKNOWN_CHANNEL ? ENOENT : EBADMSG;
    } else if (t) {
        const char *why;
        msg = pl->cb ? pl->port->scratch : pl->msg;
        if (marie_decode_input(t, r.data, (size_t)r.size, msg, &why) < 0) {
            marie_component_bad_input(c, why, "pull reply on %s: %d bytes: not a well-formed, finite %s", r.channel,
                                      r.size, t->name);
            status = EBADMSG;
            msg = NULL;
        }
    }
    if (status == 0) {
        c->msgs_in++;
        pl->port->msgs++;
    }
    bool async = pl->cb != NULL;
    pull_finish(c, pl, status, msg, r.age_us);
    if (async && msg && t)
        t->decode_cleanup(msg);
    marie_pull_reply_t_decode_cleanup(&r);
}

static pull_t *pull_send(marie_port_t *p, int timeout_ms, marie_pull_cb_t cb, void *user, void *msg)
{
    marie_component_t *c = p->c;
    if (p->spec->mech != MARIE_PULL || timeout_ms < 0)
        return marie_fail_null(EINVAL);
    if (!c->reply_subscribed) {
        if (!marie_bus_subscribe(p->lcm, c->reply_channel, on_pull_reply, c))
            return marie_fail_null(EIO);
        c->reply_subscribed = true;
    }
    pull_t **n = realloc(c->pulls, (c->npulls + 1) * sizeof *n);
    pull_t *pl = calloc(1, sizeof *pl);
    if (!n || !pl) {
        free(pl);
        if (n)
            c->pulls = n;
        return marie_fail_null(ENOMEM);
    }
    c->pulls = n;
    *pl = (pull_t){.request_id = ++c->next_request_id, .port = p, .cb = cb, .user = user, .msg = msg};
    char req_channel[256];
    snprintf(req_channel, sizeof req_channel, "%s%s", p->channel, MARIE_PULL_SUFFIX);
    marie_pull_request_t req = {
        .utime = marie_wall_us(), .request_id = pl->request_id, .requester = c->name,
        .channel = p->channel, .reply_channel = c->reply_channel, .timeout_ms = timeout_ms,
    };
    if (marie_bus_publish_msg(p->lcm, req_channel, &marie_type_pull_request_t, &req) != 0) {
        c->drops++;
        free(pl);
        return marie_fail_null(EIO);
    }
    c->msgs_out++;
    /* On the wall clock: a Mailbox answers in wall time, and under --clock sim a component that
     * has not heard the clock yet (a restart resuming from a Mailbox) would see a sim-time
     * deadline pass at the first clock message, before any answer could come. */
    pl->timeout = marie_loop_add_wall_oneshot(c->loop, (int64_t)timeout_ms * 1000, on_pull_timeout, pl);
    c->pulls[c->npulls++] = pl;
    return pl;
}

int marie_port_pull_async(marie_port_t *p, int timeout_ms, marie_pull_cb_t cb, void *user)
{
    if (!cb)
        return marie_fail(EINVAL);
    return pull_send(p, timeout_ms, cb, user, NULL) ? 0 : -1;
}

int marie_port_pull(marie_port_t *p, void *msg, int timeout_ms, int64_t *age_us)
{
    pull_t *pl = pull_send(p, timeout_ms, NULL, NULL, msg);
    if (!pl)
        return -1;
    /* Other messages keep being handled while we wait for this reply. */
    while (!pl->done && !marie_loop_quitting(p->c->loop)) {
        int rc = marie_loop_run_once(p->c->loop, 10);
        if (rc < 0) {
            pull_finish(p->c, pl, errno, NULL, 0);
            break;
        }
    }
    if (!pl->done)
        pull_finish(p->c, pl, ECANCELED, NULL, 0);
    int status = pl->status;
    if (age_us)
        *age_us = pl->age_us;
    free(pl);
    return status ? marie_fail(status) : 0;
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
    if (hz <= 0 || !cb)
        return marie_fail_null(EINVAL);
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
        return marie_fail_null(ENOMEM);
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

lcm_t *marie_comp_bus_for(marie_component_t *c, const char *url)
{
    for (size_t i = 0; i < c->nbuses; i++)
        if (strcmp(c->buses[i].url, url) == 0)
            return c->buses[i].lcm;
    bus_t *n = realloc(c->buses, (c->nbuses + 1) * sizeof *n);
    if (!n)
        return NULL;
    c->buses = n;
    lcm_t *lcm = marie_bus_create(url);
    if (!lcm) {
        marie_error("%s: cannot open the LCM bus '%s'", c->name, url);
        return NULL;
    }
    if (marie_bus_set_transports(lcm, c->sys) < 0) {
        marie_error("%s: the bus '%s' cannot take the system file's transports: %s", c->name, url, strerror(errno));
        marie_bus_destroy(lcm);
        return NULL;
    }
    c->buses[c->nbuses++] = (bus_t){strdup(url), lcm, {0}};
    return lcm;
}

int marie_comp_bind_ports(marie_component_t *c, const options_t *o, marie_errors_t *errs)
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
        p->lcm = marie_comp_bus_for(c, url);
        if (!p->lcm || !p->channel)
            return -1;
        const marie_transport_cfg_t *tr = marie_system_transport(c->sys, channel);
        if (tr && tr->shm) {
            p->shm = tr;
            bool ready = p->spec->dir == MARIE_OUT && marie_bus_prepare(p->lcm, channel) == 0;
            if (p->spec->dir == MARIE_OUT && !ready) {
                marie_errors_add(errs, c->sys->file, tr->line, tr->col, "%s '%s': port '%s': no shared memory for %s: %s",
                                 c->def->kind, c->name, p->spec->name, channel, strerror(errno));
                rc = -1;
            }
            p->loanable = ready && p->spec->type &&
                          marie_typeinfo_tail(marie_typeinfo_by_fingerprint(p->spec->type->hash()), &p->tail) == 0;
        }
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
