/* marie's side of the bus: statuses, replies and log lines from the managers, orders sent
 * and answered, and waiting until components reach a state. */
#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "core/buf.h"
#include "core/config.h"
#include "core/time.h"
#include "proto/am_proto.h"
#include "managers/marie_cli.h"
#include "core/auth.h"
#include "core/typeinfo.h"

/* ---------------------------------------------------------------- bus */

host_t *host_get(cli_t *cli, const char *name, bool create)
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

void expect_host(cli_t *cli, const char *name)
{
    for (int i = 0; i < cli->nexpect; i++)
        if (strcmp(cli->expect[i], name) == 0)
            return;
    if (cli->nexpect < MAX_HOSTS)
        snprintf(cli->expect[cli->nexpect++], sizeof cli->expect[0], "%s", name);
}

static bool replied(const cli_t *cli, const char *host)
{
    for (int k = 0; k < cli->nreplies; k++)
        if (strcmp(cli->replies[k].host, host) == 0)
            return true;
    return false;
}

static void on_status(const lcm_recv_buf_t *rbuf, const char *channel, const marie_am_status_t *st, void *user)
{
    cli_t *cli = user;
    int before = cli->nhosts;
    host_t *h = host_get(cli, st->host, true);
    if (!h)
        return;
    if (cli->nhosts > before)
        cli->new_host_mono = marie_mono_us();
    cli->hosts_unnamed |= st->nhosts == 0;
    if (h->st)
        marie_am_status_t_destroy(h->st);
    h->st = marie_am_status_t_copy(st);
    h->recv_wall = marie_wall_us();
    h->recv_mono = marie_mono_us();
    h->fresh = replied(cli, st->host);     /* its manager has handled the order in flight */
    for (int i = 0; i < st->nhosts; i++)
        expect_host(cli, st->hosts[i]);
}

