/* xb_requests: the XML bridge's requests (subscribe, publish, pull, types, describe), their
 * replies, and the LCM subscriptions that feed subscribed clients and pulls. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/xml_bridge/xb_server_int.h"
#include "core/buf.h"
#include "core/time.h"

/* ---- replies ---- */

static void put_attr(marie_buf_t *b, const char *name, const char *value)
{
    if (!value)
        return;
    marie_buf_printf(b, " %s=\"", name);
    xb_escape(b, value, strlen(value));
    marie_buf_put(b, "\"", 1);
}

void xb_reply_error(client_t *c, const xb_node_t *req, const char *code, const char *reason)
{
    xb_server_t *s = c->s;
    xb_publish_flush(s);        /* replies keep request order */
    marie_buf_t *b = &s->out;
    b->len = 0;
    marie_buf_puts(b, "<error");
    put_attr(b, "code", code);
    put_attr(b, "reason", reason);
    if (req) {
        put_attr(b, "to", req->name);
        put_attr(b, "id", xb_node_attr(req, "id"));
        put_attr(b, "channel", xb_node_attr(req, "channel"));
    }
    marie_buf_puts(b, "/>\n");
    s->st.errors++;
    xb_client_enqueue_text(c, b->data, b->len);
}

static void reply_ok(client_t *c, const xb_node_t *req, const char *extra_name, const char *extra)
{
    xb_publish_flush(c->s);
    marie_buf_t *b = &c->s->out;
    b->len = 0;
    marie_buf_puts(b, "<ok");
    put_attr(b, "to", req->name);
    put_attr(b, "id", xb_node_attr(req, "id"));
    put_attr(b, "channel", xb_node_attr(req, "channel"));
    put_attr(b, "type", xb_node_attr(req, "type"));
    put_attr(b, extra_name, extra);
    marie_buf_puts(b, "/>\n");
    xb_client_enqueue_text(c, b->data, b->len);
}

/* Writes <message ...>fields</message> of a raw payload into s->out; -1 if it does not decode. */
static int format_message(xb_server_t *s, const sub_t *sub, const char *channel, const void *data,
                          size_t len, int64_t recv_utime, const xb_node_t *req, xb_error_t *err)
{
    marie_buf_t *b = &s->out;
    b->len = 0;
    b->failed = false;
    marie_buf_puts(b, "<message");
    put_attr(b, "channel", channel);
    put_attr(b, "type", sub->type->name);
    marie_buf_printf(b, " recv_utime=\"%lld\"", (long long)recv_utime);
    if (req) {
        put_attr(b, "to", req->name);
        put_attr(b, "id", xb_node_attr(req, "id"));
        marie_buf_printf(b, " age_us=\"%lld\"", (long long)(marie_wall_us() - recv_utime));
    }
    marie_buf_puts(b, ">");
    if (xb_decode(sub->type, data, len, b, err) < 0)
        return -1;
    if (marie_buf_puts(b, "</message>\n") < 0) {
        xb_error_set(err, "too-large", "message document over %zu bytes", b->max);
        return -1;
    }
    return 0;
}

/* ---- subscriptions ---- */

/* The newest well-formed payload, for pull. */
static void keep_latest(sub_t *sub, const lcm_recv_buf_t *rbuf)
{
    char *copy = realloc(sub->latest, rbuf->data_size ? rbuf->data_size : 1);
    if (!copy)
        return;
    memcpy(copy, rbuf->data, rbuf->data_size);
    sub->latest = copy;
    sub->latest_len = rbuf->data_size;
    sub->latest_utime = rbuf->recv_utime;
    sub->has_latest = 1;
}

