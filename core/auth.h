/* auth: HMAC-SHA256 signing and checking of manager orders with a shared key file, and
 * per-sender replay protection. Used by marie-am, the marie command line and the log viewer. */
#ifndef MARIE_AUTH_H
#define MARIE_AUTH_H

#include <stddef.h>
#include <stdint.h>

#include "lcmtypes/marie_am_order_t.h"
#include "lcmtypes/marie_goal_request_t.h"
#include "lcmtypes/marie_lifecycle_command_t.h"
#include "lcmtypes/marie_param_request_t.h"

#ifdef __cplusplus
extern "C" {
#endif

#define MARIE_AUTH_KEY_LEN 32
#define MARIE_AUTH_MAC_LEN 32

typedef struct marie_auth marie_auth_t;

/* Load a key file: 64 hex digits (whitespace ignored) or 32 raw bytes. The file must be a
 * regular file that neither group nor others can read or write (mode 0600 or 0400); any
 * other mode is refused, because a key others can read lets them start processes.
 * Returns NULL with errno set and a one-line reason in err. */
marie_auth_t *marie_auth_load(const char *path, char *err, size_t errlen);
marie_auth_t *marie_auth_from_key(const uint8_t key[MARIE_AUTH_KEY_LEN]);
void marie_auth_destroy(marie_auth_t *a);          /* NULL is a no-op; wipes the key */

/* Write a fresh random key as hex to path with mode 0600 (fails if the file exists). */
int marie_auth_keygen(const char *path);

/* MAC of any bytes, and its constant-time check (0, or -1 with errno EBADMSG). */
void marie_auth_mac(const marie_auth_t *a, const void *data, size_t len, uint8_t mac[MARIE_AUTH_MAC_LEN]);
int marie_auth_verify(const marie_auth_t *a, const void *data, size_t len, const uint8_t *mac, size_t maclen);

/* Sign an order: the MAC covers the order encoded with mac_len = 0 (every field, seq
 * included). o->mac points into `store` afterwards. 0, or -1 with errno. */
int marie_auth_sign_order(const marie_auth_t *a, marie_am_order_t *o, uint8_t store[MARIE_AUTH_MAC_LEN]);
int marie_auth_sign_command(const marie_auth_t *a, marie_lifecycle_command_t *c, uint8_t store[MARIE_AUTH_MAC_LEN]);

typedef enum {
    MARIE_AUTH_OK = 0,
    MARIE_AUTH_UNSIGNED,      /* no MAC at all */
    MARIE_AUTH_FORGED,        /* MAC does not match (wrong key or altered fields) */
    MARIE_AUTH_REPLAYED,      /* seq not greater than the last accepted from this sender, or
                               * not later than the receiver's start (its epoch) */
    MARIE_AUTH_NOKEY,         /* the receiver has no key: every order is refused */
    MARIE_AUTH_STALE,         /* utime or seq older than the receiver's window */
    MARIE_AUTH_FUTURE,        /* utime or seq further ahead than the allowed clock skew */
} marie_auth_result_t;
const char *marie_auth_result_name(marie_auth_result_t r);

/* Replay protection (threat model and reasoning in docs/managers.md). An order's utime and
 * seq are microseconds of its sender's wall clock; the receiver accepts an authentic order
 * only if both lie in [now - lifetime - max_skew, now + max_skew] by its own clock, its seq is
 * later than the receiver's epoch (its wall clock when the table was created, so nothing
 * captured before a restart is obeyed after it) and greater than the last seq accepted from
 * that sender. Only accepted orders move a sender's mark, so a mark never lies beyond the
 * window: a far-future seq is refused, not remembered. With a path the marks are kept in
 * that file; marks that have left the window are dropped, and so are marks the file holds
 * beyond now + max_skew (written by an older marie, which stored any seq). */
#define MARIE_AUTH_LIFETIME_US 10000000LL   /* default: an order is obeyed within 10 s ... */
#define MARIE_AUTH_MAX_SKEW_US 5000000LL    /* ... plus 5 s either way for the hosts' clocks */
typedef struct marie_replay marie_replay_t;
marie_replay_t *marie_replay_create(const char *path);   /* path NULL: memory only; default window */
/* lifetime_us >= 0, max_skew_us >= 0, or NULL with errno EINVAL. */
marie_replay_t *marie_replay_create_window(const char *path, int64_t lifetime_us, int64_t max_skew_us);
void marie_replay_destroy(marie_replay_t *r);
int64_t marie_replay_last(const marie_replay_t *r, const char *sender);   /* 0 if never seen */
int64_t marie_replay_epoch(const marie_replay_t *r);

/* Check an order's MAC, then its time window and seq against r; only an authentic, fresh
 * order updates r. a NULL gives MARIE_AUTH_NOKEY; r NULL checks the MAC alone. */
marie_auth_result_t marie_auth_check_order(const marie_auth_t *a, marie_replay_t *r, const marie_am_order_t *o);
marie_auth_result_t marie_auth_check_command(const marie_auth_t *a, marie_replay_t *r,
                                             const marie_lifecycle_command_t *c);
/* Parameter changes at run time (marie param set): signed and checked as orders are. */
int marie_auth_sign_param(const marie_auth_t *a, marie_param_request_t *p, uint8_t store[MARIE_AUTH_MAC_LEN]);
marie_auth_result_t marie_auth_check_param(const marie_auth_t *a, marie_replay_t *r, const marie_param_request_t *p);
/* Goals asked for by people (the touch page): signed and checked as orders are. */
int marie_auth_sign_goal_request(const marie_auth_t *a, marie_goal_request_t *g, uint8_t store[MARIE_AUTH_MAC_LEN]);
marie_auth_result_t marie_auth_check_goal_request(const marie_auth_t *a, marie_replay_t *r,
                                                  const marie_goal_request_t *g);

/* Next sequence number for a sender: max(wall clock in us, last + 1), kept in path (locked,
 * so concurrent commands never reuse a number). path NULL: the wall clock alone. A last
 * value beyond now + MARIE_AUTH_MAX_SKEW_US (a clock stepped back, an old file) is no
 * reason to keep counting from it: no receiver would accept it, so the count restarts from
 * the wall clock. */
int64_t marie_auth_next_seq(const char *path);

#ifdef __cplusplus
}
#endif
#endif
