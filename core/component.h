/* component: the Application Adapter runtime: lifecycle, ports, params, heartbeat, events. */
/* Errors follow the one rule (docs/core.md): a call fails with -1, a constructor with NULL, and
 * errno says why; a refused transition also names its reason, and a pull's callback gets the
 * errno value as its status. */
#ifndef MARIE_COMPONENT_H
#define MARIE_COMPONENT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <lcm/lcm.h>

#include "core/config.h"
#include "core/log.h"
#include "core/loop.h"
#include "core/time.h"
#include "lcmtypes/marie_types.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Well-known channels shared by every component and manager. */
#define MARIE_CH_HEARTBEAT       "MARIE_HEARTBEAT"
#define MARIE_CH_LIFECYCLE       "MARIE_LIFECYCLE"
#define MARIE_CH_LIFECYCLE_REPLY "MARIE_LIFECYCLE_REPLY"
#define MARIE_CH_EVENT           "MARIE_EVENT"
#define MARIE_CH_CLOCK           "MARIE_CLOCK"
#define MARIE_CH_PARAM           "MARIE_PARAM"          /* marie param: requests ... */
#define MARIE_CH_PARAM_REPLY     "MARIE_PARAM_REPLY"    /* ... and the components' replies */
/* Pull requests for channel X go to X MARIE_PULL_SUFFIX, served by the Mailbox of X. */
#define MARIE_PULL_SUFFIX        ".PULL"

typedef enum {
    MARIE_STATE_CREATED = 0,
    MARIE_STATE_READY = 1,
    MARIE_STATE_RUNNING = 2,
    MARIE_STATE_PAUSED = 3,
    MARIE_STATE_FAILED = 4,
    MARIE_STATE_EXITED = 5,
    /* Heartbeat only: running, but its device or input has yielded no valid data for a
     * while (marie_component_set_degraded). The lifecycle state stays running. */
    MARIE_STATE_DEGRADED = 6,
} marie_state_t;

typedef enum {
    MARIE_CMD_INIT = 1, MARIE_CMD_START, MARIE_CMD_STOP, MARIE_CMD_PAUSE,
    MARIE_CMD_RESUME, MARIE_CMD_RESTART, MARIE_CMD_ABORT, MARIE_CMD_QUIT,
} marie_cmd_t;

const char *marie_state_name(marie_state_t s);
const char *marie_cmd_name(marie_cmd_t c);
int marie_cmd_parse(const char *name);          /* -1 if unknown */

typedef enum { MARIE_IN = 0, MARIE_OUT } marie_dir_t;
typedef enum {
    MARIE_PUSH = 0,   /* in: every message delivered while running; out: publish */
    MARIE_PULL,       /* in: ask the channel's Mailbox for the newest value on demand */
    MARIE_EVENT,      /* in: queued while not running, never dropped silently; out: counted failures */
} marie_mech_t;

typedef struct marie_component marie_component_t;
typedef struct marie_port marie_port_t;

typedef struct {
    const char *name;
    const marie_type_t *type;   /* &marie_type_laser_scan_t; NULL carries raw payloads */
    marie_dir_t dir;
    marie_mech_t mech;
    const char *channel;        /* default channel; NULL: the config must bind it */
} marie_port_spec_t;

typedef enum {
    MARIE_PARAM_INT, MARIE_PARAM_DOUBLE, MARIE_PARAM_BOOL, MARIE_PARAM_STRING,
    MARIE_PARAM_NODE,           /* any YAML: read with marie_param_node() */
} marie_param_type_t;

typedef struct {
    const char *name;
    marie_param_type_t type;
    const char *def;            /* default as YAML text; NULL: required */
    const char *help;
    size_t offset;              /* with `bound`: where the value goes in the params struct */
    bool bound;
} marie_param_spec_t;

/* A parameter declared once: its name is the field's, its value lands in that field of the
 * component's params struct (def.params_size bytes, read with marie_component_params), and the
 * same entry gives the default, --help and --describe. The field's C type must match:
 *   typedef struct { double rate_hz; const char *label; } hello_params_t;
 *   MARIE_PARAM_AT(hello_params_t, rate_hz, DOUBLE, "10", "rate")
 * int64_t for INT, double for DOUBLE, bool for BOOL, const char * for STRING,
 * const marie_node_t * for NODE. */
