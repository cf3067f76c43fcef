/* balance: which manager decides, and where movable components should run (pure: events in,
 * moves out; marie-am does the I/O). The rules are in docs/managers.md, "Automatic placement". */
#ifndef MARIE_BALANCE_H
#define MARIE_BALANCE_H

#include <stdbool.h>
#include <stdint.h>

#include "core/config.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct balance balance_t;

/* The system file's `balance:` section (docs/managers.md). Lists stay nodes of the system's
 * document: the settings live as long as the system. */
typedef struct {
    bool enabled;                   /* the section is present */
    double window_s;                /* load is averaged over this long before a decision */
    double high, low;               /* overloaded above high x cores; a target must stay under low */
    double cooldown_s;              /* no second move this soon, and none of a component moved last */
    double host_lost_s;             /* a manager unheard this long is lost: failover */
    const marie_node_t *movable;    /* list of component names; every other component is pinned */
    const marie_node_t *capacity;   /* host: cores (default: what its manager reports) */
    const marie_node_t *prefer;     /* component: [hosts], best first */
} balance_cfg_t;

/* Reads and checks the section (defaults when absent): 0, or -1 with file:line:col in errs. */
int balance_read_cfg(const marie_system_t *sys, balance_cfg_t *cfg, marie_errors_t *errs);

typedef enum {
    BALANCE_OVERLOAD = 1,   /* a host above `high` over the window: a component leaves it */
    BALANCE_FAILOVER,       /* a host lost: its movable components start elsewhere */
    BALANCE_DUPLICATE,      /* running on two hosts (a healed partition): one placement wins */
} balance_why_t;

typedef struct {
    balance_why_t why;
    char component[128];
    char from[128];         /* where it was placed (or also running, for DUPLICATE) */
    char to[128];
    char reason[640];       /* one sentence for the event, ps and the viewer: room for four names whole */
} balance_move_t;

/* A balancer for the manager of host `self` over the system's hosts and components. NULL with
 * errno on failure. The system (and cfg) must outlive it. */
balance_t *balance_create(const char *self, const marie_system_t *sys, const balance_cfg_t *cfg);
void balance_destroy(balance_t *b);

/* A manager's status was heard: its term, whether it says it leads, its cores (0: unknown). */
void balance_heard(balance_t *b, const char *host, int64_t term, bool leads, int ncpu, int64_t now_us);
/* One component in that status: CPU % of one core over the last period, and whether it runs. */
void balance_sample(balance_t *b, const char *host, const char *component, double cpu, bool running,
                    int64_t now_us);
/* A move was applied (by any order: the balancer's or a user's `marie move`). */
void balance_placed(balance_t *b, const char *component, const char *host, int64_t now_us);

/* Decides (only when this manager leads and has settled): at most one move per call, and
 * failovers before duplicates before overloads. 1 with *out filled, 0 when nothing to do. */
int balance_step(balance_t *b, int64_t now_us, balance_move_t *out);

/* The manager every live manager agrees leads now (the smallest live name), this manager's
 * term (announced in its status), and whether it may act. */
const char *balance_leader(balance_t *b, int64_t now_us);
int64_t balance_term(const balance_t *b);
bool balance_leads(const balance_t *b);        /* it claims the lead (acting or settling) */
bool balance_acting(balance_t *b, int64_t now_us);
/* Where the balancer believes a component is placed (NULL: unknown name). */
const char *balance_placement(const balance_t *b, const char *component);
/* A host's load over the window as a fraction of its cores; -1 until the window is covered. */

#ifdef __cplusplus
}
#endif
#endif
