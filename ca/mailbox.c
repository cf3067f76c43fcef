/* mailbox: a ring of the newest payloads of one channel and the pull protocol's server side. */
#include "ca/mailbox.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/component.h"
#include "core/err.h"
#include "lcmtypes/marie_pull_reply_t.h"

typedef struct {
    uint8_t *data;
    size_t len, cap;
    int64_t recv_utime;
} slot_t;

typedef struct {
    int64_t request_id;
    int64_t deadline;
    char *reply_channel;
} waiter_t;

struct mailbox {
    char *channel;
    char *pull_channel;
    char *overflow_counter;         /* "CHANNEL.overflow" */
    const marie_type_t *type;
    ca_sink_t sink;
    slot_t *ring;
    size_t depth, head, count;      /* head: index of the next write */
    waiter_t waiting[MAILBOX_MAX_WAITING];
    size_t nwaiting;
    uint8_t *enc;                   /* reply encode buffer */
    size_t enc_cap;
    mailbox_stats_t stats;
    lcm_t *lcm;
    ca_input_t data;
    marie_bus_sub_t *sub_pull;
};

mailbox_t *mailbox_create(const char *channel, const marie_type_t *type, int depth,
                          const ca_sink_t *sink)
{
    if (!channel || !*channel || depth < 1)
        return marie_fail_null(EINVAL);
    mailbox_t *mb = calloc(1, sizeof *mb);
    if (!mb)
        return NULL;
    mb->channel = strdup(channel);
    mb->pull_channel = malloc(strlen(channel) + sizeof MARIE_PULL_SUFFIX);
    mb->ring = calloc((size_t)depth, sizeof *mb->ring);
    mb->overflow_counter = malloc(strlen(channel) + sizeof ".overflow");
    if (!mb->channel || !mb->pull_channel || !mb->ring || !mb->overflow_counter) {
        mailbox_destroy(mb);
        return marie_fail_null(ENOMEM);
    }
    strcpy(mb->pull_channel, channel);
    strcat(mb->pull_channel, MARIE_PULL_SUFFIX);
    strcpy(mb->overflow_counter, channel);
    strcat(mb->overflow_counter, ".overflow");
    mb->depth = (size_t)depth;
    mb->type = type;
    if (sink)
        mb->sink = *sink;
    return mb;
}

void mailbox_destroy(mailbox_t *mb)
{
    if (!mb)
        return;
    mailbox_detach(mb);
    for (size_t i = 0; mb->ring && i < mb->depth; i++)
        free(mb->ring[i].data);
    for (size_t i = 0; i < mb->nwaiting; i++)
        free(mb->waiting[i].reply_channel);
    free(mb->ring);
    free(mb->enc);
    free(mb->pull_channel);
    free(mb->overflow_counter);
    free(mb->channel);
    free(mb);
}

const char *mailbox_channel(const mailbox_t *mb) { return mb->channel; }
const char *mailbox_pull_channel(const mailbox_t *mb) { return mb->pull_channel; }
size_t mailbox_count(const mailbox_t *mb) { return mb->count; }
const mailbox_stats_t *mailbox_stats(const mailbox_t *mb) { return &mb->stats; }

static const slot_t *newest(const mailbox_t *mb, size_t i)
{
    if (i >= mb->count)
        return NULL;
    return &mb->ring[(mb->head + mb->depth - 1 - i) % mb->depth];
}

int mailbox_peek(const mailbox_t *mb, size_t i, const void **raw, size_t *len, int64_t *recv_utime)
{
    const slot_t *s = newest(mb, i);
    if (!s)
        return marie_fail(ENODATA);
    if (raw)
        *raw = s->data;
    if (len)
        *len = s->len;
    if (recv_utime)
        *recv_utime = s->recv_utime;
    return 0;
}

int mailbox_latest(const mailbox_t *mb, void *msg, int64_t now, int64_t *age_us)
{
    if (!mb->type)
        return marie_fail(EINVAL);
    const slot_t *s = newest(mb, 0);
    if (!s)
        return marie_fail(ENODATA);
    if (marie_decode_checked(mb->type, s->data, s->len, msg) < 0)
        return marie_fail(EBADMSG);
    if (age_us)
        *age_us = now - s->recv_utime;
    return 0;
}

