/* topic_main: marie-topic, run as `marie topic list|echo|hz|pub`: the bus's channels with their
 * types, rates and publishers, their messages decoded from the type descriptors, and messages
 * published from YAML (signed where the channel obeys only signed ones). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/auth.h"
#include "core/cli.h"
#include "core/component.h"
#include "core/bus/bus.h"
#include "core/spec.h"
#include "core/time.h"
#include "core/version.h"
#include "tools/topic/topic.h"
#include "tools/webcommon/vjson.h"

#define EXIT_USAGE 2
#define EXIT_TIMEOUT 3
#define MAX_CHANNELS 1024
#define HZ_WINDOW_MAX 10000

typedef struct {
    char name[LCM_MAX_CHANNEL_NAME_LENGTH + 1];
    int64_t fingerprint, msgs, bytes, first_us, last_us;
    char publishers[512];
} chan_t;

typedef struct {
    marie_loop_t *loop;
    lcm_t *lcm;
    const char *url, *system, *field, *key;
    int64_t count, window, seen;
    bool json, once, version;
    double duration, timeout, rate;
    marie_buf_t buf;
    chan_t *chans;
    size_t nchans;
    int64_t *stamps;            /* hz: receive times (monotonic us), a ring of `window` */
    int64_t nstamps, last_print;
    int status;
} topic_t;

static void usage(FILE *out)
{
    fprintf(out, "usage: marie topic list [--duration S] [--json]\n"
                 "       marie topic echo CHANNEL [--once] [--count N] [--field a.b[0].c] [--json] [--timeout S]\n"
                 "       marie topic hz CHANNEL [--window N] [--duration S]\n"
                 "       marie topic pub CHANNEL TYPE '{field: value, ...}' [--rate HZ] [--count N] [--key FILE]\n"
                 "common: [--url URL] [--system FILE] (its lcm_url and types:); users' types from MARIE_TYPES_PATH\n");
}

/* ---- the bus: the one place marie-topic opens and subscribes (core/bus/bus.h) ---- */

static int bus_open(topic_t *t)
{
    marie_errors_t errs = {0};
    marie_system_t *sys = t->system ? marie_system_load(t->system, NULL, &errs) : NULL;
    if ((t->system && !sys) || marie_system_load_types(sys, &errs) < 0) {
        marie_errors_print(&errs, stderr);
        marie_errors_clear(&errs);
        marie_system_destroy(sys);
        return -1;
    }
    if (!t->url)
        t->url = sys ? sys->lcm_url : marie_default_url();
    t->url = strdup(t->url);
    marie_system_destroy(sys);
    if (!t->url || !(t->lcm = marie_bus_create(t->url)) || !(t->loop = marie_loop_create()) ||
        marie_loop_add_bus(t->loop, t->lcm, 64) < 0) {
        fprintf(stderr, "marie topic: cannot open the bus %s\n", t->url ? t->url : "");
        return -1;
    }
    return 0;
}

/* A literal channel name as LCM's whole-name regular expression. */
static int subscribe(topic_t *t, const char *channel, bool literal, lcm_msg_handler_t cb)
{
    char re[2 * LCM_MAX_CHANNEL_NAME_LENGTH + 2];
    size_t k = 0;
    for (const char *p = channel; literal && *p && k + 2 < sizeof re; p++) {
        if (strchr(".[]()*+?{}|^$\\", *p))
            re[k++] = '\\';
        re[k++] = *p;
    }
    re[k] = 0;
    return marie_bus_subscribe(t->lcm, literal ? re : channel, cb, t) ? 0 : -1;
}

static void on_signal(marie_loop_t *loop, int signo, void *user) { marie_loop_quit(loop); }

static int run(topic_t *t, double seconds)
{
    marie_loop_catch_signals(t->loop, on_signal, t);
    int rc = marie_loop_run_until(t->loop, seconds > 0 ? (int)(seconds * 1000) : -1, NULL, NULL);
    return rc < 0 ? -1 : 0;
}

/* ---- list ---- */

static chan_t *chan_get(topic_t *t, const char *name)
{
    for (size_t i = 0; i < t->nchans; i++)
        if (strcmp(t->chans[i].name, name) == 0)
            return &t->chans[i];
    if (t->nchans == MAX_CHANNELS)
        return NULL;
    chan_t *c = &t->chans[t->nchans++];
    snprintf(c->name, sizeof c->name, "%s", name);
    return c;
}

