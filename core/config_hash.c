/* config_hash: a component's effective configuration (every setting that changes how it runs,
 * inherited ones resolved), its hash and the fields in which two entries differ. */
#include "core/clear.h"
#include "core/config.h"
#include "core/config_priv.h"

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <sodium.h>

enum { F_EXEC, F_ARGS, F_ENV, F_SHELL, F_HOST, F_GROUP, F_PORTS, F_PARAMS, F_RESTART, F_STOP_TIMEOUT,
       F_HEARTBEAT_TIMEOUT, F_DEPENDS, F_SCHED, F_CLOCK, F_LCM_URL, F_AUTH, F_LIMITS, NFIELDS };
static const char *const field_names[NFIELDS] = {
    "exec", "args", "env", "shell", "host", "group", "ports", "params", "restart", "stop_timeout",
    "heartbeat_timeout", "depends", "sched", "clock", "lcm_url", "auth", "limits",
};

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

/* A list as length-prefixed items, optionally sorted (order that does not matter). */
static void put_list(FILE *f, char **v, size_t n, bool sorted)
{
    char **s = malloc((n ? n : 1) * sizeof *s);
    if (!s)
        return;
    if (n)
        memcpy(s, v, n * sizeof *s);
    if (sorted)
        qsort(s, n, sizeof *s, cmp_str);
    for (size_t i = 0; i < n; i++)
        fprintf(f, "%zu:%s,", strlen(s[i]), s[i]);
    free(s);
}

/* Every setting that changes how the component runs, inherited ones (defaults, the system's
 * clock, bus and key) resolved, one canonical text per field: field i is the NUL-terminated
 * text at buf + off[i]. Returns the buffer (caller frees), NULL when out of memory. One
 * stream per component: opening one per field cost more than the rest of the loading. */
static char *effective_fields(const marie_system_t *sys, const marie_component_cfg_t *c, size_t off[NFIELDS])
{
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    if (!f)
        return NULL;
    const marie_restart_cfg_t *r = &c->restart;
    for (int i = 0; i < NFIELDS; i++) {
        fflush(f);
        off[i] = len;
        switch (i) {
        case F_EXEC: fprintf(f, "%s", c->exec ? c->exec : ""); break;
        case F_ARGS: put_list(f, c->args, c->nargs, false); break;
        case F_ENV: put_list(f, c->env, c->nenv, true); break;
        case F_SHELL: fprintf(f, "%d", c->shell); break;
        case F_HOST: fprintf(f, "%s", c->host ? c->host : sys->nhosts ? sys->hosts[0] : ""); break;
        case F_GROUP: fprintf(f, "%s", c->group ? c->group : ""); break;
        case F_PORTS: {
            char **v = calloc(c->nports ? c->nports : 1, sizeof *v);
            size_t n = 0;
            for (size_t k = 0; v && k < c->nports; k++)
                if (asprintf(&v[n], "%s=%s@%s", c->ports[k].name, c->ports[k].channel,
                             c->ports[k].url ? c->ports[k].url : "") >= 0)
                    n++;
            if (v)
                put_list(f, v, n, true);
            marie_config_free_strv(v, n);
            break;
        }
        case F_PARAMS: {
            char *p = c->params ? marie_node_canonical(c->params) : NULL;
            fprintf(f, "%s", p ? p : "~");
            free(p);
            /* The robot's shape reaches components' parameters, so it is part of how they run. */
            char *rb = sys->robot ? marie_node_canonical(sys->robot) : NULL;
            if (rb)
                fprintf(f, " robot=%s", rb);
            free(rb);
            break;
        }
        case F_RESTART:
            fprintf(f, "%d,%.17g,%.17g,%.17g,%d,%.17g", (int)r->policy, r->backoff_min_s, r->backoff_max_s,
                    r->stable_s, r->max_failures, r->window_s);
            break;
        case F_STOP_TIMEOUT: fprintf(f, "%.17g", c->stop_timeout_s); break;
        case F_HEARTBEAT_TIMEOUT: fprintf(f, "%.17g", c->heartbeat_timeout_s); break;
        case F_DEPENDS: put_list(f, c->depends, c->ndepends, true); break;
        case F_SCHED: {
            char text[64 + 5 * (MARIE_SCHED_MAX_CPU + 1)];
            fprintf(f, "%s", marie_sched_cfg_text(&c->sched, text, sizeof text));
            break;
        }
        case F_CLOCK: fprintf(f, "%s", sys->clock == MARIE_CLOCK_SIM ? "sim" : "wall"); break;
        case F_LCM_URL: {
            fprintf(f, "%s", sys->lcm_url ? sys->lcm_url : "");
            /* A channel moved to shared memory changes how its ports run. */
            const marie_node_t *tn = marie_node_get(marie_doc_root(sys->doc), "transports");
            char *tr = tn ? marie_node_canonical(tn) : NULL;
            if (tr)
                fprintf(f, " transports=%s", tr);
            free(tr);
            /* So does the table of what the ROS 2 bridge carries. */
            char *r2 = sys->ros2 ? marie_node_canonical(sys->ros2) : NULL;
            if (r2)
                fprintf(f, " ros2=%s", r2);
            free(r2);
            break;
        }
        case F_AUTH: fprintf(f, "%s", sys->key_file ? sys->key_file : ""); break;
        case F_LIMITS: fprintf(f, "%s", marie_limits_cfg_text(&c->limits, (char[128]){0}, 128)); break;
        }
        fputc(0, f);
    }
    if (fclose(f) != 0) {
        free(buf);
        return NULL;
    }
    return buf;
}