static void on_lcm(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    sub_t *sub = user;
    xb_server_t *s = sub->s;
    if (sub->nclients == 0)
        return;
    s->st.received++;
    if (rbuf->data_size > s->cfg.max_message) {
        xb_bad_input(s, "oversized_message", "%s: %u bytes over the limit", channel, rbuf->data_size);
        return;
    }
    xb_error_t err;
    if (sub->nstream == 0) {
        /* Kept for pull only: a message components would refuse never becomes the latest. */
        if (marie_typeinfo_check(sub->type, rbuf->data, rbuf->data_size) < 0) {
            xb_bad_input(s, "bad_lcm_message", "%s: not a well-formed %s (%u bytes)", channel, sub->type->name,
                         rbuf->data_size);
            return;
        }
        keep_latest(sub, rbuf);
        return;
    }
    if (format_message(s, sub, channel, rbuf->data, rbuf->data_size, rbuf->recv_utime, NULL, &err) == 0) {
        keep_latest(sub, rbuf);
    } else {
        xb_bad_input(s, "bad_lcm_message", "%s: %s", channel, err.reason);
        marie_buf_t *b = &s->out;
        b->len = 0;
        marie_buf_puts(b, "<error");
        put_attr(b, "code", err.code);
        put_attr(b, "reason", err.reason);
        put_attr(b, "channel", channel);
        marie_buf_puts(b, "/>\n");
    }
    msgbuf_t *mb = xb_msgbuf_new(s->out.data, s->out.len);
    if (!mb)
        return;
    for (int i = 0; i < sub->nclients; i++)
        if (sub->stream[i]) {
            xb_client_enqueue(sub->clients[i], mb);
            s->st.delivered++;
        }
    xb_msgbuf_unref(mb);
}

static sub_t *sub_find(xb_server_t *s, const char *channel, const marie_typeinfo_t *t)
{
    for (sub_t *u = s->subs; u; u = u->next)
        if (u->type == t && strcmp(u->channel, channel) == 0)
            return u;
    return NULL;
}

static sub_t *sub_get(xb_server_t *s, const char *channel, const marie_typeinfo_t *t)
{
    sub_t *u = sub_find(s, channel, t);
    if (u)
        return u;
    u = calloc(1, sizeof *u);
    if (!u || !(u->channel = strdup(channel)))
        goto fail;
    u->type = t;
    u->s = s;
    /* LCM matches channels as regular expressions; bridge channels are literal names. */
    char re[2 * LCM_MAX_CHANNEL_NAME_LENGTH + 2];
    size_t k = 0;
    for (const char *p = channel; *p; p++) {
        if (strchr(".[]()*+?{}|^$\\", *p))
            re[k++] = '\\';
        re[k++] = *p;
    }
    re[k] = '\0';
    u->ls = marie_bus_subscribe(s->lcm, re, on_lcm, u);
    if (!u->ls)
        goto fail;
    u->next = s->subs;
    s->subs = u;
    s->st.subscriptions++;
    return u;
fail:
    if (u)
        free(u->channel);
    free(u);
    return NULL;
}

void xb_sub_release(xb_server_t *s, sub_t *u)
{
    if (u->nclients > 0)
        return;
    for (sub_t **pp = &s->subs; *pp; pp = &(*pp)->next)
        if (*pp == u) {
            *pp = u->next;
            break;
        }
    marie_bus_unsubscribe(s->lcm, u->ls);
    free(u->channel);
    free(u->clients);
    free(u->stream);
    free(u->latest);
    free(u);
    s->st.subscriptions--;
}

static int sub_add_client(sub_t *u, client_t *c, int stream)
{
    for (int i = 0; i < u->nclients; i++)
        if (u->clients[i] == c) {
            u->nstream += stream - u->stream[i];
            u->stream[i] = stream;
            return 0;
        }
    size_t cap_clients = u->capclients, cap_stream = u->capclients;   /* the two grow alike */
    if (MARIE_GROW(u->clients, cap_clients, (size_t)u->nclients + 1) < 0 ||
        MARIE_GROW(u->stream, cap_stream, (size_t)u->nclients + 1) < 0)
        return -1;
    u->capclients = cap_clients;
    u->clients[u->nclients] = c;
    u->stream[u->nclients] = stream;
    u->nclients++;
    u->nstream += stream;
    return 0;
}

void xb_sub_remove_client(xb_server_t *s, sub_t *u, client_t *c)
{
    for (int i = 0; i < u->nclients; i++)
        if (u->clients[i] == c) {
            u->nstream -= u->stream[i];
            u->clients[i] = u->clients[u->nclients - 1];
            u->stream[i] = u->stream[u->nclients - 1];
            u->nclients--;
            break;
        }
    xb_sub_release(s, u);
}