static void note_publishers(topic_t *t, const void *data, size_t len)
{
    marie_heartbeat_t hb;
    if (marie_decode_checked(&marie_type_heartbeat_t, data, len, &hb) < 0)
        return;
    for (int i = 0; i < hb.nports; i++) {
        chan_t *c = hb.ports[i].direction == MARIE_PORT_STATUS_T_OUT ? chan_get(t, hb.ports[i].channel) : NULL;
        if (c && !strstr(c->publishers, hb.component)) {
            size_t used = strlen(c->publishers);
            snprintf(c->publishers + used, sizeof c->publishers - used, "%s%s", used ? "," : "", hb.component);
        }
    }
    marie_heartbeat_t_decode_cleanup(&hb);
}

static void on_any(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    topic_t *t = user;
    chan_t *c = chan_get(t, channel);
    if (!c)
        return;
    c->fingerprint = marie_payload_fingerprint(rb->data, rb->data_size);
    c->msgs++;
    c->bytes += rb->data_size;
    c->last_us = marie_mono_us();
    if (!c->first_us)
        c->first_us = c->last_us;
    if (strcmp(channel, MARIE_CH_HEARTBEAT) == 0)
        note_publishers(t, rb->data, rb->data_size);
}

static int cmp_chan(const void *a, const void *b) { return strcmp(((const chan_t *)a)->name, ((const chan_t *)b)->name); }

static void print_list(topic_t *t, double seconds)
{
    qsort(t->chans, t->nchans, sizeof *t->chans, cmp_chan);
    if (t->json)
        printf("[");
    else
        printf("%-24s %-28s %9s %11s %7s  %s\n", "CHANNEL", "TYPE", "HZ", "BYTES/S", "MSGS", "PUBLISHERS");
    int shown = 0;
    for (size_t i = 0; i < t->nchans; i++) {
        const chan_t *c = &t->chans[i];
        if (!c->msgs)
            continue;       /* named by a heartbeat only */
        const marie_typeinfo_t *ti = marie_typeinfo_by_fingerprint(c->fingerprint);
        char type[64];
        snprintf(type, sizeof type, "%s", ti ? ti->name : "?");
        double hz = c->msgs / seconds, bw = c->bytes / seconds;
        if (t->json) {
            printf("%s{\"channel\":", shown++ ? "," : "");
            marie_spec_json_str(stdout, c->name);
            printf(",\"type\":");
            marie_spec_json_str(stdout, ti ? ti->name : NULL);
            printf(",\"fingerprint\":\"%016llx\",\"hz\":%.3f,\"bytes_per_s\":%.1f,\"msgs\":%lld,\"publishers\":[",
                   (unsigned long long)c->fingerprint, hz, bw, (long long)c->msgs);
            char pubs[sizeof c->publishers], *save = NULL;
            snprintf(pubs, sizeof pubs, "%s", c->publishers);
            int k = 0;
            for (char *p = strtok_r(pubs, ",", &save); p; p = strtok_r(NULL, ",", &save)) {
                printf("%s", k++ ? "," : "");
                marie_spec_json_str(stdout, p);
            }
            printf("]}");
        } else {
            printf("%-24s %-28s %9.2f %11.0f %7lld  %s\n", c->name, type, hz, bw, (long long)c->msgs,
                   c->publishers[0] ? c->publishers : "-");
        }
    }
    if (t->json)
        printf("]\n");
}

static int cmd_list(topic_t *t)
{
    if (!(t->chans = calloc(MAX_CHANNELS, sizeof *t->chans)) || subscribe(t, ".*", false, on_any) < 0)
        return 1;
    if (run(t, t->duration) < 0)
        return 1;
    print_list(t, t->duration);
    return 0;
}

/* ---- echo ---- */

/* The node at a path such as "pose.x" or "ports[1].name" in a parsed message, or NULL. */
static const marie_node_t *node_at(const marie_node_t *n, const char *path)
{
    char name[128];
    while (n && *path) {
        size_t k = strcspn(path, ".[");
        snprintf(name, sizeof name, "%.*s", (int)k, path);
        path += k;
        if (k)
            n = marie_node_get(n, name);
        while (n && *path == '[') {
            long i = strtol(path + 1, (char **)&path, 10);
            if (*path != ']' || n->kind != MARIE_NODE_SEQ || i < 0 || (size_t)i >= n->n)
                return NULL;
            n = n->items[i];
            path++;
        }
        if (*path == '.')
            path++;
    }
    return n;
}