/* Encode and publish one reply; `s` NULL for data-less answers. */
static int reply(mailbox_t *mb, const char *reply_channel, int64_t request_id, int8_t status,
                 const slot_t *s, int64_t now)
{
    marie_pull_reply_t r = {
        .utime = now,
        .request_id = request_id,
        .channel = mb->channel,
        .status = status,
        .data = (uint8_t *)"",      /* lcm-gen's encoder memcpy()s even 0 bytes */
    };
    if (s) {
        r.age_us = now - s->recv_utime;
        ca_fingerprint(s->data, s->len, &r.fingerprint);
        r.size = (int32_t)s->len;
        r.data = s->data;
    }
    int need = marie_pull_reply_t_encoded_size(&r);
    if ((size_t)need > mb->enc_cap) {
        uint8_t *nb = realloc(mb->enc, (size_t)need);
        if (!nb) {
            ca_note(&mb->sink, CA_NOTE_DROP, "reply_failed", 1, NULL);
            return marie_fail(ENOMEM);
        }
        mb->enc = nb;
        mb->enc_cap = (size_t)need;
    }
    int n = marie_pull_reply_t_encode(mb->enc, 0, need, &r);
    if (n < 0)
        return marie_fail(EINVAL);
    mb->stats.replies++;
    if (ca_publish(&mb->sink, reply_channel, mb->enc, (size_t)n) < 0) {
        ca_note(&mb->sink, CA_NOTE_DROP, "reply_failed", 1, "reply to %s failed", reply_channel);
        return marie_fail(EIO);
    }
    return 0;
}

static void waiter_remove(mailbox_t *mb, size_t i)
{
    free(mb->waiting[i].reply_channel);
    memmove(&mb->waiting[i], &mb->waiting[i + 1], (mb->nwaiting - i - 1) * sizeof mb->waiting[0]);
    mb->nwaiting--;
}

int mailbox_push(mailbox_t *mb, const void *raw, size_t len, int64_t recv_utime)
{
    if (ca_input_check(&mb->sink, mb->type, mb->channel, raw, len) < 0) {
        mb->stats.bad_input++;
        return marie_fail(EBADMSG);
    }
    slot_t *s = &mb->ring[mb->head];
    if (len > s->cap) {
        uint8_t *nb = realloc(s->data, len);
        if (!nb) {
            ca_note(&mb->sink, CA_NOTE_DROP, "overflow", 1, "%s: out of memory", mb->channel);
            return marie_fail(ENOMEM);
        }
        s->data = nb;
        s->cap = len;
    }
    memcpy(s->data, raw, len);
    s->len = len;
    s->recv_utime = recv_utime;
    mb->head = (mb->head + 1) % mb->depth;
    if (mb->count == mb->depth) {
        mb->stats.overflow++;
        ca_note(&mb->sink, CA_NOTE_DROP, mb->overflow_counter, 1, NULL);
    } else {
        mb->count++;
    }
    mb->stats.received++;
    /* Everyone waiting gets this newest payload. */
    while (mb->nwaiting > 0) {
        waiter_t *w = &mb->waiting[0];
        reply(mb, w->reply_channel, w->request_id, MARIE_PULL_REPLY_T_STATUS_OK, s, recv_utime);
        waiter_remove(mb, 0);
    }
    return 0;
}

/* How long before the requester's own timeout a held request is answered EMPTY, so the
 * answer arrives while it still listens even on a loaded machine: a quarter of the
 * timeout, at most 100 ms. */
static int64_t answer_margin_us(int32_t timeout_ms)
{
    int64_t m = (int64_t)timeout_ms * 250;
    return m > 100000 ? 100000 : m;
}

