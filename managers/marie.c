/* marie: the command line that drives the application managers (marie-am) of every host. */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <arpa/inet.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "core/config.h"
#include "core/time.h"
#include "lcmtypes/marie_event_t.h"
#include "managers/am_proto.h"
#include "managers/progcheck.h"
#include "core/auth.h"
#include "core/typeinfo.h"

#define MAX_HOSTS 64

typedef struct {
    char name[128];
    marie_am_status_t *st;      /* latest, owned */
    int64_t recv_wall;          /* local wall clock at receipt */
    int64_t recv_mono;
    bool fresh;                 /* received after the order's replies */
} host_t;

typedef struct {
    char host[128];
    bool ok;
    char reason[1024];
    int affected;
} reply_rec_t;

typedef struct {
    lcm_t *lcm;
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
    bool replies_done;
    /* status */
    host_t hosts[MAX_HOSTS];
    int nhosts;
    /* logs */
    const char *log_name;
    int64_t last_log_mono;
    bool follow;
} cli_t;

static volatile sig_atomic_t interrupted;      /* the signal that asked marie to stop */
static void on_sigint(int s) { interrupted = s; }
static int parse_interrupted(void) { return interrupted != 0; }
/* Exit status of a command cut short: 130 for SIGINT as a shell reports it, 1 for SIGTERM
 * (told to stop: the command failed). */
static int interrupted_status(void) { return interrupted == SIGINT ? 130 : MARIE_EXIT_FAIL; }

static void usage(FILE *out)
{
    fprintf(out,
            "usage: marie [--json] [--url URL] [--key FILE] [--timeout S] COMMAND [ARGS]\n"
            "  up FILE [--profile P] [--no-wait]   load a system on every host and start it\n"
            "  down [--no-wait]                    stop every component (reverse dependency order)\n"
            "  ps [--window S] [--watch]           components of every host (--watch: every second)\n"
            "  start|stop|restart NAME|GROUP... [--wait]\n"
            "  pause|resume NAME|GROUP...          lifecycle pause/resume\n"
            "  logs [-f] [-n N] NAME               last lines of a component's output (-f: follow)\n"
            "  move NAME HOST                      run a component on another host\n"
            "  doctor                              check the bus: route, TTL, buffers, clock skew\n"
            "  hash FILE [--profile A|--base [--profile B|--base]]  configuration hashes; with\n"
            "                                      two, which components are configured the same\n"
            "                                      (--base: the file without a profile)\n"
            "  keygen FILE                         write a new order key (mode 0600)\n"
            "  X ...                               runs marie-X (next to marie, or on PATH)\n"
            "exit status: 0 ok, 1 failure, 2 usage or system file error, 3 timeout or host\n"
            "unreachable, 4 key problem or order refused as unauthenticated\n");
}

/* ---------------------------------------------------------------- JSON output */

static void json_str(FILE *f, const char *s)
{
    fputc('"', f);
    for (; s && *s; s++) {
        unsigned char ch = (unsigned char)*s;
        if (ch == '"' || ch == '\\')
            fprintf(f, "\\%c", ch);
        else if (ch == '\n')
            fputs("\\n", f);
        else if (ch < 0x20)
            fprintf(f, "\\u%04x", ch);
        else
            fputc(ch, f);
    }
    fputc('"', f);
}

/* ---------------------------------------------------------------- bus */

static host_t *host_get(cli_t *cli, const char *name, bool create)
{
    for (int i = 0; i < cli->nhosts; i++)
        if (strcmp(cli->hosts[i].name, name) == 0)
            return &cli->hosts[i];
    if (!create || cli->nhosts == MAX_HOSTS)
        return NULL;
    host_t *h = &cli->hosts[cli->nhosts++];
    memset(h, 0, sizeof *h);
    snprintf(h->name, sizeof h->name, "%s", name);
    return h;
}

static void expect_host(cli_t *cli, const char *name)
{
    for (int i = 0; i < cli->nexpect; i++)
        if (strcmp(cli->expect[i], name) == 0)
            return;
    if (cli->nexpect < MAX_HOSTS)
        snprintf(cli->expect[cli->nexpect++], sizeof cli->expect[0], "%s", name);
}

static void on_status(const lcm_recv_buf_t *rbuf, const char *channel, const marie_am_status_t *st, void *user)
{
    cli_t *cli = user;
    host_t *h = host_get(cli, st->host, true);
    if (!h)
        return;
    if (h->st)
        marie_am_status_t_destroy(h->st);
    h->st = marie_am_status_t_copy(st);
    h->recv_wall = marie_wall_us();
    h->recv_mono = marie_mono_us();
    h->fresh = cli->replies_done;
    for (int i = 0; i < st->nhosts; i++)
        expect_host(cli, st->hosts[i]);
}