/* The message as JSON: {"channel", "t", "type", "k", "msg"[, "stride"]} in t->buf. */
static int message_json(topic_t *t, const char *channel, const lcm_recv_buf_t *rb, const marie_typeinfo_t *ti)
{
    marie_buf_reset(&t->buf);
    marie_buf_puts(&t->buf, "{\"channel\":");
    vj_str(&t->buf, channel);
    marie_buf_printf(&t->buf, ",\"t\":%lld,\"type\":", (long long)rb->recv_utime);
    vj_str(&t->buf, ti->name);
    if (vj_message(&t->buf, rb->data, rb->data_size, VJ_ROLE_OTHER) < 0)
        return -1;
    marie_buf_puts(&t->buf, "}");
    return t->buf.failed ? -1 : 0;
}

static void print_field(topic_t *t)
{
    marie_errors_t errs = {0};
    marie_doc_t *d = marie_doc_parse("message", t->buf.data, t->buf.len, &errs);
    const marie_node_t *n = d ? node_at(marie_node_get(marie_doc_root(d), "msg"), t->field) : NULL;
    if (!n) {
        fprintf(stderr, "marie topic: no field '%s' in this message\n", t->field);
        t->status = 1;
    } else if (n->kind == MARIE_NODE_SCALAR) {
        printf("%s\n", n->value);
    } else {
        char *text = marie_node_canonical(n);
        printf("%s\n", text ? text : "");
        free(text);
    }
    marie_doc_destroy(d);
    marie_errors_clear(&errs);
}

static void on_echo(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    topic_t *t = user;
    const marie_typeinfo_t *ti = marie_typeinfo_by_fingerprint(marie_payload_fingerprint(rb->data, rb->data_size));
    if (!ti) {
        printf("%s: %u bytes of an unknown type (fingerprint %016llx; MARIE_TYPES_PATH names users' types)\n",
               channel, rb->data_size, (unsigned long long)marie_payload_fingerprint(rb->data, rb->data_size));
    } else if (message_json(t, channel, rb, ti) < 0) {
        fprintf(stderr, "marie topic: %s: %u bytes: not a well-formed %s\n", channel, rb->data_size, ti->name);
        return;
    } else if (t->field) {
        print_field(t);
    } else if (t->json) {
        printf("%s\n", t->buf.data);
    } else {
        const char *m = strstr(t->buf.data, ",\"msg\":"), *s = m ? strstr(m, ",\"stride\":{") : NULL;
        printf("%s %s %.*s\n", channel, ti->name, m ? (int)((s ? s : t->buf.data + t->buf.len - 1) - m - 7) : 0,
               m ? m + 7 : "");
    }
    fflush(stdout);
    if (t->count && ++t->seen >= t->count)
        marie_loop_quit(t->loop);
}

static int cmd_echo(topic_t *t, const char *channel)
{
    if (t->once)
        t->count = 1;
    marie_buf_init(&t->buf, 64u << 20);
    if (subscribe(t, channel, true, on_echo) < 0 || run(t, t->timeout) < 0)
        return 1;
    if (t->count && t->seen < t->count) {
        fprintf(stderr, "marie topic: %lld message(s) on %s within %g s\n", (long long)t->seen, channel, t->timeout);
        return EXIT_TIMEOUT;
    }
    return t->status;
}

/* ---- hz ---- */

static void print_hz(topic_t *t, const char *channel)
{
    int64_t n = t->nstamps < t->window ? t->nstamps : t->window;
    if (n < 2) {
        printf("%s: no new messages\n", channel);
        return;
    }
    double sum = 0, sq = 0, lo = INFINITY, hi = 0;
    for (int64_t i = t->nstamps - n + 1; i < t->nstamps; i++) {
        double d = (t->stamps[i % t->window] - t->stamps[(i - 1) % t->window]) / 1e6;
        sum += d;
        sq += d * d;
        lo = d < lo ? d : lo;
        hi = d > hi ? d : hi;
    }
    double mean = sum / (double)(n - 1);
    printf("%s: average rate %.3f Hz\n\tmin: %.4f s max: %.4f s std dev: %.5f s window: %lld\n", channel, 1 / mean, lo, hi,
           sqrt(fmax(0, sq / (double)(n - 1) - mean * mean)), (long long)n);
    fflush(stdout);
}

