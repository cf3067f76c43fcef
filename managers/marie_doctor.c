/* marie doctor (is the bus usable: route, TTL, buffers, clocks) and marie hash (which
 * components two profiles configure the same). */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <signal.h>
#include <stdarg.h>
#include <sys/socket.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <arpa/inet.h>

#include <lcm/lcm.h>

#include "core/buf.h"
#include "core/config.h"
#include "core/log.h"
#include "core/time.h"
#include "proto/am_proto.h"
#include "managers/marie_cli.h"
#include "core/auth.h"

/* ---------------------------------------------------------------- doctor */

typedef struct {
    int problems;
    bool first;
} doc_t;

static void check(cli_t *cli, doc_t *d, const char *name, bool ok, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
static void check(cli_t *cli, doc_t *d, const char *name, bool ok, const char *fmt, ...)
{
    char detail[512];
    MARIE_VFORMAT(detail, fmt);
    if (!ok)
        d->problems++;
    if (cli->json) {
        printf("%s{\"check\":", d->first ? "" : ",");
        marie_json_fputs(stdout, name);
        printf(",\"ok\":%s,\"detail\":", ok ? "true" : "false");
        marie_json_fputs(stdout, detail);
        printf("}");
        d->first = false;
    } else {
        printf("%-6s %-16s %s\n", ok ? "ok" : "FAIL", name, detail);
    }
}

static long long read_long(const char *path)
{
    FILE *f = fopen(path, "r");
    long long v = -1;
    if (f) {
        if (fscanf(f, "%lld", &v) != 1)
            v = -1;
        fclose(f);
    }
    return v;
}

static long long url_param(const char *url, const char *key)
{
    const char *q = strchr(url, '?');
    size_t kl = strlen(key);
    while (q) {
        q++;
        if (strncmp(q, key, kl) == 0 && q[kl] == '=')
            return atoll(q + kl + 1);
        q = strchr(q, '&');
    }
    return -1;
}

/* Whether this process may have a receive buffer of `want` bytes past net.core.rmem_max: marie's
 * bus asks with SO_RCVBUFFORCE first (core/bus/udpm.c), which a privileged user may. */
static bool can_force_rcvbuf(long long want)
{
    int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0), v = want > INT_MAX / 2 ? INT_MAX / 2 : (int)want, got = 0;
    socklen_t len = sizeof got;
    bool ok = fd >= 0 && setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &v, sizeof v) == 0 &&
              getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &got, &len) == 0 && got >= v;
    if (fd >= 0)
        close(fd);
    return ok;
}

