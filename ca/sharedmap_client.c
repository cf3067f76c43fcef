/* sharedmap_client: request/reply over LCM matched by request id, waited for or called back. */
#include "ca/sharedmap_client.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ca/ca.h"
#include "core/clear.h"
#include "core/err.h"
#include "core/loop.h"
#include "core/time.h"
#include "lcmtypes/marie_sharedmap_reply_t.h"
#include "lcmtypes/marie_sharedmap_request_t.h"

typedef struct {
    int64_t id;
    int64_t deadline;               /* monotonic us */
    sharedmap_client_cb_t cb;
    void *user;
} pending_t;

struct sharedmap_client {
    lcm_t *lcm;
    char *request_channel;
    char *reply_channel;
    char *name;
    marie_bus_sub_t *sub;
    int64_t next_id;
    int64_t waiting_id;             /* 0: none */
    marie_sharedmap_reply_t *reply; /* the matching reply (&decoded), or NULL */
    marie_sharedmap_reply_t decoded;
    int64_t timeouts, strays, bad;
    pending_t *pending;             /* asynchronous requests in flight */
    size_t npending, cap_pending;
    marie_loop_t *wait_loop;        /* the synchronous calls wait on it (made at the first) */
};

static void drop_reply(sharedmap_client_t *cl)
{
    if (cl->reply)
        marie_sharedmap_reply_t_decode_cleanup(cl->reply);
    cl->reply = NULL;
}

static int errno_of(int8_t status);

/* Hand a reply to the asynchronous request it answers; false when none does. */
static bool deliver_async(sharedmap_client_t *cl, const marie_sharedmap_reply_t *r)
{
    for (size_t i = 0; i < cl->npending; i++) {
        if (cl->pending[i].id != r->request_id)
            continue;
        pending_t p = cl->pending[i];
        cl->pending[i] = cl->pending[--cl->npending];   /* before the callback: it may send more */
        sharedmap_result_t res = {
            .status = errno_of(r->status), .request_id = r->request_id, .version = r->version,
            .type = r->type, .data = r->data, .len = r->size > 0 ? (size_t)r->size : 0,
            .age_us = r->age_us, .keys = r->keys, .nkeys = r->nkeys > 0 ? (size_t)r->nkeys : 0,
        };
        p.cb(cl, &res, p.user);
        return true;
    }
    return false;
}

static void on_reply(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    sharedmap_client_t *cl = user;
    marie_sharedmap_reply_t msg;
    if (marie_decode_checked(&marie_type_sharedmap_reply_t, rbuf->data, rbuf->data_size, &msg) < 0) {
        cl->bad++;
        return;
    }
    int64_t id = msg.request_id;
    if (id != cl->waiting_id && deliver_async(cl, &msg)) {
        marie_sharedmap_reply_t_decode_cleanup(&msg);
        return;
    }
    if (cl->waiting_id == 0 || id != cl->waiting_id || cl->reply) {
        cl->strays++;
        marie_sharedmap_reply_t_decode_cleanup(&msg);
        return;
    }
    cl->decoded = msg;          /* kept until the waiting call has read it */
    cl->reply = &cl->decoded;
}

sharedmap_client_t *sharedmap_client_create(lcm_t *lcm, const char *request_channel, const char *name)
{
    sharedmap_client_t *cl = calloc(1, sizeof *cl);
    if (!cl)
        return NULL;
    static int instance;
    char rc[256];
    cl->lcm = lcm;
    cl->name = strdup(name ? name : "client");
    cl->request_channel = strdup(request_channel ? request_channel : SHAREDMAP_DEFAULT_CHANNEL);
    snprintf(rc, sizeof rc, "%s.REPLY.%s.%d.%d", cl->request_channel, cl->name, (int)getpid(), instance++);
    cl->reply_channel = strdup(rc);
    char *pat = cl->reply_channel ? ca_channel_pattern(cl->reply_channel) : NULL;
    if (!cl->name || !cl->request_channel || !pat)
        goto err;
    cl->sub = marie_bus_subscribe(lcm, pat, on_reply, cl);
    free(pat);
    if (!cl->sub)
        goto err;
    /* Ids unique across restarts of the client, so a late reply to an earlier run never
     * matches a new request. */
    cl->next_id = (marie_wall_us() & 0x3fffffffffffll) << 8;
    return cl;
err:
    sharedmap_client_destroy(cl);
    return marie_fail_null(ENOMEM);
}