static void hash_component(const marie_system_t *sys, marie_component_cfg_t *c)
{
    size_t off[NFIELDS];
    char *buf = effective_fields(sys, c, off);
    unsigned char h[crypto_hash_sha256_BYTES];
    crypto_hash_sha256_state st;
    crypto_hash_sha256_init(&st);
    for (int i = 0; i < NFIELDS; i++) {
        char head[64];
        const char *t = buf ? buf + off[i] : "";
        if (i == F_LIMITS && !*t)
            continue;       /* no limits: the hash a component had before limits existed */
        int n = snprintf(head, sizeof head, "%s:%zu:", field_names[i], strlen(t));
        crypto_hash_sha256_update(&st, (const unsigned char *)head, (unsigned long long)n);
        crypto_hash_sha256_update(&st, (const unsigned char *)t, strlen(t));
    }
    crypto_hash_sha256_final(&st, h);
    free(buf);
    for (size_t i = 0; i < sizeof h; i++)
        snprintf(c->hash_ + 2 * i, 3, "%02x", h[i]);
}

/* Hashing every entry took half of a component's start-up (its file read for its own entry):
 * the hash is made on demand, once. The entry is the system's, which a reader holds as const;
 * the hash is a cache of what the entry says, so it is filled in place. */
const char *marie_component_hash(const marie_component_cfg_t *c)
{
    if (!c->hash_[0])
        hash_component(c->sys_, (marie_component_cfg_t *)c);
    return c->hash_;
}

char *marie_component_differences(const marie_system_t *sa, const marie_component_cfg_t *a,
                                  const marie_system_t *sb, const marie_component_cfg_t *b)
{
    size_t oa[NFIELDS], ob[NFIELDS];
    char *ta = effective_fields(sa, a, oa), *tb = effective_fields(sb, b, ob), *out = calloc(1, 512);
    for (int i = 0; ta && tb && out && i < NFIELDS; i++)
        if (strcmp(ta + oa[i], tb + ob[i]) != 0)
            snprintf(out + strlen(out), 512 - strlen(out), "%s%s", out[0] ? "," : "", field_names[i]);
    if (!ta || !tb) {
        MARIE_CLEAR(out, free);
    }
    free(ta);
    free(tb);
    return out;
}
