/* The component runtime's own parts, shared by core/component*.c (not for components): the
 * component and port structures and the functions each file offers the others. */
#ifndef MARIE_CORE_COMPONENT_PRIV_H
#define MARIE_CORE_COMPONENT_PRIV_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#include <lcm/lcm.h>

#include "core/auth.h"
#include "core/component.h"
#include "core/bus/bus.h"
#include "core/spec.h"
#include "core/typeinfo.h"

#define EVENT_QUEUE_MAX 256

typedef struct {
    int64_t request_id;
    marie_port_t *port;
    marie_timer_t *timeout;
    marie_pull_cb_t cb;         /* NULL for a blocking pull */
    void *user;
    /* blocking pull result */
    void *msg;
    int64_t age_us;
    int status;
    int done;
} pull_t;

typedef struct {
    void *data;
    size_t len;
    int64_t recv_utime;
} queued_t;

struct marie_port {
    marie_component_t *c;
    const marie_port_spec_t *spec;
    char *channel;
    lcm_t *lcm;
    marie_bus_sub_t *sub;
    marie_msg_cb_t cb;
    void *scratch;              /* decoded message */
    uint8_t *buf;               /* encode buffer */
    size_t bufcap;
    queued_t *queue;            /* event port: held while not running */
    size_t nqueue;
    int64_t msgs;               /* delivered (in) or published (out), for the heartbeat */
    const marie_transport_cfg_t *shm;   /* the system file moves the channel to this host's memory */
    marie_bus_sub_stats_t counted;      /* the subscription's losses already in the counters */
    bool loanable;              /* a shared-memory output whose type has a tail (below) */
    marie_tail_t tail;          /* where that byte array lies (the type's shape) */
    uint8_t *loan;              /* marie_port_loan(): the array's bytes in the ring, until a publish */
    size_t loan_cap;
    struct {                    /* a message read in place, until the ring's verdict */
        bool decoded, queued;
        int viewed;             /* marie_decode_view(): the tail points into the held slot */
        const void *data;       /* the held slot's bytes, or NULL */
        const char *why;        /* why it did not decode */
        size_t len;
        int64_t at;             /* when the ring gave it (wall clock, us) */
    } peek;
};

typedef struct {
    const marie_param_spec_t *spec;
    const marie_node_t *node;
    int64_t i;
    double d;
    bool b;
    const char *s;
    char *expanded;             /* s after ${VAR} expansion, when it differed */
    marie_param_cb_t on_change; /* set: the parameter is dynamic (marie param set) */
} param_t;

typedef struct {
    char *name;
    int64_t value;
} counter_t;

typedef struct {
    marie_component_t *c;
    marie_tick_cb_t cb;
    marie_timer_t *timer;
} tick_t;

typedef struct {
    char *url;
    lcm_t *lcm;
    marie_bus_stats_t counted;  /* what the heartbeat has reported of marie_bus_stats() */
} bus_t;

struct marie_component {
    const marie_component_def_t *def;
    void *user;
    char *name;
    char host[64];
    marie_system_t *sys;
    const marie_component_cfg_t *cfg;
    void *params_struct;        /* def->params_size bytes, filled from MARIE_PARAM_AT entries */
    marie_doc_t **docs;         /* defaults and --param values */
    size_t ndocs;
    param_t *params;
    size_t nparams;
    marie_port_t *ports;
    size_t nports;
    bus_t *buses;               /* buses[0] is the system bus */
    size_t nbuses;
    marie_loop_t *loop;
    marie_state_t state;
    bool initialised;           /* on_init succeeded and on_quit has not run */
    bool hold;
    char reason[400];
    char fail_reason[256];
    bool degraded;              /* heartbeat says degraded while running */
    char degraded_reason[256];
    int64_t start_mono;
    int64_t msgs_in, msgs_out, drops, bad_input, overruns;
    counter_t *counters;
    size_t ncounters;
    int64_t hb_seq, event_seq;
    tick_t **ticks;
    size_t nticks;
    pull_t **pulls;
    size_t npulls;
    int64_t next_request_id;
    char reply_channel[128];
    bool reply_subscribed;
    marie_auth_t *auth;         /* set: only signed, fresh lifecycle orders are obeyed */
    marie_replay_t *replay;
};

/* The command line of a component, as parsed. */
typedef struct {
    const char *system, *name, *profile, *url, *clock;
    char **params;   /* KEY=VALUE */
    size_t nparams;
    char **ports;    /* PORT=CHANNEL */
    size_t nports;
    bool hold;
} options_t;

/* component_port.c */
/* Deliver what event ports held while the component was not running. */
void marie_comp_flush_events(marie_component_t *c);
/* The LCM instance for url (NULL: the system bus), created on first use; NULL on failure. */
lcm_t *marie_comp_bus_for(marie_component_t *c, const char *url);
int marie_comp_bind_ports(marie_component_t *c, const options_t *o, marie_errors_t *errs);
/* Add the shared-memory readers' losses since the last call to the counters; and the buses'
 * receivers' (datagrams that are not LCM's as bad input, kernel drops and messages given up
 * with fragments missing as drops). */
void marie_comp_count_shm_losses(marie_component_t *c);
void marie_comp_count_bus_losses(marie_component_t *c);
/* Close what a port opened (its subscription); the port's strings and buffers stay. */
void marie_comp_port_close(marie_port_t *p);

/* component_params.c */
int marie_comp_parse_options(const marie_component_def_t *def, int argc, char **argv, options_t *o, marie_errors_t *errs);
int marie_comp_bind_params(marie_component_t *c, const options_t *o, marie_errors_t *errs);
int marie_comp_fill_params(marie_component_t *c);
/* MARIE_PARAM: list, get and set parameters at run time (marie param). */
void marie_comp_on_param_request(const lcm_recv_buf_t *rbuf, const char *channel, void *user);

#endif