static csub_t *client_sub(client_t *c, const char *channel, const marie_typeinfo_t *t)
{
    for (int i = 0; i < c->nsubs; i++)
        if (c->subs[i].sub->type == t && strcmp(c->subs[i].sub->channel, channel) == 0)
            return &c->subs[i];
    return NULL;
}

/* ---- requests ---- */

static const char *need_channel(client_t *c, const xb_node_t *req)
{
    const char *ch = xb_node_attr(req, "channel");
    if (!ch || !ch[0]) {
        xb_reply_error(c, req, "bad-request", "missing channel attribute");
        return NULL;
    }
    if (strlen(ch) > LCM_MAX_CHANNEL_NAME_LENGTH) {
        xb_reply_error(c, req, "bad-channel", "channel name longer than 63 bytes");
        return NULL;
    }
    return ch;
}

static const marie_typeinfo_t *need_type(client_t *c, const xb_node_t *req)
{
    const char *tn = xb_node_attr(req, "type");
    if (!tn) {
        xb_reply_error(c, req, "bad-request", "missing type attribute");
        return NULL;
    }
    const marie_typeinfo_t *t = marie_typeinfo_find(tn);
    if (!t) {
        char why[160];
        snprintf(why, sizeof why, "no type named '%.100s' (see <types/>)", tn);
        xb_reply_error(c, req, "unknown-type", why);
    }
    return t;
}

static void do_subscribe(client_t *c, const xb_node_t *req)
{
    const char *ch = need_channel(c, req);
    const marie_typeinfo_t *t = ch ? need_type(c, req) : NULL;
    if (!t)
        return;
    const char *mode = xb_node_attr(req, "mode");
    if (mode && strcmp(mode, "stream") != 0 && strcmp(mode, "latest") != 0) {
        xb_reply_error(c, req, "bad-request", "mode must be stream or latest");
        return;
    }
    int stream = !mode || strcmp(mode, "stream") == 0;
    csub_t *cs = client_sub(c, ch, t);
    if (!cs) {
        if (MARIE_GROW(c->subs, c->capsubs, (size_t)c->nsubs + 1) < 0) {
            xb_reply_error(c, req, "subscribe-failed", "out of memory");
            return;
        }
        sub_t *u = sub_get(c->s, ch, t);
        if (!u || sub_add_client(u, c, stream) < 0) {
            if (u)
                xb_sub_release(c->s, u);
            xb_reply_error(c, req, "subscribe-failed", "cannot subscribe on the bus");
            return;
        }
        c->subs[c->nsubs++] = (csub_t){ u, stream };
    } else {
        sub_add_client(cs->sub, c, stream);
        cs->stream = stream;
    }
    reply_ok(c, req, "mode", stream ? "stream" : "latest");
}

/* A request's channel and, when it names one, its type: 0, or -1 after the error reply. */
static int channel_and_optional_type(client_t *c, const xb_node_t *req, const char **ch,
                                     const marie_typeinfo_t **t)
{
    *ch = need_channel(c, req);
    if (!*ch)
        return -1;
    *t = xb_node_attr(req, "type") ? need_type(c, req) : NULL;
    return xb_node_attr(req, "type") && !*t ? -1 : 0;
}

static void do_unsubscribe(client_t *c, const xb_node_t *req)
{
    const char *ch;
    const marie_typeinfo_t *t;
    if (channel_and_optional_type(c, req, &ch, &t) < 0)
        return;
    int removed = 0;
    for (int i = 0; i < c->nsubs;) {
        sub_t *u = c->subs[i].sub;
        if (strcmp(u->channel, ch) == 0 && (!t || u->type == t)) {
            c->subs[i] = c->subs[--c->nsubs];
            xb_sub_remove_client(c->s, u, c);
            removed++;
        } else {
            i++;
        }
    }
    if (!removed)
        xb_reply_error(c, req, "not-subscribed", "no such subscription");
    else
        reply_ok(c, req, NULL, NULL);
}

/* Publishes the batched messages in request order; a failure is answered as it would have
 * been at once (no other reply can have been queued after the batch began). */
