/* sharedmap_client: set, get, delete and list keys of a SharedMap over LCM, with a timeout. */
#ifndef MARIE_CA_SHAREDMAP_CLIENT_H
#define MARIE_CA_SHAREDMAP_CLIENT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <lcm/lcm.h>

#include "lcmtypes/marie_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The channel a SharedMap listens on unless configured otherwise. */
#define SHAREDMAP_DEFAULT_CHANNEL "SHAREDMAP"

typedef struct sharedmap_client sharedmap_client_t;

/* A client of the SharedMap listening on request_channel (NULL: SHAREDMAP_DEFAULT_CHANNEL).
 * `name` identifies the client in requests and logs. Replies come back on a channel of its
 * own. NULL with errno on failure. */
sharedmap_client_t *sharedmap_client_create(lcm_t *lcm, const char *request_channel, const char *name);
void sharedmap_client_destroy(sharedmap_client_t *cl);     /* NULL is a no-op */

/* The calls below send one request and run a marie loop of the client's own over `lcm` (so
 * the caller's other subscriptions keep running) until the reply arrives or timeout_ms passes.
 * They are for programs that wait for the answer (a command line, a test); a program on a
 * marie loop uses the asynchronous forms further down. Do not call them from inside an LCM
 * handler of the same lcm_t (lcm_handle is not re-entrant).
 * Returns 0, or -1 with errno ETIMEDOUT (no reply: the write may or may not have happened),
 * ENOENT (no such key), EINVAL (refused as malformed), EBADMSG (payload is not of the named
 * type), EFBIG (too large), EIO (the SharedMap could not make it durable). */

/* Encode `msg` of `type` and store it under `key`; OK means it is on the SharedMap's disk. */
int sharedmap_client_set(sharedmap_client_t *cl, const char *key, const marie_type_t *type,
                         const void *msg, int timeout_ms);
/* Store a raw payload named with its LCM type name. *version (may be NULL) gets the map version. */
int sharedmap_client_set_raw(sharedmap_client_t *cl, const char *key, const char *type_name,
                             const void *data, size_t len, int timeout_ms, int64_t *version);
/* Fetch and decode into msg (free with type->decode_cleanup); errno EBADMSG if it is another type. */
int sharedmap_client_get(sharedmap_client_t *cl, const char *key, const marie_type_t *type,
                         void *msg, int timeout_ms, int64_t *age_us);
/* Fetch raw: *data (malloc'd, caller frees) and *len; type_name (may be NULL) receives up
 * to type_cap bytes of the type name. */
int sharedmap_client_get_raw(sharedmap_client_t *cl, const char *key, void **data, size_t *len,
                             char *type_name, size_t type_cap, int timeout_ms, int64_t *age_us);
int sharedmap_client_delete(sharedmap_client_t *cl, const char *key, int timeout_ms);
/* Keys starting with prefix ("" = all), sorted: *keys is a malloc'd array of malloc'd
 * strings; free with sharedmap_client_free_keys. */
int sharedmap_client_list(sharedmap_client_t *cl, const char *prefix, char ***keys, size_t *n,
                          int timeout_ms);
void sharedmap_client_free_keys(char **keys, size_t n);

/* Asynchronous forms, safe to call from LCM handlers: they only publish. cb runs exactly
 * once, from the handling of `lcm` when the reply arrives, or from sharedmap_client_tick()
 * with status ETIMEDOUT once timeout_ms has passed. Call sharedmap_client_tick() from a
 * timer (10-100 Hz). The result's pointers are valid during the callback only. Return 0, or
 * -1 with errno (then cb is never called). */
typedef struct {
    int status;                 /* 0, or the errno value the synchronous call would set */
    int64_t request_id;
    int64_t version;
    const char *type;           /* GET */
    const void *data;           /* GET */
    size_t len;
    int64_t age_us;             /* GET */
    char **keys;                /* LIST */
    size_t nkeys;
} sharedmap_result_t;
typedef void (*sharedmap_client_cb_t)(sharedmap_client_t *cl, const sharedmap_result_t *r, void *user);

int sharedmap_client_set_async(sharedmap_client_t *cl, const char *key, const marie_type_t *type,
                               const void *msg, int timeout_ms, sharedmap_client_cb_t cb, void *user);
int sharedmap_client_set_raw_async(sharedmap_client_t *cl, const char *key, const char *type_name,
                                   const void *data, size_t len, int timeout_ms,
                                   sharedmap_client_cb_t cb, void *user);
int sharedmap_client_get_async(sharedmap_client_t *cl, const char *key, int timeout_ms,
                               sharedmap_client_cb_t cb, void *user);
int sharedmap_client_delete_async(sharedmap_client_t *cl, const char *key, int timeout_ms,
                                  sharedmap_client_cb_t cb, void *user);
/* Time out asynchronous requests whose deadline passed; returns how many are still pending. */
int sharedmap_client_tick(sharedmap_client_t *cl);

/* Requests whose reply did not come in time; replies that matched no request or were malformed. */
int64_t sharedmap_client_timeouts(const sharedmap_client_t *cl);
int64_t sharedmap_client_stray_replies(const sharedmap_client_t *cl);

#ifdef __cplusplus
}
#endif
#endif
