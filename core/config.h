/* config: YAML documents as a tree with file:line:col on every node, and the system file model. */
#ifndef MARIE_CONFIG_H
#define MARIE_CONFIG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "core/loop.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- error list: every message is "file:line:col: text" ---- */
typedef struct marie_errors {
    char **msgs;
    size_t n;
} marie_errors_t;

void marie_errors_add(marie_errors_t *e, const char *file, int line, int col, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
void marie_errors_print(const marie_errors_t *e, FILE *out);
void marie_errors_clear(marie_errors_t *e);     /* frees the messages, keeps e usable */

/* ---- YAML tree ---- */
typedef enum { MARIE_NODE_SCALAR, MARIE_NODE_SEQ, MARIE_NODE_MAP } marie_node_kind_t;

typedef struct marie_node marie_node_t;
struct marie_node {
    marie_node_kind_t kind;
    const char *file;
    int line, col;              /* 1-based, of the node's value */
    char *key;                  /* the key when this node is a map value, else NULL */
    int key_line, key_col;
    char *value;                /* scalars only */
    bool quoted;                /* a quoted scalar is always a string */
    marie_node_t **items;       /* seq items or map values, in document order */
    size_t n;
    size_t *index, index_cap;   /* private: key lookup of long maps (positions + 1) */
};

typedef struct marie_doc marie_doc_t;

/* Parse a YAML file (or a string; `name` is used in messages). NULL on failure, with the
 * reasons in errs. The doc owns every node; marie_doc_destroy(NULL) is a no-op. */
marie_doc_t *marie_doc_load(const char *path, marie_errors_t *errs);
marie_doc_t *marie_doc_parse(const char *name, const char *text, size_t len, marie_errors_t *errs);
void marie_doc_destroy(marie_doc_t *doc);
/* The YAML library is opened by the first parse and stays open until this call (unless a
 * parse is under way in another thread); the next parse opens it again. A long-running
 * process calls it once its YAML is read (components do after starting) so the library's
 * pages are not resident for the rest of its life. */
void marie_yaml_unload(void);
/* A program that wants long parses to end on a signal registers a check (nonzero: stop);
 * the parser calls it every few thousand keys and fails with "interrupted" and errno EINTR. */
void marie_config_set_interrupt(int (*check)(void));
const marie_node_t *marie_doc_root(const marie_doc_t *doc);

/* Adds "file:line:col: text" at the node's value. */
void marie_node_error(marie_errors_t *e, const marie_node_t *n, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
const marie_node_t *marie_node_get(const marie_node_t *map, const char *key);   /* NULL if absent */
/* Typed reads of a scalar; on a wrong type they add "file:line:col: KEY: expected T, got 'v'" and return -1. */
int marie_node_int(const marie_node_t *n, int64_t *out, marie_errors_t *errs);
int marie_node_double(const marie_node_t *n, double *out, marie_errors_t *errs);
int marie_node_bool(const marie_node_t *n, bool *out, marie_errors_t *errs);
int marie_node_str(const marie_node_t *n, const char **out, marie_errors_t *errs);
/* Every key of `map` must be one of `allowed` (NULL-terminated); each other key is an error. */
int marie_node_check_keys(const marie_node_t *map, const char *const *allowed, const char *what, marie_errors_t *errs);
/* Canonical text of a node (keys sorted), used for the configuration hash. Caller frees. */
char *marie_node_canonical(const marie_node_t *n);

/* ---- system file ---- */
typedef enum { MARIE_RESTART_ON_FAILURE = 0, MARIE_RESTART_ALWAYS, MARIE_RESTART_NEVER } marie_restart_kind_t;

typedef struct {
    marie_restart_kind_t policy;
    double backoff_min_s, backoff_max_s;   /* delay doubles from min to max */
    double stable_s;                       /* a run this long resets the backoff */
    int max_failures;                      /* give up after this many failures ... */
    double window_s;                       /* ... within this window */
} marie_restart_cfg_t;

/* `sched:` of a component: how the kernel is to schedule it, given by marie-am when it starts
 * it (docs/system-file.md). The zero value asks for nothing: the manager's own scheduling. */
typedef enum { MARIE_SCHED_OTHER = 0, MARIE_SCHED_FIFO, MARIE_SCHED_RR } marie_sched_policy_t;

typedef struct {
    marie_sched_policy_t policy;    /* OTHER: the normal time-sharing policy */
    int priority;                   /* 1-99 with FIFO and RR, else 0 */
    int *cpus; size_t ncpus;        /* the CPUs it may run on, ascending; none: the manager's */
    int spin_us;                    /* the component's loop spins this long after work (0: never;
                                     * applied by the component itself, marie_loop_set_spin) */
} marie_sched_cfg_t;

#define MARIE_SCHED_MAX_SPIN_US 10000

#define MARIE_SCHED_MAX_CPU 1023    /* the highest CPU number a cpu_set_t holds */

/* `limits:` of a component: what marie-am holds it to (docs/managers.md, "Resource limits"). The
 * zero value asks for nothing. */
typedef enum { MARIE_BREACH_RESTART = 0, MARIE_BREACH_STOP } marie_breach_t;

typedef struct {
    int64_t memory;             /* bytes; 0: none */
    double cpu;                 /* cores; 0: none */
    int64_t nofile;             /* open files; 0: none */
    marie_breach_t on_breach;   /* what a breach does to it */
} marie_limits_cfg_t;

typedef struct {
    char *name;                 /* the component's port name */
    char *channel;
    char *url;                  /* NULL: the system's URL */
    int line, col;
} marie_port_binding_t;

typedef struct {
    char *name;
    char *exec;
    char **args; size_t nargs;
    char **env; size_t nenv;    /* "KEY=value" */
    bool shell;                 /* run exec through /bin/sh -c (only when the file asks) */
    char *host;
    char *group;
    marie_port_binding_t *ports; size_t nports;
    const marie_node_t *params; /* a map node, or NULL */
    marie_node_t *params_merged;/* private: params with a profile's `params:` over them (owned) */
    marie_restart_cfg_t restart;
    double stop_timeout_s;      /* stop signal, then SIGKILL after this */
    double heartbeat_timeout_s; /* not responding after this long without a heartbeat */
    marie_sched_cfg_t sched;    /* effective: nothing on the simulator's clock (then sched_sim) */
    bool sched_sim;             /* the file asks for a sched that the simulator's clock leaves out */
    marie_limits_cfg_t limits;  /* resources it may use */
    char **depends; size_t ndepends;
    char hash_[65];             /* private: marie_component_hash()'s text, "" until asked */
    const struct marie_system *sys_; /* private: the system it belongs to */
    const marie_node_t *node;   /* its entry in the file */
    const char *file; int line, col;
} marie_component_cfg_t;

/* `transports:` in the system file: how a channel's messages travel between ports. */
typedef struct {
    char *channel;
    char kind[8];               /* a provider's name (core/bus/bus.h): "shm" (same-host shared
                                   memory, notices on LCM), "local" (same-host fast path); "lcm" */
    bool shm;                   /* kind is not lcm: the channel's messages are on this host's memory */
    size_t max_size;            /* bytes the largest message may take (shm) */
    int slots;                  /* messages the ring holds (shm) */
    int line, col;
} marie_transport_cfg_t;

typedef struct marie_system {
    char *file;
    char *name;
    char *profile;              /* NULL: none applied */
    char *lcm_url;
    marie_clock_kind_t clock;
    char *key_file;             /* order authentication key, or NULL */
    char **hosts; size_t nhosts;
    char **types; size_t ntypes;  /* `types:`: what marie-types-gen made (directories or .so files,
                                     relative to the system file's directory) */
    const marie_node_t *robot;  /* `robot:` (the profile's when it has one): a component parameter
                                   robot_KEY not set in its entry takes robot.KEY; NULL: none */
    marie_transport_cfg_t *transports; size_t ntransports;
    const marie_node_t *ros2;   /* `ros2:` (a mapping): which channels marie-ros2 bridges to which
                                   ROS 2 topics (docs/ros2.md); NULL: none */
    marie_component_cfg_t *components; size_t ncomponents;
    marie_component_cfg_t **by_name;   /* private: sorted by name for lookups */
    marie_doc_t *doc;
} marie_system_t;

/* Load and validate a system file, applying `profile` (NULL: none): a profile's components
 * replace or add whole components by name. Dependency cycles are errors. On any error returns NULL with every problem
 * in errs; nothing is half-applied. */
marie_system_t *marie_system_load(const char *path, const char *profile, marie_errors_t *errs);
/* The same from text already in memory (the file's text with launch arguments filled in, marie up
 * -a); path names it in messages and is where its relative paths start. */
marie_system_t *marie_system_load_text(const char *path, const char *text, size_t len, const char *profile,
                                       marie_errors_t *errs);
/* One component's part of a loaded file, for the process that runs it (marie-am passes it in
 * MARIE_SYSTEM_ENTRY; core/config_entry.c): the lines of the file's `components:` mapping and
 * of the entry `name`, and text_hash (marie_text_hash of the file's text), in out. -1 where the
 * file's layout does not allow it (a flow mapping, entries sharing a line). */
int marie_system_entry_spec(const marie_system_t *sys, const char *name, uint64_t text_hash, char *out,
                            size_t size);
uint64_t marie_text_hash(const void *text, size_t len);
/* The file at path (named origin in messages when not NULL) read for the component `name`
 * alone, with a spec from marie_system_entry_spec: the other entries' lines emptied (so lines
 * and columns stay those of the file), then loaded as marie_system_load_text without the other
 * entries or checks about them. NULL, reporting nothing, where the spec does not fit the text
 * (the file changed since) or what is left does not load: then read the whole file. */
marie_system_t *marie_system_load_entry(const char *path, const char *origin, const char *profile, const char *name,
                                        const char *spec);
void marie_system_destroy(marie_system_t *sys);
const marie_component_cfg_t *marie_system_component(const marie_system_t *sys, const char *name);

/* The sha256 (64 hex digits) of a component's effective configuration: every setting that
 * changes how it runs, inherited ones (defaults, the system's clock, bus, transports and key)
 * resolved. Made when first asked (the managers ask; a component reading its own entry never
 * does) and kept with the entry. */
const char *marie_component_hash(const marie_component_cfg_t *c);
/* Register the users' types named by MARIE_TYPES_PATH and the file's `types:` (core/typeinfo.h,
 * marie_types_load); sys may be NULL (the environment only). 0, or -1 with file:line:col in errs. */
int marie_system_load_types(const marie_system_t *sys, marie_errors_t *errs);
/* The transport the file sets for `channel`, or NULL (plain LCM). */
const marie_transport_cfg_t *marie_system_transport(const marie_system_t *sys, const char *channel);
/* Which settings of two components' effective configurations differ, as "clock,params"
 * ("" when none). Caller frees; NULL when out of memory. */
char *marie_component_differences(const marie_system_t *sa, const marie_component_cfg_t *a,
                                  const marie_system_t *sb, const marie_component_cfg_t *b);

/* ---- transports (core/config_transport.c) ---- */
/* Reads `transports:` (NULL: none) into sys->transports; errors at the entry's file:line:col. */
int marie_transports_read(const marie_node_t *n, marie_system_t *sys, marie_errors_t *errs);

/* ---- sched (core/config_sched.c) ---- */
/* Reads a `sched:` mapping ({policy, priority, cpus, spin_us}) into s, which then owns its cpus
 * (marie_sched_cfg_clear). -1 with "file:line:col: ..." in errs; s is then empty. */
int marie_sched_cfg_read(const marie_node_t *n, marie_sched_cfg_t *s, marie_errors_t *errs);
void marie_sched_cfg_clear(marie_sched_cfg_t *s);
/* Whether s asks for anything (a policy or CPUs). */
bool marie_sched_cfg_any(const marie_sched_cfg_t *s);
/* s as the file would say it, "fifo 44", "other cpus 1,3", "" when it asks for nothing: the
 * configuration hash's text and the words of messages. Returns out (cut to size). */
const char *marie_sched_cfg_text(const marie_sched_cfg_t *s, char *out, size_t size);

/* ---- limits (core/config_limits.c) ---- */
/* Reads a `limits:` mapping ({memory: 256M, cpu: 0.5, nofile: 256, on_breach: restart|stop}).
 * -1 with "file:line:col: ..." in errs; l is then empty. */
int marie_limits_cfg_read(const marie_node_t *n, marie_limits_cfg_t *l, marie_errors_t *errs);
bool marie_limits_cfg_any(const marie_limits_cfg_t *l);
/* "memory 256M cpu 0.5 nofile 256" (and " on_breach stop"), "" for none: the configuration
 * hash's text and what marie ps shows. Returns out. */
const char *marie_limits_cfg_text(const marie_limits_cfg_t *l, char *out, size_t size);

/* The default bus URL: LCM_DEFAULT_URL if set, else marie's (ttl=0, 8 MB receive buffer). */
const char *marie_default_url(void);
#define MARIE_DEFAULT_URL "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"

#ifdef __cplusplus
}
#endif
#endif