static void on_hz(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    topic_t *t = user;
    t->stamps[t->nstamps++ % t->window] = marie_mono_us();
}

static void on_hz_print(marie_loop_t *loop, marie_timer_t *tm, int64_t overruns, void *user)
{
    topic_t *t = user;
    print_hz(t, t->field);
}

static int cmd_hz(topic_t *t, const char *channel)
{
    if (!(t->stamps = calloc((size_t)t->window, sizeof *t->stamps)) || subscribe(t, channel, true, on_hz) < 0)
        return 1;
    t->field = channel;
    if (!marie_loop_add_wall_timer(t->loop, 1000000, on_hz_print, t) || run(t, t->duration) < 0)
        return 1;
    return 0;
}

/* ---- pub ---- */

/* Orders that their receivers obey only signed: sign them with the key (fresh seq and utime). */
static int sign_payload(topic_t *t, const marie_type_t *type, marie_buf_t *b)
{
    bool cmd = type == &marie_type_lifecycle_command_t, order = type == &marie_type_am_order_t;
    if (!cmd && !order && type != &marie_type_goal_request_t)
        return 0;
    const char *key = t->key ? t->key : getenv("MARIE_KEY");
    char why[512] = "no key (--key FILE or MARIE_KEY)";
    marie_auth_t *a = key ? marie_auth_load(key, why, sizeof why) : NULL;
    if (!a) {
        fprintf(stderr, "marie topic: %s needs a signature: %s\n", type->name, why);
        return -1;
    }
    union { marie_lifecycle_command_t c; marie_am_order_t o; marie_goal_request_t g; } m;
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    int rc = marie_decode_checked(type, b->data, b->len, &m);
    int64_t now = marie_wall_us(), seq = marie_auth_next_seq(getenv("MARIE_SEQ_FILE"));
    char sender[64];
    snprintf(sender, sizeof sender, "marie-topic.%d", (int)getpid());
    /* What the decoder allocated is its to free: kept aside while the signed copy is sent. */
    bool decoded = rc == 0;
    __typeof__(m) theirs = m;
    if (rc == 0) {
        if (cmd) { m.c.utime = now; m.c.seq = seq; m.c.sender = sender; rc = marie_auth_sign_command(a, &m.c, mac); }
        else if (order) { m.o.utime = now; m.o.seq = seq; m.o.sender = sender; rc = marie_auth_sign_order(a, &m.o, mac); }
        else { m.g.utime = now; m.g.seq = seq; m.g.sender = sender; rc = marie_auth_sign_goal_request(a, &m.g, mac); }
    }
    int n = rc == 0 ? type->encoded_size(&m) : -1;
    marie_buf_reset(b);
    if (n < 0 || marie_buf_reserve(b, (size_t)n) < 0 || type->encode(b->data, 0, n, &m) < 0)
        rc = -1;
    b->len = n < 0 ? 0 : (size_t)n;
    if (decoded)
        type->decode_cleanup(&theirs);
    marie_auth_destroy(a);
    return rc;
}

typedef struct {
    topic_t *t;
    const char *channel, *text;
    const marie_type_t *type;
    const marie_typeinfo_t *ti;
} pub_t;

static int publish_once(pub_t *p)
{
    char why[512];
    if (topic_encode(p->ti, p->text, &p->t->buf, why, sizeof why) < 0) {
        fprintf(stderr, "marie topic: %s: %s\n", p->ti->name, why);
        return -1;
    }
    if (p->type && sign_payload(p->t, p->type, &p->t->buf) < 0)
        return -1;
    if (marie_bus_publish(p->t->lcm, p->channel, p->t->buf.data, (unsigned)p->t->buf.len) < 0) {
        fprintf(stderr, "marie topic: publish on %s: %s\n", p->channel, strerror(errno));
        return -1;
    }
    p->t->seen++;
    return 0;
}

static void on_pub_tick(marie_loop_t *loop, marie_timer_t *tm, int64_t overruns, void *user)
{
    pub_t *p = user;
    if (publish_once(p) < 0)
        p->t->status = 1;
    if (p->t->status || (p->t->count && p->t->seen >= p->t->count))
        marie_loop_quit(loop);
}