void xb_publish_flush(xb_server_t *s)
{
    int n = s->npend;
    if (n == 0)
        return;
    s->npend = 0;               /* the failure replies below call this again */
    marie_bus_msg_t msgs[XB_BATCH_MSGS] = { 0 };
    int rc[XB_BATCH_MSGS];
    for (int i = 0; i < n; i++)
        msgs[i] = (marie_bus_msg_t){ s->batch.data + s->pend[i].channel, s->batch.data + s->pend[i].data,
                                     (unsigned)s->pend[i].len };
    marie_bus_publish_batch(s->lcm, msgs, n, rc);     /* one system call for the lot */
    for (int i = 0; i < n; i++) {
        pend_t *m = &s->pend[i];
        const char *ch = s->batch.data + m->channel;
        if (rc[i] < 0) {
            if (s->hooks.drop)
                s->hooks.drop(s->hooks.user, 1);
            const char *attrs[] = { "channel", ch, m->id == SIZE_MAX ? NULL : "id",
                                    s->batch.data + m->id, NULL };
            xb_node_t req = { .name = "publish", .attrs = attrs };
            xb_reply_error(m->c, &req, "publish-failed", "the bus refused the message");
            continue;
        }
        s->st.published++;
    }
    marie_buf_reset(&s->batch);
}

/* Adds the encoded message in s->enc to the batch: 0, or -1 when it does not fit (the batch
 * is left as it was). */
static int batch_add(xb_server_t *s, client_t *c, const char *ch, const char *id)
{
    marie_buf_t *b = &s->batch;
    size_t at = b->len;
    pend_t m = { .c = c, .channel = at, .id = SIZE_MAX };
    marie_buf_put(b, ch, strlen(ch) + 1);
    if (id) {
        m.id = b->len;
        marie_buf_put(b, id, strlen(id) + 1);
    }
    m.data = b->len;
    m.len = s->enc.len;
    marie_buf_put(b, s->enc.data, s->enc.len);
    if (b->failed) {
        b->len = at;
        b->failed = false;
        return -1;
    }
    s->pend[s->npend++] = m;
    return 0;
}

static void do_publish(client_t *c, const xb_node_t *req)
{
    xb_server_t *s = c->s;
    const char *ch = need_channel(c, req);
    const marie_typeinfo_t *t = ch ? need_type(c, req) : NULL;
    if (!t)
        return;
    xb_error_t err;
    s->enc.len = 0;
    s->enc.failed = false;
    if (xb_encode(t, req, &s->enc, &err) < 0) {
        if (strcmp(err.code, "no-memory") == 0) {   /* the bridge's fault, not the document's */
            xb_reply_error(c, req, "publish-failed", err.reason);
            return;
        }
        xb_bad_input(s, "bad_document", "%s: %s", err.code, err.reason);
        xb_reply_error(c, req, err.code, err.reason);
        return;
    }
    const char *ack = xb_node_attr(req, "ack");
    int quiet = ack && strcmp(ack, "false") == 0;
    /* A reply must follow the batch it comes after; the batch never holds a large message. */
    if (!quiet || s->enc.len > XB_BATCH_BYTES / 4 || batch_add(s, c, ch, xb_node_attr(req, "id")) < 0) {
        xb_publish_flush(s);
        if (batch_add(s, c, ch, xb_node_attr(req, "id")) < 0) {
            xb_reply_error(c, req, "publish-failed", "out of memory");
            return;
        }
        uint64_t before = s->st.published;
        xb_publish_flush(s);
        if (!quiet && s->st.published != before)
            reply_ok(c, req, NULL, NULL);
        return;
    }
    if (s->npend == XB_BATCH_MSGS)
        xb_publish_flush(s);
}

static void do_pull(client_t *c, const xb_node_t *req)
{
    const char *ch;
    const marie_typeinfo_t *t;
    if (channel_and_optional_type(c, req, &ch, &t) < 0)
        return;
    /* The bridge is a Mailbox for every channel some client subscribed to. */
    sub_t *u = NULL;
    for (sub_t *v = c->s->subs; v; v = v->next)
        if (strcmp(v->channel, ch) == 0 && (!t || v->type == t) && (!u || (v->has_latest &&
            (!u->has_latest || v->latest_utime > u->latest_utime))))
            u = v;
    if (!u) {
        xb_reply_error(c, req, "not-subscribed", "subscribe to the channel (mode stream or latest) first");
        return;
    }
    if (!u->has_latest) {
        xb_reply_error(c, req, "no-data", "nothing received on the channel yet");
        return;
    }
    xb_error_t err;
    if (format_message(c->s, u, u->channel, u->latest, u->latest_len, u->latest_utime, req, &err) < 0) {
        xb_reply_error(c, req, err.code, err.reason);
        return;
    }
    xb_client_enqueue_text(c, c->s->out.data, c->s->out.len);
}