int cmd_doctor(cli_t *cli, int argc, char **argv)
{
    doc_t d = {0, true};
    if (argc != 1) {
        fprintf(stderr, "usage: marie doctor\n");
        return MARIE_EXIT_USAGE;
    }
    if (cli->json)
        printf("{\"url\":\"%s\",\"checks\":[", cli->url);
    else
        printf("bus %s\n", cli->url);
    /* multicast group and route */
    unsigned a, b, c2, e;
    const char *addr = strstr(cli->url, "://");
    bool parsed = addr && sscanf(addr + 3, "%u.%u.%u.%u", &a, &b, &c2, &e) == 4;
    if (!parsed) {
        check(cli, &d, "url", strncmp(cli->url, "udpm://", 7) != 0, "not a udpm:// URL with an IPv4 group");
    } else {
        uint32_t group = (a << 24) | (b << 16) | (c2 << 8) | e;
        check(cli, &d, "multicast-group", a >= 224 && a <= 239, "%u.%u.%u.%u", a, b, c2, e);
        FILE *f = fopen("/proc/net/route", "r");
        char line[256], dev[64] = "", best_dev[64] = "";
        int best_len = -1;
        if (f) {
            if (fgets(line, sizeof line, f)) { /* header */ }
            while (fgets(line, sizeof line, f)) {
                unsigned dst, gw, flags, refc, use, metric, mask;
                if (sscanf(line, "%63s %x %x %x %u %u %u %x", dev, &dst, &gw, &flags, &refc, &use, &metric, &mask) != 8)
                    continue;
                dst = ntohl(dst);
                mask = ntohl(mask);
                if ((group & mask) == (dst & mask) && (flags & 1)) {
                    int len = __builtin_popcount(mask);
                    if (len > best_len) {
                        best_len = len;
                        snprintf(best_dev, sizeof best_dev, "%s", dev);
                    }
                }
            }
            fclose(f);
        }
        if (best_len >= 0)
            check(cli, &d, "multicast-route", true, "group routed via %s (/%d)", best_dev, best_len);
        else
            check(cli, &d, "multicast-route", false, "no route covers the group: ip route add 224.0.0.0/4 dev IFACE");
    }
    long long ttl = url_param(cli->url, "ttl");
    /* hosts and clock skew from the managers' status */
    bool lcm_ok = cli_open(cli) == 0;
    if (lcm_ok)     /* the managers answer at once; a silent one is waited for the whole 1.2 s */
        pump(cli, 1.2, request_status(cli) == 0 ? all_hosts_heard : NULL);
    int nhosts_sys = 0;
    for (int i = 0; i < cli->nhosts; i++)
        if (cli->hosts[i].st && cli->hosts[i].st->nhosts > nhosts_sys)
            nhosts_sys = cli->hosts[i].st->nhosts;
    if (ttl < 0)
        ttl = 0;
    bool ttl_ok = !(ttl == 0 && nhosts_sys > 1) && ttl <= 1;
    check(cli, &d, "ttl", ttl_ok, "ttl=%lld with %d host(s) in the system%s", ttl, nhosts_sys,
          ttl == 0 && nhosts_sys > 1 ? ": messages never leave this host (use ttl=1)"
          : ttl > 1 ? ": messages may cross routers (use ttl=1)" : "");
    long long rmem_max = read_long("/proc/sys/net/core/rmem_max");
    long long rmem_def = read_long("/proc/sys/net/core/rmem_default");
    long long want = url_param(cli->url, "recv_buf_size");
    bool forced = want > rmem_max && rmem_max >= 0 && can_force_rcvbuf(want);
    if (want > 0)
        check(cli, &d, "recv-buffer", rmem_max < 0 || want <= rmem_max || forced,
              "recv_buf_size=%lld, net.core.rmem_max=%lld%s", want, rmem_max,
              forced ? " (above it, but this user may force the buffer: SO_RCVBUFFORCE, as marie's bus does)"
              : rmem_max >= 0 && want > rmem_max ? " (the kernel caps it: sysctl -w net.core.rmem_max=N)" : "");
    else
        check(cli, &d, "recv-buffer", true, "no recv_buf_size in the URL: kernel default %lld bytes (large messages may be lost)",
              rmem_def);
    {
        char err[512];
        marie_auth_t *a = marie_auth_load(marie_am_key_path(cli->key_override), err, sizeof err);
        check(cli, &d, "key", a != NULL, "%s", a ? marie_am_key_path(cli->key_override) : err);
        marie_auth_destroy(a);
    }
    if (!lcm_ok) {
        check(cli, &d, "bus", false, "cannot open %s", cli->url);
    } else {
        for (int i = 0; i < cli->nhosts; i++)
            expect_host(cli, cli->hosts[i].name);
        int64_t lo = INT64_MAX, hi = INT64_MIN;
        int heard = 0;
        for (int i = 0; i < cli->nexpect; i++) {
            host_t *h = host_get(cli, cli->expect[i], false);
            if (!h || !h->st) {
                check(cli, &d, "host", false, "%s: not heard from (lost)", cli->expect[i]);
                continue;
            }
            heard++;
            int64_t off = h->st->utime - h->recv_wall;
            if (off < lo) lo = off;
            if (off > hi) hi = off;
            check(cli, &d, "host", true, "%s: clock %+.1f ms from here, load %.2f, %d component(s), %lld order(s) refused",
                  h->name, off / 1000.0, h->st->load1, h->st->ncomponents, (long long)h->st->orders_refused);
        }
        if (heard == 0)
            check(cli, &d, "managers", false, "no marie-am heard within 1.2 s");
        else
            check(cli, &d, "clock-skew", hi - lo <= 50000, "%.1f ms between the hosts' clocks (limit 50 ms)",
                  (hi - lo) / 1000.0);
    }
    if (cli->json)
        printf("],\"problems\":%d}\n", d.problems);
    else
        printf("%d problem(s)\n", d.problems);
    return d.problems ? MARIE_EXIT_FAIL : MARIE_EXIT_OK;
}

/* ---------------------------------------------------------------- hash */

/* Effective-configuration hashes of a system under one or two profiles (--base is the file
 * without a profile, the real robot): a component shows "same" when both runs get an identical
 * configuration, else which settings differ. */
