/* am_proto: the managers' wire protocol as their clients see it (libmarie_proto): channels,
 * order names, exit codes, the key file, and signed orders sent. marie-am, the marie command
 * line and the tools (viewer, face, log, map) include it; nothing in it knows marie-am's state. */
#ifndef MARIE_PROTO_AM_PROTO_H
#define MARIE_PROTO_AM_PROTO_H

#include <stddef.h>
#include <stdint.h>

#include "lcmtypes/marie_am_order_t.h"
#include "lcmtypes/marie_am_reply_t.h"
#include "lcmtypes/marie_am_status_request_t.h"
#include "lcmtypes/marie_am_status_t.h"
#include "lcmtypes/marie_log_line_t.h"

#ifdef __cplusplus
extern "C" {
#endif

#define MARIE_CH_AM_ORDER  "MARIE_AM_ORDER"
#define MARIE_CH_AM_REPLY  "MARIE_AM_REPLY"
#define MARIE_CH_AM_STATUS "MARIE_AM_STATUS"
#define MARIE_CH_AM_STATUS_REQUEST "MARIE_AM_STATUS_REQUEST"
#define MARIE_CH_LOG       "MARIE_LOG"

/* The most of a system file read to send or load (the loader, core/yaml.c, refuses more). */
#define MARIE_AM_SYSTEM_MAX_BYTES (16 << 20)

/* Exit codes of the marie command line (documented in docs/managers.md). */
enum {
    MARIE_EXIT_OK = 0,
    MARIE_EXIT_FAIL = 1,        /* refused order, failed component, doctor found a problem */
    MARIE_EXIT_USAGE = 2,       /* bad command line or system file */
    MARIE_EXIT_TIMEOUT = 3,     /* a manager did not answer, a host is lost, a wait timed out */
    MARIE_EXIT_AUTH = 4,        /* no usable key file, or an order refused as unauthenticated */
};

const char *marie_am_op_name(int op);
int marie_am_op_parse(const char *name);        /* -1 if unknown */

/* Key file: MARIE_KEY, else /etc/marie/key. */
const char *marie_am_key_path(const char *override);
/* "user@host" for order senders. */
void marie_am_sender(char *buf, size_t len);

#ifdef __cplusplus
}
#endif

#include "core/config.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Send an order as a client (marie, the log viewer): fills utime, sender ("user@host") and
 * seq (marie_auth_next_seq over seq_file, which may be NULL), signs with auth and publishes
 * on MARIE_CH_AM_ORDER. Answers come as marie_am_reply_t on MARIE_CH_AM_REPLY carrying the
 * same sender and seq. 0, or -1 with errno. */
typedef struct marie_auth marie_auth_t;
typedef struct _lcm_t lcm_t;
int marie_am_send_order(lcm_t *lcm, const marie_auth_t *auth, marie_am_order_t *o, char *sender_buf,
                        size_t sender_len, const char *seq_file);
/* The same under a given sender name (a manager's own orders: "balance@HOST"). */
int marie_am_send_order_as(lcm_t *lcm, const marie_auth_t *auth, marie_am_order_t *o, const char *sender,
                           const char *seq_file);

/* The host a component runs on: its `host`, else the first of `hosts`, else `fallback`. */
const char *marie_am_component_host(const marie_system_t *sys, const marie_component_cfg_t *c, const char *fallback);

#ifdef __cplusplus
}
#endif
#endif