static bool all_replied(cli_t *cli)
{
    if (cli->nexpect == 0)
        return false;
    for (int i = 0; i < cli->nexpect; i++) {
        bool got = false;
        for (int k = 0; k < cli->nreplies && !got; k++)
            got = strcmp(cli->replies[k].host, cli->expect[i]) == 0;
        if (!got)
            return false;
    }
    return true;
}

static void on_reply(const lcm_recv_buf_t *rbuf, const char *channel, const marie_am_reply_t *r, void *user)
{
    cli_t *cli = user;
    if (r->seq != cli->seq || strcmp(r->sender, cli->sender) != 0)
        return;
    for (int i = 0; i < cli->nreplies; i++)
        if (strcmp(cli->replies[i].host, r->host) == 0)
            return;
    if (cli->nreplies == MAX_HOSTS)
        return;
    reply_rec_t *rr = &cli->replies[cli->nreplies++];
    snprintf(rr->host, sizeof rr->host, "%s", r->host);
    rr->ok = r->ok;
    snprintf(rr->reason, sizeof rr->reason, "%s", r->reason);
    rr->affected = r->affected;
    for (int i = 0; i < r->nhosts; i++)
        expect_host(cli, r->hosts[i]);
    if (r->nhosts == 0)
        expect_host(cli, r->host);
}

static void on_log(const lcm_recv_buf_t *rbuf, const char *channel, const marie_log_line_t *l, void *user)
{
    cli_t *cli = user;
    if (!cli->log_name || strcmp(l->component, cli->log_name) != 0)
        return;
    if (l->request_seq != 0) {
        if (l->request_seq != cli->seq)
            return;
        cli->last_log_mono = marie_mono_us();
        if (cli->json) {
            printf("{\"host\":");
            json_str(stdout, l->host);
            printf(",\"text\":");
            json_str(stdout, l->text);
            printf("}\n");
        } else {
            printf("%s\n", l->text);
        }
    } else if (cli->follow) {
        if (cli->json) {
            printf("{\"utime\":%lld,\"host\":", (long long)l->utime);
            json_str(stdout, l->host);
            printf(",\"pid\":%d,\"stream\":\"%s\",\"dropped\":%lld,\"text\":", (int)l->pid,
                   l->stream == MARIE_LOG_LINE_T_STDERR ? "err" : "out", (long long)l->dropped);
            json_str(stdout, l->text);
            printf("}\n");
        } else {
            time_t secs = (time_t)(l->utime / 1000000);
            struct tm tm;
            gmtime_r(&secs, &tm);
            if (l->dropped)
                printf("-- %lld lines dropped (rate limit)\n", (long long)l->dropped);
            printf("%04d-%02d-%02dT%02d:%02d:%02d.%03dZ %s %s\n", tm.tm_year + 1900, tm.tm_mon + 1,
                   tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, (int)(l->utime / 1000 % 1000),
                   l->stream == MARIE_LOG_LINE_T_STDERR ? "err" : "out", l->text);
        }
    }
    fflush(stdout);
}

/* Handle bus traffic for up to ms milliseconds, or until done(cli) holds. */
static bool pump(cli_t *cli, double seconds, bool (*done)(cli_t *))
{
    int64_t end = marie_mono_us() + (int64_t)(seconds * 1e6);
    for (;;) {
        if (done && done(cli))
            return true;
        if (interrupted)
            return false;
        int64_t left = end - marie_mono_us();
        if (left <= 0)
            return false;
        int ms = (int)(left / 1000) + 1;
        if (ms > 100)
            ms = 100;
        lcm_handle_timeout(cli->lcm, ms);
    }
}