#define MARIE_PARAM_CTYPE_INT int64_t
#define MARIE_PARAM_CTYPE_DOUBLE double
#define MARIE_PARAM_CTYPE_BOOL bool
#define MARIE_PARAM_CTYPE_STRING const char *
#define MARIE_PARAM_CTYPE_NODE const marie_node_t *
#ifdef __cplusplus
#define MARIE_PARAM_TYPECHECK_(st, field, T) 0
#else
#define MARIE_PARAM_TYPECHECK_(st, field, T) \
    (sizeof(char[__builtin_types_compatible_p(__typeof__(((st *)0)->field), MARIE_PARAM_CTYPE_##T) ? 1 : -1]) * 0)
#endif
#define MARIE_PARAM_AT(st, field, T, def, help) \
    { #field, MARIE_PARAM_##T, def, help, offsetof(st, field) + MARIE_PARAM_TYPECHECK_(st, field, T), true }
/* The same for a field of a member struct: a library's parameters inside the component's
 * (core/params_gen.py's `members:`), named by the field alone:
 *   MARIE_PARAM_IN(mapper_params_t, slam, resolution, DOUBLE, "0.05", "m per cell") */
#define MARIE_PARAM_IN(st, member, field, T, def, help) \
    { #field, MARIE_PARAM_##T, def, help, \
      offsetof(st, member.field) + MARIE_PARAM_TYPECHECK_(st, member.field, T), true }
/* ... and under another name (a member taken with a prefix: its `bias` is "gyro_bias"). */
#define MARIE_PARAM_IN_AS(st, member, name, field, T, def, help) \
    { name, MARIE_PARAM_##T, def, help, \
      offsetof(st, member.field) + MARIE_PARAM_TYPECHECK_(st, member.field, T), true }

/* What a component is. Hooks return 0, or -1 after marie_component_fail_reason() to refuse
 * the transition (the reply and the heartbeat carry the reason). Any hook may be NULL. */
typedef struct {
    const char *kind;
    const marie_port_spec_t *ports;     /* terminated by an entry with name NULL */
    const marie_param_spec_t *params;   /* terminated by an entry with name NULL */
    size_t params_size;                 /* size of the struct that MARIE_PARAM_AT entries fill */
    int  (*on_init)(marie_component_t *c);     /* created/failed -> ready: read params, allocate */
    int  (*on_start)(marie_component_t *c);    /* ready -> running */
    int  (*on_stop)(marie_component_t *c);     /* running/paused -> ready: outputs safe */
    int  (*on_pause)(marie_component_t *c);
    int  (*on_resume)(marie_component_t *c);
    void (*on_abort)(marie_component_t *c);    /* any -> failed: outputs safe, now */
    void (*on_quit)(marie_component_t *c);     /* free what on_init made */
} marie_component_def_t;

/* Parse the command line and environment, load the configuration, run the component until
 * quit, and return the process exit status: 0 after quit, 2 for configuration errors
 * (printed as file:line:col), 1 for other failures.
 *   --system FILE | MARIE_SYSTEM   system file        --name NAME | MARIE_NAME
 *   --profile P | MARIE_PROFILE                        --url URL   (else system, LCM_DEFAULT_URL)
 *   --param KEY=VALUE   --port PORT=CHANNEL   --clock wall|sim   --hold (wait for init/start) */
int marie_main(const marie_component_def_t *def, int argc, char **argv, void *user);

/* What --help prints: the options, ports and parameters (prog NULL: the kind's name). */
void marie_component_usage(const marie_component_def_t *def, const char *prog, FILE *out);

/* The same in steps, for tests and programs with their own main. NULL on failure with the
 * reasons in errs (exit status 2 for configuration errors). */
marie_component_t *marie_component_create(const marie_component_def_t *def, int argc, char **argv,
                                          void *user, marie_errors_t *errs);
int marie_component_run(marie_component_t *c);          /* until quit; 0, or -1 with errno */
void marie_component_destroy(marie_component_t *c);     /* NULL is a no-op */

/* Drive the lifecycle in-process (the LCM command path uses the same function). Returns 0,
 * or -1 with *reason (static or owned by c) when the transition is refused, and errno
 * ECANCELED (a hook refused it) or EINVAL (not in this state, or an unknown command). */
int marie_component_command(marie_component_t *c, marie_cmd_t cmd, const char **reason);

void *marie_component_user(const marie_component_t *c);
void marie_component_set_user(marie_component_t *c, void *user);
const char *marie_component_name(const marie_component_t *c);
marie_state_t marie_component_state(const marie_component_t *c);
marie_loop_t *marie_component_loop(marie_component_t *c);
lcm_t *marie_component_lcm(marie_component_t *c);      /* the system bus */
/* The max_size of the shared-memory transport the system file gives `channel` (`transports:`),
 * or 0 when the channel is on LCM (or the component has no system file). */
size_t marie_component_shm_max(const marie_component_t *c, const char *channel);
int64_t marie_component_now(const marie_component_t *c);  /* us, on the configured clock */
const marie_component_cfg_t *marie_component_cfg(const marie_component_t *c);  /* NULL standalone */
const marie_system_t *marie_component_system(const marie_component_t *c);      /* NULL standalone */
/* Reason for the refusal a hook is about to return; formatted into the component. */
void marie_component_fail_reason(marie_component_t *c, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

/* Parameters (validated at create: unknown keys and wrong types are config errors). */
int64_t marie_param_int(const marie_component_t *c, const char *name);
double marie_param_double(const marie_component_t *c, const char *name);
bool marie_param_bool(const marie_component_t *c, const char *name);
const char *marie_param_str(const marie_component_t *c, const char *name);
const marie_node_t *marie_param_node(const marie_component_t *c, const char *name);  /* NULL if unset */
/* The params struct that MARIE_PARAM_AT entries filled (def.params_size bytes; NULL if 0). It and
 * its strings live as long as the component. */
const void *marie_component_params(const marie_component_t *c);

/* Parameters changed at run time (`marie param set COMPONENT NAME VALUE`, docs/cli.md): a
 * parameter is dynamic once the component registers a callback for it (in on_init, say). When cb
 * runs, the new value is already in the params struct and marie_param_*(); cb returns -1 after
 * marie_component_fail_reason() to refuse it, and the old value comes back. A set of a parameter
 * without a callback is refused with the reason. 0, or -1 with errno ENOENT (no such parameter). */
typedef int (*marie_param_cb_t)(marie_component_t *c, const char *name);
int marie_component_on_param(marie_component_t *c, const char *name, marie_param_cb_t cb);

/* Ports. marie_port() on an undeclared name is a programmer error (assert). */
typedef struct {
    const char *channel;
    int64_t recv_utime;         /* wall clock at receipt */
    const void *raw;            /* the LCM payload; NULL for a typed port whose channel is on
                                 * shared memory (decoded in place, the bytes are the writer's) */
    size_t raw_len;
} marie_msg_info_t;
typedef void (*marie_msg_cb_t)(marie_component_t *c, marie_port_t *p, const void *msg,
                               const marie_msg_info_t *info);

marie_port_t *marie_port(marie_component_t *c, const char *name);
const char *marie_port_channel(const marie_port_t *p);
const char *marie_port_name(const marie_port_t *p);
/* Encode with the port's type and publish. 0, or -1 with errno (counted as a drop). */
int marie_port_publish(marie_port_t *p, const void *msg);
int marie_port_publish_raw(marie_port_t *p, const void *data, size_t len);
/* A loan, so that a large message is never copied: on a port whose channel the system file puts
 * on shared memory and whose type ends in a byte array after fixed-size fields (image_t's data),
 * room for n bytes of that array straight in the ring. Make the bytes there, point the
 * message's array at the loan (its length at most n), and marie_port_publish() encodes only the
 * fields before it. The loan lasts until the port's next publish, of it or of anything else. NULL
 * with errno ENOTSUP (another transport or type shape) or EMSGSIZE (past the transport's max_size). */
void *marie_port_loan(marie_port_t *p, size_t n);
/* Input handler for a push or event port: gets the decoded message (NULL msg for raw
 * ports: use info->raw). Payloads with the wrong fingerprint or that fail to decode are
 * counted as bad input and dropped. */
int marie_port_on_message(marie_port_t *p, marie_msg_cb_t cb);
/* Pull the newest value of a pull port from its channel's Mailbox, waiting at most
 * timeout_ms (other messages keep being handled meanwhile). Fills msg (free with the
 * type's decode_cleanup) and *age_us. 0, or -1 with errno ETIMEDOUT (no answer), ENODATA (the
 * Mailbox holds nothing yet), ENOENT (the Mailbox knows no such channel), EBADMSG (bad reply;
 * counted) or ECANCELED (the loop quit first). */
int marie_port_pull(marie_port_t *p, void *msg, int timeout_ms, int64_t *age_us);
/* Asynchronous form: cb(status, msg or NULL, age_us) runs from the loop exactly once; status is
 * 0, or the errno value marie_port_pull() would set (a value, as no errno survives the wait). */
typedef void (*marie_pull_cb_t)(marie_component_t *c, marie_port_t *p, int status,
                                const void *msg, int64_t age_us, void *user);
int marie_port_pull_async(marie_port_t *p, int timeout_ms, marie_pull_cb_t cb, void *user);

/* Fixed-rate work that runs only while the component is running; overruns are counted in
 * the heartbeat. The timer lives as long as the component. Asking again for the same callback
 * (an on_init that runs again after a failure) returns the same timer at the new rate. */
typedef void (*marie_tick_cb_t)(marie_component_t *c, int64_t overruns);
marie_timer_t *marie_component_every(marie_component_t *c, double hz, marie_tick_cb_t cb);

/* Counters reported in the heartbeat. */
void marie_component_count(marie_component_t *c, const char *counter, int64_t delta);
int64_t marie_component_counter(const marie_component_t *c, const char *counter);
/* Bad input: counted (heartbeat bad_input and the named counter), logged rate-limited. */
void marie_component_bad_input(marie_component_t *c, const char *counter, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
void marie_component_drop(marie_component_t *c, int64_t n);
/* Traffic a component handles outside its declared ports (adapters on raw channels). */
void marie_component_count_io(marie_component_t *c, int64_t in, int64_t out);

/* Publish an event_t from this component (per-source sequence numbers). */
void marie_component_event(marie_component_t *c, int severity, const char *kind, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
/* Publish a heartbeat now (it also goes out at 1 Hz and on every state change). */
void marie_component_heartbeat(marie_component_t *c);
/* While set and running, the heartbeat says degraded (with the reason) instead of running;
 * a change is published at once. For drivers whose device has gone quiet or talks garbage:
 * the process is alive and obeys orders, but its output cannot be trusted to come. */
void marie_component_set_degraded(marie_component_t *c, bool degraded, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

#ifdef __cplusplus
}
#endif
#endif