void sharedmap_client_destroy(sharedmap_client_t *cl)
{
    if (!cl)
        return;
    if (cl->sub)
        marie_bus_unsubscribe(cl->lcm, cl->sub);
    drop_reply(cl);
    marie_loop_destroy(cl->wait_loop);
    free(cl->pending);
    free(cl->request_channel);
    free(cl->reply_channel);
    free(cl->name);
    free(cl);
}

int64_t sharedmap_client_timeouts(const sharedmap_client_t *cl) { return cl->timeouts; }
int64_t sharedmap_client_stray_replies(const sharedmap_client_t *cl) { return cl->strays + cl->bad; }

/* A reply's status as an errno value (0: OK). */
static int errno_of(int8_t status)
{
    switch (status) {
    case MARIE_SHAREDMAP_REPLY_T_STATUS_OK: return 0;
    case MARIE_SHAREDMAP_REPLY_T_STATUS_NOT_FOUND: return ENOENT;
    case MARIE_SHAREDMAP_REPLY_T_STATUS_BAD_REQUEST: return EINVAL;
    case MARIE_SHAREDMAP_REPLY_T_STATUS_BAD_TYPE: return EBADMSG;
    case MARIE_SHAREDMAP_REPLY_T_STATUS_TOO_LARGE: return EFBIG;
    default: return EIO;
    }
}

/* Fill in the common fields and publish. 0, or -1 with errno EIO. */
static int send_request(sharedmap_client_t *cl, marie_sharedmap_request_t *req)
{
    req->utime = marie_wall_us();
    req->request_id = ++cl->next_id;
    req->client = cl->name;
    req->reply_channel = cl->reply_channel;
    if (!req->key)
        req->key = "";
    if (!req->type)
        req->type = "";
    if (!req->data)
        req->data = (uint8_t *)"";  /* lcm-gen's encoder memcpy()s even 0 bytes */
    return marie_bus_publish_msg(cl->lcm, cl->request_channel, &marie_type_sharedmap_request_t, req) < 0
               ? marie_fail(EIO) : 0;
}

static int have_reply(void *user) { return ((sharedmap_client_t *)user)->reply != NULL; }

/* Send req, wait for its reply (left in cl->reply): 0, or -1 with the reply's status as errno. */
static int call(sharedmap_client_t *cl, marie_sharedmap_request_t *req, int timeout_ms)
{
    drop_reply(cl);
    if (!cl->wait_loop) {
        cl->wait_loop = marie_loop_create();
        if (!cl->wait_loop || marie_loop_add_bus(cl->wait_loop, cl->lcm, 1) < 0) {
            MARIE_CLEAR(cl->wait_loop, marie_loop_destroy);
            return marie_fail(ENOMEM);
        }
    }
    if (send_request(cl, req) < 0)
        return marie_fail(EIO);
    cl->waiting_id = req->request_id;
    marie_loop_run_until(cl->wait_loop, timeout_ms < 0 ? 0 : timeout_ms, have_reply, cl);
    cl->waiting_id = 0;
    if (!cl->reply) {
        cl->timeouts++;
        return marie_fail(ETIMEDOUT);
    }
    int err = errno_of(cl->reply->status);
    return err ? marie_fail(err) : 0;
}