/* Checked decoding: liblcm's decoders trust lengths from the wire. */
#define RAW_HANDLER(fn, type, typed)                                                           \
    static void fn(const lcm_recv_buf_t *rbuf, const char *channel, void *user)                 \
    {                                                                                           \
        marie_##type m;                                                                         \
        if (marie_decode_checked(&marie_type_##type, rbuf->data, rbuf->data_size, &m) < 0)      \
            return;                                                                             \
        typed(rbuf, channel, &m, user);                                                         \
        marie_##type##_decode_cleanup(&m);                                                      \
    }
RAW_HANDLER(on_raw_status, am_status_t, on_status)
RAW_HANDLER(on_raw_reply, am_reply_t, on_reply)
RAW_HANDLER(on_raw_log, log_line_t, on_log)

static int cli_open(cli_t *cli)
{
    cli->lcm = lcm_create(cli->url);
    if (!cli->lcm) {
        fprintf(stderr, "marie: cannot open the bus %s\n", cli->url);
        return -1;
    }
    lcm_subscribe(cli->lcm, MARIE_CH_AM_STATUS, on_raw_status, cli);
    lcm_subscribe(cli->lcm, MARIE_CH_AM_REPLY, on_raw_reply, cli);
    lcm_subscribe(cli->lcm, MARIE_CH_LOG, on_raw_log, cli);
    return 0;
}

static int load_key(cli_t *cli)
{
    if (cli->auth)
        return 0;
    char err[512];
    cli->auth = marie_auth_load(marie_am_key_path(cli->key_override), err, sizeof err);
    if (!cli->auth) {
        fprintf(stderr, "marie: %s\n", err);
        return -1;
    }
    return 0;
}

static const char *seq_path(void)
{
    static char path[PATH_MAX];
    const char *e = getenv("MARIE_SEQ_FILE");
    if (e && *e)
        return e;
    e = getenv("XDG_RUNTIME_DIR");
    if (e && *e) {
        snprintf(path, sizeof path, "%s/marie-order-seq", e);
        return path;
    }
    e = getenv("HOME");
    if (e && *e) {
        snprintf(path, sizeof path, "%s/.marie-order-seq", e);
        return path;
    }
    return NULL;
}

/* Send an order and gather the replies of every expected host. Returns an exit code. */
static int send_order(cli_t *cli, int op, char **targets, int ntargets, const char *arg,
                      const char *path, const char *text)
{
    if (load_key(cli) < 0)
        return MARIE_EXIT_AUTH;
    for (int attempt = 0; attempt < 2; attempt++) {
        cli->nreplies = 0;
        cli->replies_done = false;
        cli->seq = 0;
        marie_am_order_t o = {
            .op = (int8_t)op, .ntargets = ntargets, .targets = targets, .arg = (char *)arg,
            .system_path = (char *)path, .system_text = (char *)text,
        };
        if (marie_am_send_order(cli->lcm, cli->auth, &o, cli->sender, sizeof cli->sender, seq_path()) < 0) {
            fprintf(stderr, "marie: cannot send the order\n");
            return MARIE_EXIT_FAIL;
        }
        cli->seq = o.seq;
        pump(cli, cli->timeout_s, all_replied);
        /* a concurrent marie from the same user may have overtaken this seq: once more */
        bool replayed = false;
        for (int i = 0; i < cli->nreplies; i++)
            replayed |= strstr(cli->replies[i].reason, "replayed") != NULL;
        if (!replayed)
            break;
    }
    cli->replies_done = true;
    int rc = MARIE_EXIT_OK;
    if (cli->nreplies == 0) {
        fprintf(stderr, "marie: no manager answered within %.1f s\n", cli->timeout_s);
        return MARIE_EXIT_TIMEOUT;
    }
    for (int i = 0; i < cli->nreplies; i++) {
        reply_rec_t *r = &cli->replies[i];
        if (!r->ok) {
            fprintf(stderr, "marie: %s: %s\n", r->host, r->reason);
            if (strstr(r->reason, "refused: ") == r->reason)
                rc = MARIE_EXIT_AUTH;
            else if (rc == MARIE_EXIT_OK)
                rc = MARIE_EXIT_FAIL;
        }
    }
    for (int i = 0; i < cli->nexpect; i++) {
        bool got = false;
        for (int k = 0; k < cli->nreplies && !got; k++)
            got = strcmp(cli->replies[k].host, cli->expect[i]) == 0;
        if (!got) {
            fprintf(stderr, "marie: %s: no answer (host unreachable or marie-am not running)\n", cli->expect[i]);
            if (rc == MARIE_EXIT_OK)
                rc = MARIE_EXIT_TIMEOUT;
        }
    }
    return rc;
}

static void print_replies_json(cli_t *cli, int rc)
{
    printf("{\"ok\":%s,\"exit\":%d,\"replies\":[", rc == 0 ? "true" : "false", rc);
    for (int i = 0; i < cli->nreplies; i++) {
        printf("%s{\"host\":", i ? "," : "");
        json_str(stdout, cli->replies[i].host);
        printf(",\"ok\":%s,\"affected\":%d,\"reason\":", cli->replies[i].ok ? "true" : "false",
               cli->replies[i].affected);
        json_str(stdout, cli->replies[i].reason);
        printf("}");
    }
    printf("]}\n");
}

/* ---------------------------------------------------------------- waiting for states */

typedef struct {
    char **targets;
    int ntargets;
    bool want_running;
    const char *failed;         /* set when a target failed */
    char failed_buf[256];
} wait_spec_t;

static wait_spec_t *g_wait;

static bool target_hit(const marie_am_component_status_t *c, char **targets, int n)
{
    if (n == 0)
        return true;
    for (int t = 0; t < n; t++)
        if (strcmp(targets[t], "*") == 0 || strcmp(targets[t], c->name) == 0 || strcmp(targets[t], c->group) == 0)
            return true;
    return false;
}

static bool wait_done(cli_t *cli)
{
    wait_spec_t *w = g_wait;
    if (cli->nexpect == 0)
        return false;
    for (int i = 0; i < cli->nexpect; i++) {
        host_t *h = host_get(cli, cli->expect[i], false);
        if (!h || !h->st || !h->fresh)
            return false;
        for (int k = 0; k < h->st->ncomponents; k++) {
            const marie_am_component_status_t *c = &h->st->components[k];
            if (!target_hit(c, w->targets, w->ntargets))
                continue;
            if (w->want_running) {
                if (strcmp(c->state, "failed") == 0) {
                    snprintf(w->failed_buf, sizeof w->failed_buf, "%s on %s", c->name, h->name);
                    w->failed = w->failed_buf;
                    return true;
                }
                if (strcmp(c->state, "running") != 0 && strcmp(c->state, "paused") != 0 &&
                    strcmp(c->state, "degraded") != 0)
                    return false;
            } else if (c->pid != 0) {
                return false;
            }
        }
    }
    return true;
}

static int wait_states(cli_t *cli, char **targets, int ntargets, bool running, double timeout)
{
    wait_spec_t w = {.targets = targets, .ntargets = ntargets, .want_running = running};
    g_wait = &w;
    bool ok = pump(cli, timeout, wait_done);
    g_wait = NULL;
    if (w.failed) {
        fprintf(stderr, "marie: %s failed\n", w.failed);
        return MARIE_EXIT_FAIL;
    }
    if (!ok) {
        fprintf(stderr, "marie: components not %s within %.0f s (see marie ps)\n", running ? "running" : "stopped",
                timeout);
        return MARIE_EXIT_TIMEOUT;
    }
    return MARIE_EXIT_OK;
}

/* ---------------------------------------------------------------- commands */

static char *slurp(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    char *buf = NULL;
    size_t len = 0;
    FILE *m = open_memstream(&buf, &len);
    char tmp[8192];
    size_t n;
    while (m && (n = fread(tmp, 1, sizeof tmp, f)) > 0)
        fwrite(tmp, 1, n, m);
    if (m)
        fclose(m);
    fclose(f);
    return buf;
}

/* Every component's program, on whichever host it runs, is checked here: the programs are
 * installed alike on every host (deploy/), and a bad entry must stop `up` before any start. */
static int check_programs(const marie_system_t *sys, marie_errors_t *errs)
{
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    self[n > 0 ? n : 0] = 0;
    char *slash = strrchr(self, '/');
    if (slash)
        *slash = 0;
    char *cache = marie_progcheck_default_cache();
    marie_progcheck_t *p = marie_progcheck_create(self[0] ? self : NULL, cache);
    free(cache);
    int rc = p ? marie_progcheck_system(p, sys, NULL, NULL, errs) : -1;
    marie_progcheck_destroy(p);
    return rc;
}

static int cmd_up(cli_t *cli, int argc, char **argv)
{
    static const struct option opts[] = {{"profile", required_argument, 0, 'p'}, {"no-wait", no_argument, 0, 'n'},
                                         {"wait-timeout", required_argument, 0, 'w'}, {0, 0, 0, 0}};
    const char *profile = NULL;
    bool wait = true;
    double wait_s = 30;
    int opt;
    optind = 1;
    while ((opt = getopt_long(argc, argv, "p:", opts, NULL)) != -1) {
        if (opt == 'p') profile = optarg;
        else if (opt == 'n') wait = false;
        else if (opt == 'w') wait_s = atof(optarg);
        else return MARIE_EXIT_USAGE;
    }
    if (optind != argc - 1) {
        fprintf(stderr, "usage: marie up FILE [--profile P] [--no-wait]\n");
        return MARIE_EXIT_USAGE;
    }
    const char *file = argv[optind];
    /* Validate here first: a bad file never reaches a manager. */
    marie_errors_t errs = {0};
    marie_system_t *sys = marie_system_load(file, profile, &errs);
    marie_am_settings_t set;
    if (sys && (marie_am_check_system(sys, &set, &errs) < 0 || check_programs(sys, &errs) < 0)) {
        marie_system_destroy(sys);
        sys = NULL;
    }
    if (!sys) {
        marie_errors_print(&errs, stderr);
        marie_errors_clear(&errs);
        return interrupted ? interrupted_status() : MARIE_EXIT_USAGE;
    }
    for (size_t i = 0; i < sys->nhosts; i++)
        expect_host(cli, sys->hosts[i]);
    char *text = slurp(file);
    char *abs = realpath(file, NULL);
    int rc = text ? cli_open(cli) : -1;
    if (rc == 0)
        rc = send_order(cli, MARIE_AM_ORDER_T_OP_UP, NULL, 0, profile, abs ? abs : file, text);
    else
        rc = MARIE_EXIT_FAIL;
    if (rc == MARIE_EXIT_OK && wait)
        rc = wait_states(cli, NULL, 0, true, wait_s);
    if (cli->json)
        print_replies_json(cli, rc);
    else if (rc == MARIE_EXIT_OK)
        printf("%s is up on %d host(s)\n", sys->name ? sys->name : file, cli->nreplies);
    free(abs);
    free(text);
    marie_system_destroy(sys);
    return rc;
}

static int cmd_simple(cli_t *cli, int op, int argc, char **argv)
{
    static const struct option opts[] = {{"wait", no_argument, 0, 'w'}, {"no-wait", no_argument, 0, 'n'},
                                         {"wait-timeout", required_argument, 0, 't'}, {0, 0, 0, 0}};
    bool wait = op == MARIE_AM_ORDER_T_OP_DOWN;
    double wait_s = 30;
    int opt;
    optind = 1;
    while ((opt = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        if (opt == 'w') wait = true;
        else if (opt == 'n') wait = false;
        else if (opt == 't') wait_s = atof(optarg);
        else return MARIE_EXIT_USAGE;
    }
    char **targets = argv + optind;
    int ntargets = argc - optind;
    if ((op == MARIE_AM_ORDER_T_OP_DOWN) != (ntargets == 0)) {
        fprintf(stderr, op == MARIE_AM_ORDER_T_OP_DOWN ? "usage: marie down\n"
                                                       : "usage: marie %s NAME|GROUP...\n", marie_am_op_name(op));
        return MARIE_EXIT_USAGE;
    }
    if (cli_open(cli) < 0)
        return MARIE_EXIT_FAIL;
    int rc = send_order(cli, op, targets, ntargets, NULL, NULL, NULL);
    if (rc == MARIE_EXIT_OK && wait) {
        bool running = op == MARIE_AM_ORDER_T_OP_START || op == MARIE_AM_ORDER_T_OP_RESTART ||
                       op == MARIE_AM_ORDER_T_OP_RESUME;
        if (op == MARIE_AM_ORDER_T_OP_RESTART)
            pump(cli, 0.1, NULL);    /* let the old process go before waiting for running */
        rc = wait_states(cli, targets, ntargets, running, wait_s);
    }
    int affected = 0;
    for (int i = 0; i < cli->nreplies; i++)
        affected += cli->replies[i].affected;
    if (cli->json)
        print_replies_json(cli, rc);
    else if (rc == MARIE_EXIT_OK)
        printf("%s: %d component(s)\n", marie_am_op_name(op), affected);
    return rc;
}

static int cmd_move(cli_t *cli, int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: marie move NAME HOST\n");
        return MARIE_EXIT_USAGE;
    }
    if (cli_open(cli) < 0)
        return MARIE_EXIT_FAIL;
    int rc = send_order(cli, MARIE_AM_ORDER_T_OP_MOVE, &argv[1], 1, argv[2], NULL, NULL);
    if (cli->json)
        print_replies_json(cli, rc);
    else if (rc == MARIE_EXIT_OK)
        printf("%s moves to %s\n", argv[1], argv[2]);
    return rc;
}

static void fmt_uptime(int64_t us, char *buf, size_t len)
{
    int64_t s = us / 1000000;
    if (us <= 0)
        snprintf(buf, len, "-");
    else if (s < 60)
        snprintf(buf, len, "%llds", (long long)s);
    else if (s < 3600)
        snprintf(buf, len, "%lldm%02llds", (long long)(s / 60), (long long)(s % 60));
    else
        snprintf(buf, len, "%lldh%02lldm", (long long)(s / 3600), (long long)(s / 60 % 60));
}

static void fmt_bytes(int64_t b, char *buf, size_t len)
{
    if (b <= 0)
        snprintf(buf, len, "-");
    else if (b < 10 << 20)
        snprintf(buf, len, "%.1fM", (double)b / (1 << 20));
    else
        snprintf(buf, len, "%lldM", (long long)(b >> 20));
}

/* Print the table; a host not heard from for lost_us (or never) is lost. Returns how many. */
static int print_ps(cli_t *cli, int64_t lost_us)
{
    for (int i = 0; i < cli->nhosts; i++)
        expect_host(cli, cli->hosts[i].name);
    int64_t now = marie_mono_us();
    int lost = 0;
    if (cli->json)
        printf("{\"hosts\":[");
    else
        printf("%-12s %-20s %-9s %7s %8s %4s %6s %7s\n", "HOST", "COMPONENT", "STATE", "PID", "UPTIME",
               "RST", "CPU%", "RSS");
    for (int i = 0; i < cli->nexpect; i++) {
        host_t *h = host_get(cli, cli->expect[i], false);
        bool is_lost = !h || !h->st || now - h->recv_mono > lost_us;
        lost += is_lost;
        if (cli->json) {
            printf("%s{\"host\":", i ? "," : "");
            json_str(stdout, cli->expect[i]);
            if (is_lost) {
                printf(",\"lost\":true,\"components\":[]}");
                continue;
            }
            marie_am_status_t *st = h->st;
            printf(",\"lost\":false,\"system\":");
            json_str(stdout, st->system);
            printf(",\"profile\":");
            json_str(stdout, st->profile);
            printf(",\"load\":[%.2f,%.2f,%.2f],\"ncpu\":%d,\"am_pid\":%d,\"am_cpu\":%.2f,\"am_rss\":%lld,"
                   "\"orders_refused\":%lld,\"clock_offset_us\":%lld,\"components\":[",
                   st->load1, st->load5, st->load15, st->ncpu, st->pid, st->am_cpu, (long long)st->am_rss,
                   (long long)st->orders_refused, (long long)(st->utime - h->recv_wall));
            for (int k = 0; k < st->ncomponents; k++) {
                marie_am_component_status_t *c = &st->components[k];
                printf("%s{\"name\":", k ? "," : "");
                json_str(stdout, c->name);
                printf(",\"group\":");
                json_str(stdout, c->group);
                printf(",\"state\":");
                json_str(stdout, c->state);
                printf(",\"comp_state\":%d,\"pid\":%d,\"uptime_us\":%lld,\"restarts\":%d,\"last_exit\":%d,"
                       "\"cpu\":%.2f,\"rss\":%lld,\"heartbeat_age_us\":%lld,\"log_drops\":%lld,\"config_hash\":",
                       c->comp_state, c->pid, (long long)c->uptime_us, c->restarts, c->last_exit, c->cpu,
                       (long long)c->rss, (long long)c->heartbeat_age_us, (long long)c->log_drops);
                json_str(stdout, c->config_hash);
                printf("}");
            }
            printf("]}");
            continue;
        }
        if (is_lost) {
            printf("%-12s %-20s %-9s\n", cli->expect[i], "-", "lost");
            continue;
        }
        marie_am_status_t *st = h->st;
        if (st->ncomponents == 0)
            printf("%-12s %-20s %-9s\n", st->host, "-", st->system[0] ? "idle" : "no-system");
        for (int k = 0; k < st->ncomponents; k++) {
            marie_am_component_status_t *c = &st->components[k];
            char up[32], rss[32], pid[16], cpu[16];
            fmt_uptime(c->uptime_us, up, sizeof up);
            fmt_bytes(c->rss, rss, sizeof rss);
            snprintf(pid, sizeof pid, c->pid ? "%d" : "-", c->pid);
            snprintf(cpu, sizeof cpu, c->pid ? "%.1f" : "-", c->cpu);
            printf("%-12s %-20s %-9s %7s %8s %4d %6s %7s\n", st->host, c->name, c->state, pid, up, c->restarts,
                   cpu, rss);
        }
    }
    if (cli->json) {
        printf("]}\n");
    } else if (cli->nexpect > 0) {
        printf("\n%-12s %-6s %-7s %-7s %-8s %s\n", "HOST", "LOAD", "AM-CPU%", "AM-RSS", "REFUSED", "SYSTEM");
        for (int i = 0; i < cli->nexpect; i++) {
            host_t *h = host_get(cli, cli->expect[i], false);
            if (!h || !h->st || now - h->recv_mono > lost_us) {
                printf("%-12s %-6s\n", cli->expect[i], "lost");
                continue;
            }
            char rss[32];
            fmt_bytes(h->st->am_rss, rss, sizeof rss);
            printf("%-12s %-6.2f %-7.1f %-7s %-8lld %s%s%s%s\n", h->name, h->st->load1, h->st->am_cpu, rss,
                   (long long)h->st->orders_refused, h->st->system[0] ? h->st->system : "-",
                   h->st->profile[0] ? " (" : "", h->st->profile, h->st->profile[0] ? ")" : "");
        }
    }
    fflush(stdout);
    return lost;
}

static int cmd_ps(cli_t *cli, int argc, char **argv)
{
    static const struct option opts[] = {{"window", required_argument, 0, 'w'}, {"watch", no_argument, 0, 'W'},
                                         {0, 0, 0, 0}};
    double window = 1.2;
    bool watch = false;
    int opt;
    optind = 1;
    while ((opt = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        if (opt == 'w') window = atof(optarg);
        else if (opt == 'W') watch = true;
        else return MARIE_EXIT_USAGE;
    }
    if (optind != argc) {
        fprintf(stderr, "usage: marie ps [--window S] [--watch]\n");
        return MARIE_EXIT_USAGE;
    }
    if (cli_open(cli) < 0)
        return MARIE_EXIT_FAIL;
    /* Managers report twice a second: a host silent for the whole window is lost. */
    pump(cli, window, NULL);
    if (watch) {
        /* every second; a host silent for more than 2 s is lost */
        while (!interrupted) {
            if (!cli->json)
                printf("\033[H\033[J");
            print_ps(cli, 2000000);
            pump(cli, 1.0, NULL);
        }
        return MARIE_EXIT_OK;
    }
    int lost = print_ps(cli, INT64_MAX / 2);
    if (cli->nexpect == 0) {
        fprintf(stderr, "marie: no manager heard within %.1f s\n", window);
        return MARIE_EXIT_TIMEOUT;
    }
    return lost ? MARIE_EXIT_TIMEOUT : MARIE_EXIT_OK;
}

static bool logs_quiet(cli_t *cli)
{
    return all_replied(cli) && marie_mono_us() - cli->last_log_mono > 300000;
}

static int cmd_logs(cli_t *cli, int argc, char **argv)
{
    int n = 20, opt;
    optind = 1;
    while ((opt = getopt(argc, argv, "fn:")) != -1) {
        if (opt == 'f') cli->follow = true;
        else if (opt == 'n') n = atoi(optarg);
        else return MARIE_EXIT_USAGE;
    }
    if (optind != argc - 1) {
        fprintf(stderr, "usage: marie logs [-f] [-n N] NAME\n");
        return MARIE_EXIT_USAGE;
    }
    cli->log_name = argv[optind];
    if (cli_open(cli) < 0)
        return MARIE_EXIT_FAIL;
    int rc = MARIE_EXIT_OK;
    if (n > 0) {
        char arg[32];
        snprintf(arg, sizeof arg, "%d", n);
        if (load_key(cli) < 0) {
            if (!cli->follow)
                return MARIE_EXIT_AUTH;
            fprintf(stderr, "marie: following new lines only\n");
        } else {
            /* the answers carry the order's seq (on_log matches it) */
            cli->last_log_mono = marie_mono_us();
            rc = send_order(cli, MARIE_AM_ORDER_T_OP_TAIL, &argv[optind], 1, arg, NULL, NULL);
            pump(cli, 0.5, logs_quiet);
        }
    }
    if (cli->follow && rc == MARIE_EXIT_OK) {
        while (!interrupted)
            lcm_handle_timeout(cli->lcm, 200);
    }
    return rc;
}

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
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(detail, sizeof detail, fmt, ap);
    va_end(ap);
    if (!ok)
        d->problems++;
    if (cli->json) {
        printf("%s{\"check\":", d->first ? "" : ",");
        json_str(stdout, name);
        printf(",\"ok\":%s,\"detail\":", ok ? "true" : "false");
        json_str(stdout, detail);
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

static int cmd_doctor(cli_t *cli, int argc, char **argv)
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
    if (lcm_ok)
        pump(cli, 1.2, NULL);
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
    if (want > 0)
        check(cli, &d, "recv-buffer", rmem_max < 0 || want <= rmem_max,
              "recv_buf_size=%lld, net.core.rmem_max=%lld%s", want, rmem_max,
              rmem_max >= 0 && want > rmem_max ? " (the kernel caps it: sysctl -w net.core.rmem_max=N)" : "");
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
        json_str(stdout, name);
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

static int cmd_hash(cli_t *cli, int argc, char **argv)
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
        bool same = b && strcmp(a->hash, b->hash) == 0;
        char *fields = b && !same ? marie_component_differences(sys[0], a, sys[1], b) : NULL;
        differ += b && !same;
        hash_row(cli, &first, a->name, n == 1 ? "" : !b ? "only-in-a" : same ? "same" : "differs", a->hash,
                 b ? b->hash : NULL, fields, n);
        free(fields);
    }
    for (size_t i = 0; n == 2 && i < sys[1]->ncomponents; i++) {
        const marie_component_cfg_t *b = &sys[1]->components[i];
        if (!marie_system_component(sys[0], b->name))
            hash_row(cli, &first, b->name, "only-in-b", NULL, b->hash, NULL, n);
    }
    if (cli->json)
        printf("],\"differ\":%d}\n", differ);
    marie_system_destroy(sys[0]);
    marie_system_destroy(sys[1]);
    return MARIE_EXIT_OK;
}

/* ---------------------------------------------------------------- dispatch */

static int run_external(const char *cmd, int argc, char **argv)
{
    char name[256];
    snprintf(name, sizeof name, "marie-%s", cmd);
    if (strchr(cmd, '/')) {
        fprintf(stderr, "marie: unknown command '%s'\n", cmd);
        return MARIE_EXIT_USAGE;
    }
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    argv[0] = name;
    if (n > 0) {
        self[n] = 0;
        char *slash = strrchr(self, '/');
        if (slash) {
            char path[PATH_MAX + 256];
            snprintf(path, sizeof path, "%.*s/%s", (int)(slash - self), self, name);
            if (access(path, X_OK) == 0) {
                execv(path, argv);
                fprintf(stderr, "marie: %s: %s\n", path, strerror(errno));
                return MARIE_EXIT_FAIL;
            }
        }
    }
    execvp(name, argv);
    if (errno == ENOENT) {
        fprintf(stderr, "marie: unknown command '%s' (no %s next to marie or on PATH)\n", cmd, name);
        usage(stderr);
        return MARIE_EXIT_USAGE;
    }
    fprintf(stderr, "marie: %s: %s\n", name, strerror(errno));
    return MARIE_EXIT_FAIL;
}

int main(int argc, char **argv)
{
    cli_t cli = {0};
    cli.timeout_s = 3;
    cli.url = getenv("LCM_DEFAULT_URL") ? getenv("LCM_DEFAULT_URL") : marie_default_url();
    int i = 1;
    for (; i < argc && argv[i][0] == '-'; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--json") == 0) {
            cli.json = true;
        } else if (strcmp(a, "--url") == 0 && i + 1 < argc) {
            cli.url = argv[++i];
        } else if (strcmp(a, "--key") == 0 && i + 1 < argc) {
            cli.key_override = argv[++i];
        } else if (strcmp(a, "--timeout") == 0 && i + 1 < argc) {
            cli.timeout_s = atof(argv[++i]);
        } else if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            return 0;
        } else {
            fprintf(stderr, "marie: unknown option %s\n", a);
            usage(stderr);
            return MARIE_EXIT_USAGE;
        }
    }
    if (i >= argc) {
        usage(stderr);
        return MARIE_EXIT_USAGE;
    }
    const char *cmd = argv[i];
    int sargc = argc - i;
    char **sargv = argv + i;
    /* --json may also follow the command */
    for (int k = 1; k < sargc; k++)
        if (strcmp(sargv[k], "--json") == 0 && strcmp(cmd, "logs") != 0) {
            cli.json = true;
            memmove(&sargv[k], &sargv[k + 1], (size_t)(sargc - k) * sizeof *sargv);
            sargc--;
            k--;
        }
    marie_am_sender(cli.sender, sizeof cli.sender);
    struct sigaction sa = {.sa_handler = on_sigint};
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);
    marie_config_set_interrupt(parse_interrupted);

    int rc;
    if (strcmp(cmd, "help") == 0) {
        usage(stdout);
        return 0;
    } else if (strcmp(cmd, "up") == 0) {
        rc = cmd_up(&cli, sargc, sargv);
    } else if (strcmp(cmd, "down") == 0) {
        rc = cmd_simple(&cli, MARIE_AM_ORDER_T_OP_DOWN, sargc, sargv);
    } else if (strcmp(cmd, "ps") == 0) {
        rc = cmd_ps(&cli, sargc, sargv);
    } else if (marie_am_op_parse(cmd) >= MARIE_AM_ORDER_T_OP_START && marie_am_op_parse(cmd) <= MARIE_AM_ORDER_T_OP_RESUME) {
        rc = cmd_simple(&cli, marie_am_op_parse(cmd), sargc, sargv);
    } else if (strcmp(cmd, "logs") == 0) {
        rc = cmd_logs(&cli, sargc, sargv);
    } else if (strcmp(cmd, "move") == 0) {
        rc = cmd_move(&cli, sargc, sargv);
    } else if (strcmp(cmd, "doctor") == 0) {
        rc = cmd_doctor(&cli, sargc, sargv);
    } else if (strcmp(cmd, "hash") == 0) {
        rc = cmd_hash(&cli, sargc, sargv);
    } else if (strcmp(cmd, "keygen") == 0) {
        if (sargc != 2) {
            fprintf(stderr, "usage: marie keygen FILE\n");
            return MARIE_EXIT_USAGE;
        }
        int r = marie_auth_keygen(sargv[1]);
        if (r < 0)
            fprintf(stderr, "marie: keygen %s: %s\n", sargv[1], strerror(-r));
        rc = r < 0 ? MARIE_EXIT_FAIL : MARIE_EXIT_OK;
    } else {
        return run_external(cmd, sargc, sargv);
    }
    for (int k = 0; k < cli.nhosts; k++)
        if (cli.hosts[k].st)
            marie_am_status_t_destroy(cli.hosts[k].st);
    marie_auth_destroy(cli.auth);
    if (cli.lcm)
        lcm_destroy(cli.lcm);
    return rc;
}
