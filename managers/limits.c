/* limits: whether a component breaks its limits, from samples of its use (no I/O here). */
#include "managers/limits.h"

#include <stdio.h>

static marie_limit_kind_t memory(const marie_limits_cfg_t *cfg, bool cgroup, const marie_limit_watch_t *w,
                                 const marie_limit_sample_t *s, char *why, size_t len)
{
    double mb = (double)cfg->memory / (1 << 20);
    if (cgroup && s->oom_kills > w->first.oom_kills && w->first.oom_kills >= 0) {
        snprintf(why, len, "memory: the kernel killed it at its limit of %.0f MB (cgroup memory.max)", mb);
        return MARIE_LIMIT_MEMORY;
    }
    if (!cgroup && s->rss > cfg->memory) {
        snprintf(why, len, "memory: %.0f MB resident, over its limit of %.0f MB", (double)s->rss / (1 << 20), mb);
        return MARIE_LIMIT_MEMORY;
    }
    return MARIE_LIMIT_NONE;
}

/* Over a whole window: more than its cores (watched), or throttled a good part of it (cgroup). */
static marie_limit_kind_t cpu(const marie_limits_cfg_t *cfg, bool cgroup, marie_limit_watch_t *w,
                              const marie_limit_sample_t *s, char *why, size_t len)
{
    int64_t span = s->t_us - w->window.t_us;
    if (span < MARIE_LIMITS_CPU_WINDOW_US)
        return MARIE_LIMIT_NONE;
    marie_limit_sample_t from = w->window;
    w->window = *s;
    if (cgroup && from.throttled_us >= 0 && s->throttled_us >= 0) {
        double f = (double)(s->throttled_us - from.throttled_us) / (double)span;
        if (f < MARIE_LIMITS_THROTTLED_FRACTION)
            return MARIE_LIMIT_NONE;
        snprintf(why, len, "cpu: held to its limit of %g core for %.0f%% of %.0f s (cgroup cpu.max)", cfg->cpu,
                 100 * f, span * 1e-6);
        return MARIE_LIMIT_CPU;
    }
    double cores = (double)(s->cpu_us - from.cpu_us) / (double)span;
    if (cgroup || from.cpu_us < 0 || cores <= cfg->cpu)
        return MARIE_LIMIT_NONE;
    snprintf(why, len, "cpu: %.2f core over %.0f s, over its limit of %g", cores, span * 1e-6, cfg->cpu);
    return MARIE_LIMIT_CPU;
}

void marie_limits_start(marie_limit_watch_t *w, const marie_limit_sample_t *s)
{
    *w = (marie_limit_watch_t){.started = true, .first = *s, .window = *s};
}

marie_limit_kind_t marie_limits_check(const marie_limits_cfg_t *cfg, bool cgroup, marie_limit_watch_t *w,
                                      const marie_limit_sample_t *s, char *why, size_t len)
{
    if (!w->started)
        marie_limits_start(w, s);
    marie_limit_kind_t k = MARIE_LIMIT_NONE;
    if (cfg->memory > 0)
        k = memory(cfg, cgroup, w, s, why, len);
    if (!k && cfg->cpu > 0)
        k = cpu(cfg, cgroup, w, s, why, len);
    if (!k && cfg->nofile > 0 && s->nfiles >= cfg->nofile) {
        snprintf(why, len, "nofile: %lld files open, its limit (the next open fails)", (long long)s->nfiles);
        k = MARIE_LIMIT_NOFILE;
    }
    return k;
}