bool all_replied(cli_t *cli)
{
    if (cli->nexpect == 0)
        return false;
    for (int i = 0; i < cli->nexpect; i++)
        if (!replied(cli, cli->expect[i]))
            return false;
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

static bool log_followed(const cli_t *cli, const char *component)
{
    for (int i = 0; i < cli->nfollowed; i++)
        if (strcmp(cli->followed[i], component) == 0)
            return true;
    return false;
}

/* A component's own log line on stderr ("12:00:01.234 NAME info file.c:12: text") is not an
 * error: its level is the tag, and its time and name, which the line's stamp and the component
 * repeat, go. */
static const char *log_tag(const marie_log_line_t *l, const char **text)
{
    static const char *const levels[] = {"debug", "info", "warn", "error"};
    const char *t = l->text, *sp;
    *text = t;
    if (l->stream != MARIE_LOG_LINE_T_STDERR)
        return "out";
    if (strlen(t) > 13 && t[2] == ':' && t[5] == ':' && t[8] == '.' && t[12] == ' ' && (sp = strchr(t + 13, ' ')))
        for (size_t i = 0; i < sizeof levels / sizeof *levels; i++) {
            size_t n = strlen(levels[i]);
            if (strncmp(sp + 1, levels[i], n) == 0 && sp[1 + n] == ' ') {
                *text = sp + 2 + n;
                return levels[i];
            }
        }
    return "err";
}

static void print_follow(const cli_t *cli, const marie_log_line_t *l)
{
    const char *text, *tag = log_tag(l, &text);
    if (cli->json) {
        printf("{\"utime\":%lld,\"host\":", (long long)l->utime);
        marie_json_fputs(stdout, l->host);
        printf(",\"component\":");
        marie_json_fputs(stdout, l->component);
        printf(",\"pid\":%d,\"stream\":\"%s\",\"tag\":\"%s\",\"dropped\":%lld,\"text\":", (int)l->pid,
               l->stream == MARIE_LOG_LINE_T_STDERR ? "err" : "out", tag, (long long)l->dropped);
        marie_json_fputs(stdout, l->text);
        printf("}\n");
        return;
    }
    time_t secs = (time_t)(l->utime / 1000000);
    struct tm tm;
    gmtime_r(&secs, &tm);
    if (l->dropped)
        printf("-- %lld lines dropped (rate limit)\n", (long long)l->dropped);
    printf("%04d-%02d-%02dT%02d:%02d:%02d.%03dZ %s%s%s %s\n", tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday,
           tm.tm_hour, tm.tm_min, tm.tm_sec, (int)(l->utime / 1000 % 1000), cli->nfollowed > 1 ? l->component : "",
           cli->nfollowed > 1 ? " " : "", tag, text);
}

static void on_log(const lcm_recv_buf_t *rbuf, const char *channel, const marie_log_line_t *l, void *user)
{
    cli_t *cli = user;
    if (l->request_seq != 0) {
        /* an answer to our tail order: the manager chose the components (names and groups) */
        if (l->request_seq != cli->seq)
            return;
        cli->last_log_mono = marie_mono_us();
        if (cli->json) {
            printf("{\"host\":");
            marie_json_fputs(stdout, l->host);
            printf(",\"component\":");
            marie_json_fputs(stdout, l->component);
            printf(",\"text\":");
            marie_json_fputs(stdout, l->text);
            printf("}\n");
        } else if (cli->nlog_names > 1 || strcmp(cli->log_names[0], l->component) != 0) {
            printf("%s: %s\n", l->component, l->text);
        } else {
            printf("%s\n", l->text);
        }
    } else if (cli->follow && log_followed(cli, l->component)) {
        print_follow(cli, l);
    }
    fflush(stdout);
}

/* Handle bus traffic for up to ms milliseconds, or until done(cli) holds. */
bool pump(cli_t *cli, double seconds, bool (*done)(cli_t *))
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
        marie_loop_run_once(cli->loop, ms);
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

int cli_open(cli_t *cli)
{
    cli->lcm = marie_bus_create(cli->url);
    if (!cli->lcm) {
        fprintf(stderr, "marie: cannot open the bus %s\n", cli->url);
        return -1;
    }
    marie_bus_subscribe(cli->lcm, MARIE_CH_AM_STATUS, on_raw_status, cli);
    marie_bus_subscribe(cli->lcm, MARIE_CH_AM_REPLY, on_raw_reply, cli);
    marie_bus_subscribe(cli->lcm, MARIE_CH_LOG, on_raw_log, cli);
    if (!(cli->loop = marie_loop_create()) || marie_loop_add_bus(cli->loop, cli->lcm, 64) < 0) {
        fprintf(stderr, "marie: out of memory\n");
        return -1;
    }
    return 0;
}

int load_key(cli_t *cli)
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
int send_order(cli_t *cli, int op, char **targets, int ntargets, const char *arg,
                      const char *path, const char *text)
{
    if (load_key(cli) < 0)
        return MARIE_EXIT_AUTH;
    for (int attempt = 0; attempt < 2; attempt++) {
        cli->nreplies = 0;
        for (int i = 0; i < cli->nhosts; i++)
            cli->hosts[i].fresh = false;
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
            else if (strstr(r->reason, "system file refused:") == r->reason && rc != MARIE_EXIT_AUTH)
                rc = MARIE_EXIT_USAGE;   /* its file:line:col, as a check here would have said */
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

/* Not signed: it asks only for what the managers broadcast anyway, and each answers within a
 * rate limit. A manager that does not know the request is heard at its next periodic status. */
/* Every host named in the managers' status has answered. A manager without a system names no
 * hosts, so while one is heard the others may still be unknown: then the answers must also have
 * stopped bringing new hosts for PS_QUIET_US (they come within milliseconds of the request). */
#define PS_QUIET_US 150000
bool all_hosts_heard(cli_t *cli)
{
    for (int i = 0; i < cli->nexpect; i++) {
        host_t *h = host_get(cli, cli->expect[i], false);
        if (!h || !h->st)
            return false;
    }
    return cli->nexpect > 0 && (!cli->hosts_unnamed || marie_mono_us() - cli->new_host_mono >= PS_QUIET_US);
}

int request_status(cli_t *cli)
{
    char sender[256];
    marie_am_sender(sender, sizeof sender);
    marie_am_status_request_t rq = {.utime = marie_wall_us(), .sender = sender, .host = "*"};
    if (marie_am_status_request_t_publish(cli->lcm, MARIE_CH_AM_STATUS_REQUEST, &rq) < 0) {
        fprintf(stderr, "marie: cannot send the status request\n");
        return -1;
    }
    return 0;
}

void print_replies_json(cli_t *cli, int rc)
{
    printf("{\"ok\":%s,\"exit\":%d,\"replies\":[", rc == 0 ? "true" : "false", rc);
    for (int i = 0; i < cli->nreplies; i++) {
        printf("%s{\"host\":", i ? "," : "");
        marie_json_fputs(stdout, cli->replies[i].host);
        printf(",\"ok\":%s,\"affected\":%d,\"reason\":", cli->replies[i].ok ? "true" : "false",
               cli->replies[i].affected);
        marie_json_fputs(stdout, cli->replies[i].reason);
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

int wait_states(cli_t *cli, char **targets, int ntargets, bool running, double timeout)
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
