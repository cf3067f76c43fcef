/* limits: whether a component breaks its `limits:` (memory, cpu, nofile), from samples of its
 * use: a pure decision, as supervise.c is; marie-am takes the samples and acts (am_limits.c). */
#ifndef MARIE_MANAGERS_LIMITS_H
#define MARIE_MANAGERS_LIMITS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/config.h"

#ifdef __cplusplus
extern "C" {
#endif

/* CPU use is judged over windows this long: a burst is not a breach. */
#define MARIE_LIMITS_CPU_WINDOW_US 5000000
/* In a cgroup the kernel holds CPU use to the limit: a component throttled for this fraction of
 * a window wants more than its share. */
#define MARIE_LIMITS_THROTTLED_FRACTION 0.25

typedef enum { MARIE_LIMIT_NONE = 0, MARIE_LIMIT_MEMORY, MARIE_LIMIT_CPU, MARIE_LIMIT_NOFILE } marie_limit_kind_t;

/* One look at a running component; -1 for what was not read. */
typedef struct {
    int64_t t_us;               /* monotonic */
    int64_t rss;                /* bytes resident */
    int64_t cpu_us;             /* CPU time used since it started */
    int64_t nfiles;             /* open descriptors */
    int64_t oom_kills;          /* its cgroup's memory.events oom_kill */
    int64_t throttled_us;       /* its cgroup's cpu.stat throttled_usec */
} marie_limit_sample_t;

/* What one instance's samples so far say (zeroed at each start). */
typedef struct {
    bool started;
    marie_limit_sample_t first;     /* of this instance */
    marie_limit_sample_t window;    /* the start of the current CPU window */
} marie_limit_watch_t;

/* A new instance: s (taken before it ran) is what its counters are measured from. */
void marie_limits_start(marie_limit_watch_t *w, const marie_limit_sample_t *s);

/* The first limit s shows broken, with "memory: 270 MB resident, over its limit of 256 MB" in
 * why; MARIE_LIMIT_NONE when none. cgroup: the kernel enforces memory and CPU (breaches are its
 * kills and throttling), else they are judged from rss and cpu_us. */
marie_limit_kind_t marie_limits_check(const marie_limits_cfg_t *cfg, bool cgroup, marie_limit_watch_t *w,
                                      const marie_limit_sample_t *s, char *why, size_t len);


#ifdef __cplusplus
}
#endif
#endif
