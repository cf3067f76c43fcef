/* config_sched: a component's `sched:` setting (policy, priority, CPUs, spinning) read and written as text. */
#include "core/config.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The names systemd's CPUSchedulingPolicy= and chrt use, in marie_sched_policy_t's order. */
static const char *const policy_names[] = {"other", "fifo", "rr"};

static int read_policy(const marie_node_t *n, marie_sched_cfg_t *s, marie_errors_t *errs)
{
    const char *name;
    if (marie_node_str(n, &name, errs) < 0)
        return -1;
    for (int i = 0; i < 3; i++)
        if (strcmp(name, policy_names[i]) == 0) {
            s->policy = (marie_sched_policy_t)i;
            return 0;
        }
    marie_node_error(errs, n, "sched policy: expected other, fifo or rr, got '%s'", name);
    return -1;
}

static int cmp_int(const void *a, const void *b)
{
    int x = *(const int *)a, y = *(const int *)b;
    return (x > y) - (x < y);
}

/* cpus: one number or a list of them, kept sorted and without repeats. */
static int read_cpus(const marie_node_t *n, marie_sched_cfg_t *s, marie_errors_t *errs)
{
    const marie_node_t *const *items = n->kind == MARIE_NODE_SEQ ? (const marie_node_t *const *)n->items
                                                                 : (const marie_node_t *const *)&n;
    size_t count = n->kind == MARIE_NODE_SEQ ? n->n : 1;
    if (count == 0) {
        marie_node_error(errs, n, "sched cpus: an empty list leaves no CPU to run on");
        return -1;
    }
    if (!(s->cpus = calloc(count, sizeof *s->cpus)))
        return -1;
    for (size_t i = 0; i < count; i++) {
        int64_t v;
        if (marie_node_int(items[i], &v, errs) < 0)
            return -1;
        if (v < 0 || v > MARIE_SCHED_MAX_CPU) {
            marie_node_error(errs, items[i], "sched cpus: CPU %lld is not 0 to %d", (long long)v, MARIE_SCHED_MAX_CPU);
            return -1;
        }
        s->cpus[i] = (int)v;
    }
    qsort(s->cpus, count, sizeof *s->cpus, cmp_int);
    for (size_t i = 0; i < count; i++)
        if (s->ncpus == 0 || s->cpus[s->ncpus - 1] != s->cpus[i])
            s->cpus[s->ncpus++] = s->cpus[i];
    return 0;
}

static int read_spin(const marie_node_t *n, marie_sched_cfg_t *s, marie_errors_t *errs)
{
    int64_t v;
    if (marie_node_int(n, &v, errs) < 0)
        return -1;
    if (v < 0 || v > MARIE_SCHED_MAX_SPIN_US) {
        marie_node_error(errs, n, "sched spin_us: expected 0 to %d microseconds, got %lld", MARIE_SCHED_MAX_SPIN_US,
                         (long long)v);
        return -1;
    }
    s->spin_us = (int)v;
    return 0;
}

static int read_all(const marie_node_t *n, marie_sched_cfg_t *s, marie_errors_t *errs)
{
    static const char *const keys[] = {"policy", "priority", "cpus", "spin_us", NULL};
    if (n->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, n, "sched: expected a mapping such as {policy: fifo, priority: 40}");
        return -1;
    }
    if (marie_node_check_keys(n, keys, "sched", errs) < 0)
        return -1;
    const marie_node_t *pol = marie_node_get(n, "policy"), *pri = marie_node_get(n, "priority"),
                       *cpus = marie_node_get(n, "cpus"), *spin = marie_node_get(n, "spin_us");
    if ((pol && read_policy(pol, s, errs) < 0) || (cpus && read_cpus(cpus, s, errs) < 0) ||
        (spin && read_spin(spin, s, errs) < 0))
        return -1;
    bool real_time = s->policy != MARIE_SCHED_OTHER;
    if (!pri) {
        if (!real_time)
            return 0;
        marie_node_error(errs, pol, "sched: policy %s needs a priority (1 to 99)", policy_names[s->policy]);
        return -1;
    }
    int64_t v;
    if (marie_node_int(pri, &v, errs) < 0)
        return -1;
    if (!real_time) {
        marie_node_error(errs, pri, "sched priority: only policies fifo and rr have one");
        return -1;
    }
    if (v < 1 || v > 99) {
        marie_node_error(errs, pri, "sched priority: expected 1 to 99, got %lld", (long long)v);
        return -1;
    }
    s->priority = (int)v;
    return 0;
}

int marie_sched_cfg_read(const marie_node_t *n, marie_sched_cfg_t *s, marie_errors_t *errs)
{
    *s = (marie_sched_cfg_t){0};
    if (read_all(n, s, errs) == 0)
        return 0;
    marie_sched_cfg_clear(s);
    return -1;
}

void marie_sched_cfg_clear(marie_sched_cfg_t *s)
{
    free(s->cpus);
    *s = (marie_sched_cfg_t){0};
}

bool marie_sched_cfg_any(const marie_sched_cfg_t *s)
{
    return s->policy != MARIE_SCHED_OTHER || s->ncpus > 0 || s->spin_us > 0;
}

const char *marie_sched_cfg_text(const marie_sched_cfg_t *s, char *out, size_t size)
{
    size_t len = 0;
    out[0] = 0;
    if (!marie_sched_cfg_any(s))
        return out;
    len += (size_t)snprintf(out, size, "%s", policy_names[s->policy]);
    if (s->policy != MARIE_SCHED_OTHER && len < size)
        len += (size_t)snprintf(out + len, size - len, " %d", s->priority);
    for (size_t i = 0; i < s->ncpus && len < size; i++)
        len += (size_t)snprintf(out + len, size - len, "%s%d", i ? "," : " cpus ", s->cpus[i]);
    if (s->spin_us && len < size)
        snprintf(out + len, size - len, " spin %d us", s->spin_us);
    return out;
}