static void hash_row(cli_t *cli, bool *first, const char *name, const char *verdict, const char *ha,
                     const char *hb, const char *fields, int n)
{
    if (cli->json) {
        printf("%s{\"name\":", *first ? "" : ",");
        marie_json_fputs(stdout, name);
        printf(",\"hash\":\"%s\"", ha ? ha : "");
        if (n == 2) {
            printf(",\"hash_b\":\"%s\",\"verdict\":\"%s\",\"fields\":[", hb ? hb : "", verdict);
            for (const char *f = fields; f && *f;) {
                size_t len = strcspn(f, ",");
                printf("%s\"%.*s\"", f == fields ? "" : ",", (int)len, f);
                f += len + (f[len] == ',');
            }
            printf("]");
        }
        printf("}");
    } else if (n == 2) {
        printf("%-20s %-9s %-16.16s %-16.16s %s\n", name, verdict, ha ? ha : "-", hb ? hb : "-",
               fields ? fields : "");
    } else {
        printf("%-20s %s\n", name, ha);
    }
    *first = false;
}

int cmd_hash(cli_t *cli, int argc, char **argv)
{
    const char *profiles[2] = {NULL, NULL};
    const char *labels[2] = {"base", "base"};
    int np = 0, opt;
    static const struct option opts[] = {{"profile", required_argument, 0, 'p'}, {"base", no_argument, 0, 'b'},
                                         {0, 0, 0, 0}};
    optind = 1;
    while ((opt = getopt_long(argc, argv, "p:", opts, NULL)) != -1) {
        if ((opt != 'p' && opt != 'b') || np == 2) {
            fprintf(stderr, "usage: marie hash FILE [--profile A | --base] [--profile B | --base]\n");
            return MARIE_EXIT_USAGE;
        }
        profiles[np] = opt == 'p' ? optarg : NULL;
        labels[np++] = opt == 'p' ? optarg : "base";
    }
    if (optind != argc - 1) {
        fprintf(stderr, "usage: marie hash FILE [--profile A | --base] [--profile B | --base]\n");
        return MARIE_EXIT_USAGE;
    }
    marie_system_t *sys[2] = {NULL, NULL};
    int n = np == 2 ? 2 : 1;
    for (int i = 0; i < n; i++) {
        marie_errors_t errs = {0};
        sys[i] = marie_system_load(argv[optind], profiles[i], &errs);
        if (!sys[i]) {
            marie_errors_print(&errs, stderr);
            if (profiles[i] && !interrupted)
                fprintf(stderr, "marie: (the file without a profile, the base, is named with --base)\n");
            marie_errors_clear(&errs);
            marie_system_destroy(sys[0]);
            return interrupted ? interrupted_status() : MARIE_EXIT_USAGE;
        }
    }
    int differ = 0;
    if (cli->json)
        printf("{\"a\":\"%s\",\"b\":\"%s\",\"components\":[", labels[0], n == 2 ? labels[1] : "");
    else if (n == 2)
        printf("%-20s %-9s %-16s %-16s %s\n", "COMPONENT", "", labels[0], labels[1], "DIFFERS IN");
    bool first = true;
    for (size_t i = 0; i < sys[0]->ncomponents; i++) {
        const marie_component_cfg_t *a = &sys[0]->components[i];
        const marie_component_cfg_t *b = n == 2 ? marie_system_component(sys[1], a->name) : NULL;
        bool same = b && strcmp(marie_component_hash(a), marie_component_hash(b)) == 0;
        char *fields = b && !same ? marie_component_differences(sys[0], a, sys[1], b) : NULL;
        differ += b && !same;
        hash_row(cli, &first, a->name, n == 1 ? "" : !b ? "only-in-a" : same ? "same" : "differs", marie_component_hash(a),
                 b ? marie_component_hash(b) : NULL, fields, n);
        free(fields);
    }
    for (size_t i = 0; n == 2 && i < sys[1]->ncomponents; i++) {
        const marie_component_cfg_t *b = &sys[1]->components[i];
        if (!marie_system_component(sys[0], b->name))
            hash_row(cli, &first, b->name, "only-in-b", NULL, marie_component_hash(b), NULL, n);
    }
    if (cli->json)
        printf("],\"differ\":%d}\n", differ);
    marie_system_destroy(sys[0]);
    marie_system_destroy(sys[1]);
    return MARIE_EXIT_OK;
}