int mailbox_handle_request(mailbox_t *mb, const marie_pull_request_t *req, int64_t now)
{
    mb->stats.requests++;
    if (!req->reply_channel || !*req->reply_channel) {
        mb->stats.bad_requests++;
        ca_note(&mb->sink, CA_NOTE_BAD_INPUT, "bad_request", 1,
                "%s: pull request %lld from '%s' has no reply channel", mb->pull_channel,
                (long long)req->request_id, req->requester ? req->requester : "");
        return marie_fail(EINVAL);
    }
    if (!req->channel || strcmp(req->channel, mb->channel) != 0) {
        reply(mb, req->reply_channel, req->request_id, MARIE_PULL_REPLY_T_STATUS_UNKNOWN_CHANNEL,
              NULL, now);
        return 0;
    }
    const slot_t *s = newest(mb, 0);
    if (s)
        return reply(mb, req->reply_channel, req->request_id, MARIE_PULL_REPLY_T_STATUS_OK, s, now) < 0
                   ? marie_fail(EIO) : 0;
    if (req->timeout_ms <= 0)
        return reply(mb, req->reply_channel, req->request_id, MARIE_PULL_REPLY_T_STATUS_EMPTY, NULL, now) < 0
                   ? marie_fail(EIO) : 0;
    if (mb->nwaiting == MAILBOX_MAX_WAITING) {
        waiter_t *w = &mb->waiting[0];
        reply(mb, w->reply_channel, w->request_id, MARIE_PULL_REPLY_T_STATUS_EMPTY, NULL, now);
        waiter_remove(mb, 0);
    }
    char *rc = strdup(req->reply_channel);
    if (!rc)
        return marie_fail(ENOMEM);
    int64_t t = (int64_t)req->timeout_ms;
    if (t > 3600 * 1000)
        t = 3600 * 1000;
    waiter_t *w = &mb->waiting[mb->nwaiting++];
    w->request_id = req->request_id;
    w->reply_channel = rc;
    w->deadline = now + t * 1000 - answer_margin_us((int32_t)t);
    mb->stats.waited++;
    return 1;
}

int mailbox_handle_request_raw(mailbox_t *mb, const void *buf, size_t len, int64_t now)
{
    marie_pull_request_t req;
    if (marie_decode_checked(&marie_type_pull_request_t, buf, len, &req) < 0) {
        mb->stats.bad_requests++;
        return ca_bad_request(&mb->sink, mb->pull_channel, "pull request", buf, len);
    }
    int rc = mailbox_handle_request(mb, &req, now);
    marie_pull_request_t_decode_cleanup(&req);
    return rc;
}

int mailbox_tick(mailbox_t *mb, int64_t now)
{
    int n = 0;
    for (size_t i = 0; i < mb->nwaiting;) {
        waiter_t *w = &mb->waiting[i];
        if (w->deadline <= now) {
            reply(mb, w->reply_channel, w->request_id, MARIE_PULL_REPLY_T_STATUS_EMPTY, NULL, now);
            waiter_remove(mb, i);
            n++;
        } else {
            i++;
        }
    }
    return n;
}

int64_t mailbox_next_deadline(const mailbox_t *mb)
{
    int64_t d = INT64_MAX;
    for (size_t i = 0; i < mb->nwaiting; i++)
        if (mb->waiting[i].deadline < d)
            d = mb->waiting[i].deadline;
    return d;
}

static void on_data(void *user, const void *buf, size_t len, int64_t recv_utime)
{
    mailbox_push(user, buf, len, recv_utime);
}

static void on_pull(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    mailbox_handle_request_raw(user, rbuf->data, rbuf->data_size, marie_wall_us());
}

int mailbox_attach(mailbox_t *mb, lcm_t *lcm)
{
    if (mb->lcm)
        return marie_fail(EALREADY);
    char *pat = ca_channel_pattern(mb->pull_channel);
    if (!pat)
        return marie_fail(ENOMEM);
    int rc = ca_input_open(&mb->data, lcm, mb->channel, on_data, mb);
    int err = rc < 0 ? errno : EIO;
    mb->sub_pull = marie_bus_subscribe(lcm, pat, on_pull, mb);
    free(pat);
    mb->lcm = lcm;
    mb->sink.lcm = lcm;
    if (rc < 0 || !mb->sub_pull) {
        mailbox_detach(mb);
        return marie_fail(err);
    }
    return 0;
}

marie_bus_sub_stats_t mailbox_input_stats(const mailbox_t *mb)
{
    return ca_input_stats(&mb->data);
}

void mailbox_detach(mailbox_t *mb)
{
    if (!mb->lcm)
        return;
    ca_input_close(&mb->data);
    if (mb->sub_pull)
        marie_bus_unsubscribe(mb->lcm, mb->sub_pull);
    mb->sub_pull = NULL;
    mb->lcm = NULL;
}