static const char *dims_text(const marie_tfield_t *f, const marie_typeinfo_t *t, char *buf, size_t size)
{
    size_t n = 0;
    buf[0] = '\0';
    for (int d = 0; d < f->ndims && n < size; d++) {
        if (f->dims[d].len_field < 0)
            n += (size_t)snprintf(buf + n, size - n, "[%d]", (int)f->dims[d].size);
        else
            n += (size_t)snprintf(buf + n, size - n, "[%s]", t->fields[f->dims[d].len_field].name);
    }
    return buf;
}

static void do_types(client_t *c, const xb_node_t *req)
{
    marie_buf_t *b = &c->s->out;
    b->len = 0;
    marie_buf_puts(b, "<types");
    put_attr(b, "id", xb_node_attr(req, "id"));
    marie_buf_puts(b, ">");
    const marie_typeinfo_t *t;
    for (size_t i = 0; (t = marie_typeinfo_at(i)); i++)
        marie_buf_printf(b, "<type name=\"%s\" fingerprint=\"%016llx\"/>", t->name,
                      (unsigned long long)t->fingerprint);
    marie_buf_puts(b, "</types>\n");
    xb_client_enqueue_text(c, b->data, b->len);
}

static void do_describe(client_t *c, const xb_node_t *req)
{
    const marie_typeinfo_t *t = need_type(c, req);
    if (!t)
        return;
    marie_buf_t *b = &c->s->out;
    b->len = 0;
    marie_buf_printf(b, "<type name=\"%s\" fingerprint=\"%016llx\"", t->name,
                  (unsigned long long)t->fingerprint);
    put_attr(b, "id", xb_node_attr(req, "id"));
    marie_buf_puts(b, ">");
    for (int i = 0; i < t->nfields; i++) {
        const marie_tfield_t *f = &t->fields[i];
        char dims[128];
        marie_buf_printf(b, "<field name=\"%s\" type=\"%s\"", f->name,
                      f->prim == MARIE_PRIM_STRUCT ? f->sub->name : marie_prim_name(f->prim));
        if (f->ndims)
            marie_buf_printf(b, " dims=\"%s\"", dims_text(f, t, dims, sizeof dims));
        marie_buf_puts(b, "/>");
    }
    for (int i = 0; i < t->nconsts; i++) {
        marie_buf_printf(b, "<const name=\"%s\" type=\"%s\"", t->consts[i].name,
                      marie_prim_name(t->consts[i].prim));
        put_attr(b, "value", t->consts[i].value);
        marie_buf_puts(b, "/>");
    }
    marie_buf_puts(b, "</type>\n");
    xb_client_enqueue_text(c, b->data, b->len);
}

void xb_on_document(void *user, xb_node_t *req)
{
    client_t *c = user;
    xb_server_t *s = c->s;
    s->st.documents++;
    c->active_us = marie_mono_us();
    if (c->dead || c->closing_since)
        return;
    const char *op = req->name;
    if (strcmp(op, "publish") == 0) {
        do_publish(c, req);
        return;
    }
    xb_publish_flush(s);        /* what came before is done before this request */
    if (strcmp(op, "subscribe") == 0)
        do_subscribe(c, req);
    else if (strcmp(op, "unsubscribe") == 0)
        do_unsubscribe(c, req);
    else if (strcmp(op, "pull") == 0)
        do_pull(c, req);
    else if (strcmp(op, "ping") == 0)
        reply_ok(c, req, NULL, NULL);
    else if (strcmp(op, "types") == 0)
        do_types(c, req);
    else if (strcmp(op, "describe") == 0)
        do_describe(c, req);
    else {
        char why[128];
        snprintf(why, sizeof why, "unknown request <%.64s>", op);
        xb_bad_input(s, "bad_document", "%s", why);
        xb_reply_error(c, req, "unknown-request", why);
    }
}