static int cmd_pub(topic_t *t, const char *channel, const char *type, const char *text)
{
    pub_t p = {t, channel, text, marie_type_find(type), marie_typeinfo_find(type)};
    if (!p.ti) {
        fprintf(stderr, "marie topic: no type named '%s' (users' types: MARIE_TYPES_PATH or --system)\n", type);
        return EXIT_USAGE;
    }
    marie_buf_init(&t->buf, 64u << 20);
    if (publish_once(&p) < 0)
        return 1;
    if (t->rate <= 0 || (t->count && t->seen >= t->count))
        return 0;
    if (!marie_loop_add_wall_timer(t->loop, (int64_t)(1e6 / t->rate), on_pub_tick, &p) || run(t, 0) < 0)
        return 1;
    return t->status;
}

int main(int argc, char **argv)
{
    topic_t t = {.duration = 2, .window = 100, .status = 0};
    const marie_cli_opt_t opts[] = {
        {"url", MARIE_CLI_STRING, &t.url, 0, 0, "URL the bus (default: the system file's, $LCM_DEFAULT_URL, marie's)"},
        {"system", MARIE_CLI_STRING, &t.system, 0, 0, "FILE a system file: its lcm_url and types:"},
        {"json", MARIE_CLI_FLAG, &t.json, 0, 0, "list, echo: JSON"},
        {"duration", MARIE_CLI_DOUBLE, &t.duration, 0.1, 1e9, "S list: listen S seconds (2); hz: stop after S"},
        {"once", MARIE_CLI_FLAG, &t.once, 0, 0, "echo: one message"},
        {"count", MARIE_CLI_INT, &t.count, 1, 1e12, "N echo: N messages; pub: N messages"},
        {"field", MARIE_CLI_STRING, &t.field, 0, 0, "PATH echo: only this field (pose.x, ports[0].name)"},
        {"timeout", MARIE_CLI_DOUBLE, &t.timeout, 0, 1e9, "S echo: give up after S seconds (exit 3)"},
        {"window", MARIE_CLI_INT, &t.window, 2, HZ_WINDOW_MAX, "N hz: intervals averaged (100)"},
        {"rate", MARIE_CLI_DOUBLE, &t.rate, 0, 1e6, "HZ pub: again at HZ until --count or Ctrl-C"},
        {"key", MARIE_CLI_STRING, &t.key, 0, 0, "FILE pub: the order key (default $MARIE_KEY)"},
        {"version", MARIE_CLI_FLAG, &t.version, 0, 0, "print the version"},
        {0},
    };
    if (argc > 1 && strcmp(argv[1], "--version") == 0) {
        printf("marie-topic %s\n", MARIE_VERSION);
        return 0;
    }
    if (argc > 1 && (strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0)) {
        usage(stdout);
        marie_cli_usage("marie topic VERB", opts, stdout);
        return 0;
    }
    const char *verb = argc > 1 ? argv[1] : NULL;
    int rc = marie_cli_parse("marie topic VERB", opts, argc - 1, argv + 1);
    if (rc >= 0) {
        if (rc == 0)
            usage(stdout);
        return rc;
    }
    if (t.version) {
        printf("marie-topic %s\n", MARIE_VERSION);
        return 0;
    }
    int nargs = argc - 1 - optind;
    char **args = argv + 1 + optind;
    if (!verb || (strcmp(verb, "list") != 0 && nargs < 1) || (strcmp(verb, "pub") == 0 && nargs != 3)) {
        usage(stderr);
        return EXIT_USAGE;
    }
    if (strcmp(verb, "list") && strcmp(verb, "echo") && strcmp(verb, "hz") && strcmp(verb, "pub")) {
        fprintf(stderr, "marie topic: unknown verb '%s'\n", verb);
        usage(stderr);
        return EXIT_USAGE;
    }
    if (bus_open(&t) < 0)
        return 1;
    if (strcmp(verb, "list") == 0)
        rc = cmd_list(&t);
    else if (strcmp(verb, "echo") == 0)
        rc = cmd_echo(&t, args[0]);
    else if (strcmp(verb, "hz") == 0)
        rc = cmd_hz(&t, args[0]);
    else
        rc = cmd_pub(&t, args[0], args[1], args[2]);
    marie_buf_free(&t.buf);
    free(t.chans);
    free(t.stamps);
    marie_loop_destroy(t.loop);
    marie_bus_destroy(t.lcm);
    free((char *)t.url);
    return rc;
}
