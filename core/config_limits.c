/* config_limits: a component's `limits:` (memory, cpu, nofile, on_breach) read and written as text. */
#include "core/config.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* "256M", "1.5G", "65536", "512KiB": bytes; -1 when the text is none of these. */
static int64_t parse_bytes(const char *s)
{
    char *end;
    double v = strtod(s, &end);
    static const char *const units[] = {"", "K", "M", "G", "T"};
    if (end == s || !(v >= 0))
        return -1;
    for (int i = 0; i < 5; i++) {
        size_t n = strlen(units[i]);
        if (strncmp(end, units[i], n) != 0)
            continue;
        const char *rest = end + n;
        if (*rest == 0 || (i > 0 && (strcmp(rest, "iB") == 0 || strcmp(rest, "B") == 0)))
            return v * pow(1024, i) < 9e18 ? (int64_t)(v * pow(1024, i)) : -1;
    }
    return -1;
}

static int read_memory(const marie_node_t *n, marie_limits_cfg_t *l, marie_errors_t *errs)
{
    const char *s;
    if (marie_node_str(n, &s, errs) < 0)
        return -1;
    int64_t v = parse_bytes(s);
    if (v < (4 << 20) || v > (1LL << 40)) {
        marie_node_error(errs, n, "limits memory: 4M to 1T (bytes, or with K, M, G, T: 256M), got '%s'", s);
        return -1;
    }
    l->memory = v;
    return 0;
}

static int read_policy(const marie_node_t *n, marie_limits_cfg_t *l, marie_errors_t *errs)
{
    const char *s;
    if (marie_node_str(n, &s, errs) < 0)
        return -1;
    if (strcmp(s, "restart") == 0 || strcmp(s, "stop") == 0) {
        l->on_breach = strcmp(s, "stop") == 0 ? MARIE_BREACH_STOP : MARIE_BREACH_RESTART;
        return 0;
    }
    marie_node_error(errs, n, "limits on_breach: expected restart or stop, got '%s'", s);
    return -1;
}

int marie_limits_cfg_read(const marie_node_t *n, marie_limits_cfg_t *l, marie_errors_t *errs)
{
    static const char *const keys[] = {"memory", "cpu", "nofile", "on_breach", NULL};
    *l = (marie_limits_cfg_t){0};
    if (n->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, n, "limits: expected a mapping such as {memory: 256M, cpu: 0.5, nofile: 256}");
        return -1;
    }
    if (marie_node_check_keys(n, keys, "limits", errs) < 0)
        return -1;
    const marie_node_t *v;
    int64_t nf = 0;
    int rc = 0;
    if ((v = marie_node_get(n, "memory")))
        rc |= read_memory(v, l, errs);
    if ((v = marie_node_get(n, "cpu")) && marie_node_double(v, &l->cpu, errs) < 0) {
        rc = -1;
    } else if (v && !(l->cpu >= 0.01 && l->cpu <= 1024)) {
        marie_node_error(errs, v, "limits cpu: 0.01 to 1024 cores, got %g", l->cpu);
        rc = -1;
    }
    if ((v = marie_node_get(n, "nofile")) && (marie_node_int(v, &nf, errs) < 0 || nf < 16 || nf > (1 << 20))) {
        marie_node_error(errs, v, "limits nofile: 16 to 1048576 open files");
        rc = -1;
    }
    l->nofile = nf;
    if ((v = marie_node_get(n, "on_breach")))
        rc |= read_policy(v, l, errs);
    if (rc == 0 && !marie_limits_cfg_any(l)) {
        marie_node_error(errs, n, "limits: name at least one of memory, cpu and nofile");
        rc = -1;
    }
    if (rc)
        *l = (marie_limits_cfg_t){0};
    return rc;
}

bool marie_limits_cfg_any(const marie_limits_cfg_t *l)
{
    return l->memory > 0 || l->cpu > 0 || l->nofile > 0;
}

const char *marie_limits_cfg_text(const marie_limits_cfg_t *l, char *out, size_t size)
{
    size_t o = 0;
    out[0] = 0;
    if (l->memory > 0)
        o += (size_t)snprintf(out + o, o < size ? size - o : 0, "memory %.4gM", (double)l->memory / (1 << 20));
    if (l->cpu > 0)
        o += (size_t)snprintf(out + o, o < size ? size - o : 0, "%scpu %g", o ? " " : "", l->cpu);
    if (l->nofile > 0)
        o += (size_t)snprintf(out + o, o < size ? size - o : 0, "%snofile %lld", o ? " " : "", (long long)l->nofile);
    if (o && l->on_breach == MARIE_BREACH_STOP)
        snprintf(out + o, o < size ? size - o : 0, " on_breach stop");
    return out;
}