int sharedmap_client_set_raw(sharedmap_client_t *cl, const char *key, const char *type_name,
                             const void *data, size_t len, int timeout_ms, int64_t *version)
{
    if (len > INT32_MAX)
        return marie_fail(EFBIG);
    marie_sharedmap_request_t req = {
        .op = MARIE_SHAREDMAP_REQUEST_T_OP_SET, .key = (char *)key, .type = (char *)type_name,
        .size = (int32_t)len, .data = (uint8_t *)data,
    };
    int rc = call(cl, &req, timeout_ms);
    if (rc == 0 && version)
        *version = cl->reply->version;
    return rc;
}

/* encode_new: msg encoded into *buf (malloc'd; the caller frees it) of *n bytes: 0, or -1 with
 * errno EINVAL or ENOMEM. */
static int encode_new(const marie_type_t *type, const void *msg, uint8_t **buf, int *n)
{
    *buf = NULL;
    *n = type->encoded_size(msg);
    if (*n < 0)
        return marie_fail(EINVAL);
    if (!(*buf = malloc((size_t)*n)))
        return marie_fail(ENOMEM);
    if (type->encode(*buf, 0, *n, msg) != *n) {
        free(*buf);
        *buf = NULL;
        return marie_fail(EINVAL);
    }
    return 0;
}

int sharedmap_client_set(sharedmap_client_t *cl, const char *key, const marie_type_t *type,
                         const void *msg, int timeout_ms)
{
    uint8_t *buf;
    int n, rc = encode_new(type, msg, &buf, &n);
    if (rc == 0)
        rc = sharedmap_client_set_raw(cl, key, type->name, buf, (size_t)n, timeout_ms, NULL);
    MARIE_KEEP_ERRNO(free(buf));
    return rc;
}

int sharedmap_client_get_raw(sharedmap_client_t *cl, const char *key, void **data, size_t *len,
                             char *type_name, size_t type_cap, int timeout_ms, int64_t *age_us)
{
    marie_sharedmap_request_t req = { .op = MARIE_SHAREDMAP_REQUEST_T_OP_GET, .key = (char *)key };
    int rc = call(cl, &req, timeout_ms);
    if (rc < 0)
        return rc;
    const marie_sharedmap_reply_t *r = cl->reply;
    if (r->size < 0)
        return marie_fail(EBADMSG);
    if (data) {
        *data = malloc(r->size ? (size_t)r->size : 1);
        if (!*data)
            return marie_fail(ENOMEM);
        memcpy(*data, r->data, (size_t)r->size);
    }
    if (len)
        *len = (size_t)r->size;
    if (type_name && type_cap)
        snprintf(type_name, type_cap, "%s", r->type);
    if (age_us)
        *age_us = r->age_us;
    return 0;
}

int sharedmap_client_get(sharedmap_client_t *cl, const char *key, const marie_type_t *type,
                         void *msg, int timeout_ms, int64_t *age_us)
{
    marie_sharedmap_request_t req = { .op = MARIE_SHAREDMAP_REQUEST_T_OP_GET, .key = (char *)key };
    int rc = call(cl, &req, timeout_ms);
    if (rc < 0)
        return rc;
    const marie_sharedmap_reply_t *r = cl->reply;
    if (r->size < 0 || marie_decode_checked(type, r->data, (size_t)r->size, msg) < 0)
        return marie_fail(EBADMSG);
    if (age_us)
        *age_us = r->age_us;
    return 0;
}

int sharedmap_client_delete(sharedmap_client_t *cl, const char *key, int timeout_ms)
{
    marie_sharedmap_request_t req = { .op = MARIE_SHAREDMAP_REQUEST_T_OP_DELETE, .key = (char *)key };
    return call(cl, &req, timeout_ms);
}

void sharedmap_client_free_keys(char **keys, size_t n)
{
    for (size_t i = 0; keys && i < n; i++)
        free(keys[i]);
    free(keys);
}

