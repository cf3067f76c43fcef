/* The marie command line's own parts, shared between its files (not a library interface): the
 * state of one run, the bus helpers, and one function per command. */
#ifndef MARIE_MANAGERS_MARIE_CLI_H
#define MARIE_MANAGERS_MARIE_CLI_H

#include <signal.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#include <lcm/lcm.h>

#include "core/auth.h"
#include "core/loop.h"
#include "proto/am_proto.h"

#define MAX_HOSTS 64

typedef struct {
    char name[128];
    marie_am_status_t *st;      /* latest, owned */
    int64_t recv_wall;          /* local wall clock at receipt */
    int64_t recv_mono;
    bool fresh;                 /* received after this host's reply to the order */
} host_t;

typedef struct {
    char host[128];
    bool ok;
    char reason[1024];
    int affected;
} reply_rec_t;

typedef struct {
    lcm_t *lcm;
    marie_loop_t *loop;         /* waits: the bus is one of its fds */
    const char *url;
    bool json;
    double timeout_s;
    const char *key_override;
    marie_auth_t *auth;
    char sender[256];
    /* expected hosts (from the system file or the first reply) */
    char expect[MAX_HOSTS][128];
    int nexpect;
    /* the order in flight */
    int64_t seq;
    reply_rec_t replies[MAX_HOSTS];
    int nreplies;
    /* status */
    host_t hosts[MAX_HOSTS];
    int nhosts;
    int64_t new_host_mono;      /* when a host was first heard, last */
    bool hosts_unnamed;         /* a heard manager names no hosts (it has no system) */
    /* logs */
    char **log_names;           /* marie logs: the components and groups asked for (argv) */
    int nlog_names;
    char (*followed)[128];      /* -f: the components they name (groups resolved from status) */
    int nfollowed;
    int64_t last_log_mono;
    bool follow;
} cli_t;

/* The signal that asked marie to stop (0: none); long waits give up when it is set. */
extern volatile sig_atomic_t interrupted;
/* Exit status of a command cut short: 130 for SIGINT as a shell reports it, 1 for SIGTERM
 * (told to stop: the command failed). */
int interrupted_status(void);

/* marie_bus.c: the bus, orders and replies */
host_t *host_get(cli_t *cli, const char *name, bool create);
void expect_host(cli_t *cli, const char *name);
bool all_replied(cli_t *cli);
/* Handle bus traffic for up to `seconds`, or until done(cli) holds; false if it did not. */
bool pump(cli_t *cli, double seconds, bool (*done)(cli_t *));
int cli_open(cli_t *cli);
int load_key(cli_t *cli);
int send_order(cli_t *cli, int op, char **targets, int ntargets, const char *arg,
               const char *path, const char *text);
void print_replies_json(cli_t *cli, int rc);
/* Ask every manager for its status now (marie ps). 0 or -1. */
int request_status(cli_t *cli);
/* pump()'s `done` after request_status(): every host the managers' status names has answered
 * (and, while a manager names none, no new one for 150 ms). */
bool all_hosts_heard(cli_t *cli);
int wait_states(cli_t *cli, char **targets, int ntargets, bool running, double timeout);

/* One per command (marie_cmds.c, marie_doctor.c); each returns the exit status. */
int cmd_up(cli_t *cli, int argc, char **argv);
int cmd_simple(cli_t *cli, int op, int argc, char **argv);
int cmd_move(cli_t *cli, int argc, char **argv);
int cmd_ps(cli_t *cli, int argc, char **argv);
int cmd_logs(cli_t *cli, int argc, char **argv);
int cmd_doctor(cli_t *cli, int argc, char **argv);
int cmd_hash(cli_t *cli, int argc, char **argv);

#endif