int sharedmap_client_list(sharedmap_client_t *cl, const char *prefix, char ***keys, size_t *n,
                          int timeout_ms)
{
    marie_sharedmap_request_t req = { .op = MARIE_SHAREDMAP_REQUEST_T_OP_LIST, .key = (char *)prefix };
    int rc = call(cl, &req, timeout_ms);
    if (rc < 0)
        return rc;
    const marie_sharedmap_reply_t *r = cl->reply;
    size_t k = r->nkeys > 0 ? (size_t)r->nkeys : 0;
    char **out = calloc(k ? k : 1, sizeof *out);
    if (!out)
        return marie_fail(ENOMEM);
    for (size_t i = 0; i < k; i++) {
        out[i] = strdup(r->keys[i]);
        if (!out[i]) {
            sharedmap_client_free_keys(out, i);
            return marie_fail(ENOMEM);
        }
    }
    *keys = out;
    *n = k;
    return 0;
}

/* ---- asynchronous forms ---- */

static int call_async(sharedmap_client_t *cl, marie_sharedmap_request_t *req, int timeout_ms,
                      sharedmap_client_cb_t cb, void *user)
{
    if (!cb || timeout_ms < 0)
        return marie_fail(EINVAL);
    if (cl->npending == cl->cap_pending) {
        size_t cap = cl->cap_pending ? cl->cap_pending * 2 : 8;
        pending_t *np = realloc(cl->pending, cap * sizeof *np);
        if (!np)
            return marie_fail(ENOMEM);
        cl->pending = np;
        cl->cap_pending = cap;
    }
    if (send_request(cl, req) < 0)
        return marie_fail(EIO);
    cl->pending[cl->npending++] = (pending_t){ req->request_id,
                                               marie_mono_us() + (int64_t)timeout_ms * 1000, cb, user };
    return 0;
}

int sharedmap_client_set_raw_async(sharedmap_client_t *cl, const char *key, const char *type_name,
                                   const void *data, size_t len, int timeout_ms,
                                   sharedmap_client_cb_t cb, void *user)
{
    if (len > INT32_MAX)
        return marie_fail(EFBIG);
    marie_sharedmap_request_t req = {
        .op = MARIE_SHAREDMAP_REQUEST_T_OP_SET, .key = (char *)key, .type = (char *)type_name,
        .size = (int32_t)len, .data = (uint8_t *)data,
    };
    return call_async(cl, &req, timeout_ms, cb, user);
}

int sharedmap_client_set_async(sharedmap_client_t *cl, const char *key, const marie_type_t *type,
                               const void *msg, int timeout_ms, sharedmap_client_cb_t cb, void *user)
{
    uint8_t *buf;
    int n, rc = encode_new(type, msg, &buf, &n);
    if (rc == 0)
        rc = sharedmap_client_set_raw_async(cl, key, type->name, buf, (size_t)n, timeout_ms, cb, user);
    MARIE_KEEP_ERRNO(free(buf));
    return rc;
}

int sharedmap_client_get_async(sharedmap_client_t *cl, const char *key, int timeout_ms,
                               sharedmap_client_cb_t cb, void *user)
{
    marie_sharedmap_request_t req = { .op = MARIE_SHAREDMAP_REQUEST_T_OP_GET, .key = (char *)key };
    return call_async(cl, &req, timeout_ms, cb, user);
}

int sharedmap_client_delete_async(sharedmap_client_t *cl, const char *key, int timeout_ms,
                                  sharedmap_client_cb_t cb, void *user)
{
    marie_sharedmap_request_t req = { .op = MARIE_SHAREDMAP_REQUEST_T_OP_DELETE, .key = (char *)key };
    return call_async(cl, &req, timeout_ms, cb, user);
}

int sharedmap_client_tick(sharedmap_client_t *cl)
{
    int64_t now = marie_mono_us();
    for (size_t i = 0; i < cl->npending;) {
        if (cl->pending[i].deadline > now) {
            i++;
            continue;
        }
        pending_t p = cl->pending[i];
        cl->pending[i] = cl->pending[--cl->npending];
        cl->timeouts++;
        sharedmap_result_t res = { .status = ETIMEDOUT, .request_id = p.id, .type = "" };
        p.cb(cl, &res, p.user);
        i = 0;      /* the callback may have changed the list */
    }
    return (int)cl->npending;
}
