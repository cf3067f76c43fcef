/* test_xb_server: the XML bridge server over real TCP sockets and a real LCM bus: every type in
 * both directions, Mailbox pulls, slow clients, bad streams, stalls and many clients. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "adapters/xml_bridge/xb_codec.h"
#include "adapters/xml_bridge/xb_server.h"
#include "core/loop.h"
#include "core/time.h"
#include "lcmtypes/marie_types.h"
#include "tests/xml_bridge/xb_canon.h"

typedef struct {
    lcm_t *lcm;
    marie_loop_t *loop;
    xb_server_t *srv;
} env_t;

/* A test client: a socket, its own document parser, and the documents received so far. */
#define MAX_DOCS 8192
typedef struct {
    int fd;
    int eof;
    xb_doc_parser_t *p;
    char *docs[MAX_DOCS];       /* each document re-serialised as "name|attr=v|...|text" */
    marie_buf_t raw[MAX_DOCS];     /* and re-encodable: the document itself as received */
    int ndocs;
} cli_t;

static env_t env;

static void collect(void *user, xb_node_t *root)
{
    cli_t *c = user;
    if (c->ndocs >= MAX_DOCS)
        return;
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_puts(&b, root->name);
    for (const char **a = root->attrs; a && a[0]; a += 2)
        marie_buf_printf(&b, "|%s=%s", a[0], a[1]);
    marie_buf_put(&b, "", 1);
    c->docs[c->ndocs] = b.data;
    /* Keep the fields re-serialised so the test can encode them again. */
    marie_buf_t *r = &c->raw[c->ndocs];
    marie_buf_init(r, 0);
    for (const xb_node_t *n = root->first; n; n = n->next) {
        /* Minimal serialiser: enough for codec output (text leaves, item lists, base64). */
        struct { const xb_node_t *n; int state; } st[64];
        int sp = 0;
        st[sp].n = n;
        st[sp++].state = 0;
        while (sp > 0) {
            const xb_node_t *x = st[sp - 1].n;
            if (st[sp - 1].state == 0) {
                marie_buf_printf(r, "<%s", x->name);
                for (const char **a = x->attrs; a && a[0]; a += 2)
                    marie_buf_printf(r, " %s=\"%s\"", a[0], a[1]);
                marie_buf_puts(r, ">");
                xb_escape(r, x->text, x->text_len);
                st[sp - 1].state = 1;
                if (x->first && sp < 64) {
                    st[sp].n = x->first;
                    st[sp++].state = 0;
                }
                continue;
            }
            marie_buf_printf(r, "</%s>", x->name);
            sp--;
            if (sp > 0 && x->next) {
                st[sp].n = x->next;
                st[sp++].state = 0;
            }
        }
    }
    marie_buf_put(r, "", 1);
    c->ndocs++;
}

static int cli_connect(cli_t *c, int rcvbuf)
{
    memset(c, 0, sizeof *c);
    c->fd = socket(AF_INET, SOCK_STREAM, 0);
    assert_true(c->fd >= 0);
    if (rcvbuf)
        setsockopt(c->fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    struct sockaddr_in sa = { .sin_family = AF_INET, .sin_port = htons((uint16_t)xb_server_port(env.srv)) };
    sa.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(c->fd, (struct sockaddr *)&sa, sizeof sa) < 0)
        return -1;
    fcntl(c->fd, F_SETFL, O_NONBLOCK);
    c->p = xb_doc_parser_create(NULL, collect, c);
    return 0;
}

static void cli_free(cli_t *c)
{
    if (c->fd >= 0)
        close(c->fd);
    for (int i = 0; i < c->ndocs; i++) {
        free(c->docs[i]);
        marie_buf_free(&c->raw[i]);
    }
    xb_doc_parser_destroy(c->p);
    c->fd = -1;
    c->ndocs = 0;
}

static void cli_pump(cli_t *c)
{
    char buf[65536];
    for (;;) {
        ssize_t n = read(c->fd, buf, sizeof buf);
        if (n > 0) {
            xb_doc_parser_feed(c->p, buf, (size_t)n);
            continue;
        }
        if (n == 0 || (errno != EAGAIN && errno != EINTR))
            c->eof = 1;
        return;
    }
}

static void cli_send(cli_t *c, const char *s)
{
    size_t len = strlen(s), off = 0;
    while (off < len) {
        ssize_t n = write(c->fd, s + off, len - off);
        if (n < 0 && errno == EAGAIN) {
            marie_loop_run_once(env.loop, 1);
            cli_pump(c);
            continue;
        }
        assert_true(n > 0);
        off += (size_t)n;
    }
}

/* Runs the bridge until the client holds `ndocs` documents (or EOF), at most 5 s. */
static int cli_wait(cli_t *c, int ndocs)
{
    int64_t end = marie_mono_us() + 5000000;
    while (c->ndocs < ndocs && !c->eof && marie_mono_us() < end) {
        marie_loop_run_once(env.loop, 2);
        cli_pump(c);
    }
    return c->ndocs >= ndocs;
}

static int cli_wait_eof(cli_t *c)
{
    int64_t end = marie_mono_us() + 5000000;
    while (!c->eof && marie_mono_us() < end) {
        marie_loop_run_once(env.loop, 2);
        cli_pump(c);
    }
    return c->eof;
}

static void pump_ms(int ms)
{
    int64_t end = marie_mono_us() + ms * 1000;
    while (marie_mono_us() < end)
        marie_loop_run_once(env.loop, 2);
}

static int starts(const char *doc, const char *prefix)
{
    return strncmp(doc, prefix, strlen(prefix)) == 0;
}

static int setup_with(xb_server_cfg_t *cfg)
{
    env.lcm = lcm_create(NULL);
    env.loop = marie_loop_create();
    cfg->port = 0;
    cfg->handle_lcm = 1;
    env.srv = xb_server_create(cfg, env.lcm, env.loop, NULL);
    return env.lcm && env.loop && env.srv ? 0 : -1;
}

static int setup(void **state)
{
    xb_server_cfg_t cfg;
    xb_server_cfg_defaults(&cfg);
    return setup_with(&cfg);
}

static int teardown(void **state)
{
    xb_server_destroy(env.srv);
    marie_loop_destroy(env.loop);
    lcm_destroy(env.lcm);
    memset(&env, 0, sizeof env);
    return 0;
}

/* Raw LCM captures for the bridge -> bus direction. */
typedef struct {
    char channel[64];
    uint8_t *data;
    size_t len;
    int got;
} capture_t;

static void on_capture(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    capture_t *cap = user;
    free(cap->data);
    cap->data = malloc(rb->data_size);
    memcpy(cap->data, rb->data, rb->data_size);
    cap->len = rb->data_size;
    snprintf(cap->channel, sizeof cap->channel, "%s", channel);
    cap->got++;
}

static const marie_type_t *registry(const char *name)
{
    for (size_t i = 0; marie_types[i]; i++)
        if (strcmp(marie_types[i]->name, name) == 0)
            return marie_types[i];
    return NULL;
}

typedef struct {
    const marie_typeinfo_t *t;
    marie_buf_t *out;
    xb_error_t *err;
    int rc;
} reenc_t;

static void reencode(void *u, xb_node_t *root)
{
    reenc_t *ctx = u;
    ctx->rc = xb_encode(ctx->t, root, ctx->out, ctx->err);
}

static void test_every_type_both_directions(void **state)
{
    cli_t c;
    assert_int_equal(cli_connect(&c, 0), 0);
    assert_true(cli_wait(&c, 1));
    assert_true(starts(c.docs[0], "hello|protocol=1"));
    int expect = 1;
    for (size_t i = 0; marie_typeinfos[i]; i++) {
        const marie_typeinfo_t *t = marie_typeinfos[i];
        const marie_type_t *mt = registry(t->name);
        assert_non_null(mt);
        for (uint32_t seed = 1; seed <= 3; seed++) {
            /* client -> bridge -> bus: lcm-gen's decoder sees every field as sent */
            char ch[64];
            snprintf(ch, sizeof ch, "TO_BUS.%s", t->short_name);
            capture_t cap = { 0 };
            lcm_subscription_t *ls = lcm_subscribe(env.lcm, ch, on_capture, &cap);
            marie_buf_t xml;
            xb_canon_t want, got;
            marie_buf_init(&xml, 0);
            xb_canon_init(&want);
            xb_canon_init(&got);
            marie_buf_printf(&xml, "<publish channel=\"%s\" type=\"%s\" id=\"p%u\">", ch, t->name, seed);
            xb_sample(t, seed * 31u + (uint32_t)i, &xml, &want);
            marie_buf_puts(&xml, "</publish>\n");
            marie_buf_put(&xml, "", 1);
            cli_send(&c, xml.data);
            assert_true(cli_wait(&c, ++expect));
            if (!starts(c.docs[expect - 1], "ok|to=publish"))
                fail_msg("%s: %s", t->name, c.docs[expect - 1]);
            int64_t end = marie_mono_us() + 3000000;
            while (!cap.got && marie_mono_us() < end)
                marie_loop_run_once(env.loop, 5);
            assert_int_equal(cap.got, 1);
            void *msg = calloc(1, mt->size);
            assert_int_equal(mt->decode(cap.data, 0, (int)cap.len, msg), (int)cap.len);
            xb_struct_dump(&got, t->name, msg);
            if (strcmp(xb_canon_text(&want), xb_canon_text(&got)) != 0)
                fail_msg("%s to bus: want\n%s\ngot\n%s", t->name, xb_canon_text(&want), xb_canon_text(&got));
            lcm_unsubscribe(env.lcm, ls);

            /* bus -> bridge -> client: lcm-gen's encoding arrives with the same fields */
            snprintf(ch, sizeof ch, "TO_XML.%s", t->short_name);
            char sub[160];
            snprintf(sub, sizeof sub, "<subscribe channel=\"%s\" type=\"%s\"/>", ch, t->short_name);
            cli_send(&c, sub);
            assert_true(cli_wait(&c, ++expect));
            assert_true(starts(c.docs[expect - 1], "ok|to=subscribe"));
            lcm_publish(env.lcm, ch, cap.data, (unsigned)cap.len);
            assert_true(cli_wait(&c, ++expect));
            char head[128];
            snprintf(head, sizeof head, "message|channel=%s|type=%s", ch, t->name);
            if (!starts(c.docs[expect - 1], head))
                fail_msg("%s: %s", t->name, c.docs[expect - 1]);
            marie_buf_t back;
            xb_error_t err;
            marie_buf_init(&back, 0);
            /* Encode the received fields again and compare with the bus bytes. */
            marie_buf_t doc;
            marie_buf_init(&doc, 0);
            marie_buf_printf(&doc, "<m>%s</m>", c.raw[expect - 1].data);
            reenc_t ctx = { t, &back, &err, -1 };
            xb_doc_parser_t *dp = xb_doc_parser_create(NULL, reencode, &ctx);
            assert_int_equal(xb_doc_parser_feed(dp, doc.data, doc.len), 0);
            xb_doc_parser_destroy(dp);
            if (ctx.rc != 0)
                fail_msg("%s: %s %s\n%s", t->name, err.code, err.reason, doc.data);
            assert_int_equal(back.len, cap.len);
            assert_memory_equal(back.data, cap.data, cap.len);
            snprintf(sub, sizeof sub, "<unsubscribe channel=\"%s\"/>", ch);
            cli_send(&c, sub);
            assert_true(cli_wait(&c, ++expect));
            assert_true(starts(c.docs[expect - 1], "ok|to=unsubscribe"));

            mt->decode_cleanup(msg);
            free(msg);
            free(cap.data);
            marie_buf_free(&doc);
            marie_buf_free(&back);
            marie_buf_free(&xml);
            xb_canon_free(&want);
            xb_canon_free(&got);
        }
    }
    xb_server_stats_t st;
    xb_server_stats(env.srv, &st);
    assert_int_equal(st.subscriptions, 0);
    assert_int_equal(st.errors, 0);
    cli_free(&c);
}

static void test_pull_gives_the_latest_value(void **state)
{
    cli_t c;
    assert_int_equal(cli_connect(&c, 0), 0);
    cli_send(&c, "<pull channel=\"ODOM\" id=\"a\"/>"
                 "<subscribe channel=\"ODOM\" type=\"marie.odometry_t\" mode=\"latest\"/>"
                 "<pull channel=\"ODOM\" id=\"b\"/>");
    assert_true(cli_wait(&c, 4));
    assert_true(starts(c.docs[1], "error|code=not-subscribed"));
    assert_true(starts(c.docs[2], "ok|to=subscribe"));
    assert_true(starts(c.docs[3], "error|code=no-data"));
    for (int i = 1; i <= 5; i++) {
        marie_odometry_t m = { 0 };
        m.utime = i;
        m.distance = i * 1.5;
        uint8_t buf[256];
        int n = marie_odometry_t_encode(buf, 0, sizeof buf, &m);
        lcm_publish(env.lcm, "ODOM", buf, (unsigned)n);
    }
    pump_ms(200);
    cli_pump(&c);
    assert_int_equal(c.ndocs, 4);       /* latest mode: nothing streamed */
    cli_send(&c, "<pull channel=\"ODOM\" type=\"odometry_t\" id=\"c\"/>");
    assert_true(cli_wait(&c, 5));
    assert_true(starts(c.docs[4], "message|channel=ODOM|type=marie.odometry_t"));
    assert_non_null(strstr(c.docs[4], "|to=pull|id=c|age_us="));
    assert_non_null(strstr(c.raw[4].data, "<utime>5</utime>"));
    assert_non_null(strstr(c.raw[4].data, "<distance>7.5</distance>"));
    cli_free(&c);
}

static void test_semantic_errors_keep_the_connection(void **state)
{
    cli_t c;
    assert_int_equal(cli_connect(&c, 0), 0);
    cli_send(&c, "<publish channel=\"A\" type=\"marie.nope_t\"/>"
                 "<publish channel=\"A\" type=\"pose2d_t\"><x>abc</x></publish>"
                 "<publish channel=\"A\" type=\"pose2d_t\"><q>1</q></publish>"
                 "<publish type=\"pose2d_t\"/>"
                 "<publish channel=\"0123456789012345678901234567890123456789012345678901234567890123456789\" type=\"pose2d_t\"/>"
                 "<subscribe channel=\"A\"/>"
                 "<unsubscribe channel=\"NEVER\"/>"
                 "<frobnicate/>"
                 "<subscribe channel=\"A\" type=\"pose2d_t\" mode=\"sometimes\"/>"
                 "<ping id=\"still-here\"/>");
    assert_true(cli_wait(&c, 11));
    const char *want[] = { "hello", "error|code=unknown-type", "error|code=bad-value",
                           "error|code=unknown-field", "error|code=bad-request", "error|code=bad-channel",
                           "error|code=bad-request", "error|code=not-subscribed",
                           "error|code=unknown-request", "error|code=bad-request", "ok|to=ping|id=still-here" };
    for (int i = 0; i < 11; i++)
        if (!starts(c.docs[i], want[i]))
            fail_msg("doc %d: %s, want %s", i, c.docs[i], want[i]);
    assert_false(c.eof);
    cli_free(&c);
}

/* Publishes answered only on failure leave in batches: every one still reaches the bus, in
 * order, a bad one among them is answered before what follows it, and a stream that breaks after
 * some of them loses none of those before the break. */
typedef struct {
    double x[512];
    int n;
} seq_t;

static void on_seq(const lcm_recv_buf_t *rb, const char *channel, void *user)
{
    seq_t *q = user;
    marie_pose2d_t m;
    if (q->n < 512 && marie_pose2d_t_decode(rb->data, 0, (int)rb->data_size, &m) >= 0)
        q->x[q->n++] = m.x;
}

static void test_quiet_publishes_keep_order_and_lose_nothing(void **state)
{
    seq_t q = { .n = 0 };
    lcm_subscription_t *ls = lcm_subscribe(env.lcm, "SEQ", on_seq, &q);
    lcm_subscription_set_queue_capacity(ls, 512);
    cli_t c;
    assert_int_equal(cli_connect(&c, 0), 0);
    marie_buf_t b;
    marie_buf_init(&b, 0);
    for (int i = 0; i < 100; i++) {
        if (i == 50)
            marie_buf_puts(&b, "<publish channel=\"SEQ\" type=\"pose2d_t\" ack=\"false\" id=\"bad\"><x>no</x></publish>");
        marie_buf_printf(&b, "<publish channel=\"SEQ\" type=\"pose2d_t\" ack=\"false\"><x>%d</x></publish>", i);
    }
    marie_buf_puts(&b, "<publish channel=\"SEQ\" type=\"pose2d_t\" id=\"acked\"><x>100</x></publish><ping id=\"end\"/>");
    cli_send(&c, b.data);
    assert_true(cli_wait(&c, 4));
    assert_true(starts(c.docs[1], "error|code=bad-value|reason=x: not a real number in range|to=publish|id=bad"));
    assert_true(starts(c.docs[2], "ok|to=publish|id=acked"));
    assert_true(starts(c.docs[3], "ok|to=ping|id=end"));
    int64_t end = marie_mono_us() + 2000000;
    while (q.n < 101 && marie_mono_us() < end)
        marie_loop_run_once(env.loop, 2);
    assert_int_equal(q.n, 101);
    for (int i = 0; i <= 100; i++)
        assert_true(q.x[i] == i);

    /* Three good ones, then bytes that are not XML, in one write. */
    q.n = 0;
    b.len = 0;
    for (int i = 0; i < 3; i++)
        marie_buf_printf(&b, "<publish channel=\"SEQ\" type=\"pose2d_t\" ack=\"false\"><x>%d</x></publish>", i);
    marie_buf_puts(&b, "<a><b></a>");
    cli_send(&c, b.data);
    assert_true(cli_wait_eof(&c));
    assert_true(starts(c.docs[c.ndocs - 1], "error|code=malformed"));
    end = marie_mono_us() + 2000000;
    while (q.n < 3 && marie_mono_us() < end)
        marie_loop_run_once(env.loop, 2);
    assert_int_equal(q.n, 3);
    for (int i = 0; i < 3; i++)
        assert_true(q.x[i] == i);
    xb_server_stats_t st;
    xb_server_stats(env.srv, &st);
    assert_int_equal(st.published, 104);
    marie_buf_free(&b);
    lcm_unsubscribe(env.lcm, ls);
    cli_free(&c);
}

static void expect_closed_with(const char *input, const char *code)
{
    cli_t bad, good;
    assert_int_equal(cli_connect(&bad, 0), 0);
    assert_int_equal(cli_connect(&good, 0), 0);
    cli_send(&bad, input);
    assert_true(cli_wait_eof(&bad));
    assert_true(bad.ndocs >= 2);
    char want[64];
    snprintf(want, sizeof want, "error|code=%s", code);
    if (!starts(bad.docs[bad.ndocs - 1], want))
        fail_msg("%s: %s", input, bad.docs[bad.ndocs - 1]);
    cli_send(&good, "<ping/>");
    assert_true(cli_wait(&good, 2));
    assert_true(starts(good.docs[1], "ok|to=ping"));
    cli_free(&bad);
    cli_free(&good);
}

static int setup_small(void **state)
{
    xb_server_cfg_t cfg;
    xb_server_cfg_defaults(&cfg);
    cfg.max_document = 4096;
    cfg.max_depth = 8;
    cfg.stall_ms = 300;
    cfg.max_clients = 200;
    return setup_with(&cfg);
}

static void test_bad_streams_close_only_their_client(void **state)
{
    expect_closed_with("<ping/><a><b></a>", "malformed");
    expect_closed_with("<ping/><a>\xc3\x28</a>", "malformed");
    expect_closed_with("<!DOCTYPE x [<!ENTITY a \"aaaaaaaaaa\">]><x>&a;</x>", "malformed");
    expect_closed_with("<a><a><a><a><a><a><a><a><a><a></a></a></a></a></a></a></a></a></a></a>", "too-deep");
    char big[6000];
    memset(big, 'x', sizeof big);
    memcpy(big, "<publish channel=\"A\" type=\"event_t\"><text>", 42);
    big[sizeof big - 1] = '\0';
    expect_closed_with(big, "too-large");
    /* Half a document, then silence: closed after stall_ms while others are served. */
    expect_closed_with("<publish channel=\"A\" type=\"pose2d_t\"><x>1", "stalled");
    xb_server_stats_t st;
    xb_server_stats(env.srv, &st);
    assert_int_equal(st.closed_bad, 6);
}

static int setup_tiny_message(void **state)
{
    xb_server_cfg_t cfg;
    xb_server_cfg_defaults(&cfg);
    cfg.max_message = 64;
    cfg.max_document = 4096;
    return setup_with(&cfg);
}

/* too-large names two limits: a message over max_message refuses the request only, a document
 * over max_document closes the stream (the rest of it cannot be told from the next document). */
static void test_too_large_message_keeps_the_connection(void **state)
{
    cli_t c;
    assert_int_equal(cli_connect(&c, 0), 0);
    char doc[600];
    snprintf(doc, sizeof doc, "<publish channel=\"A\" type=\"event_t\" id=\"big\"><text>%0200d</text>"
             "</publish><ping id=\"after\"/>", 7);
    cli_send(&c, doc);
    assert_true(cli_wait(&c, 3));
    assert_true(starts(c.docs[1], "error|code=too-large"));
    assert_non_null(strstr(c.docs[1], "|to=publish|id=big"));
    assert_true(starts(c.docs[2], "ok|to=ping|id=after"));
    assert_false(c.eof);
    cli_free(&c);
    char big[6000];
    memset(big, 'x', sizeof big);
    memcpy(big, "<ping><x>", 9);
    big[sizeof big - 1] = '\0';
    expect_closed_with(big, "too-large");
}

static void test_hundreds_of_clients_and_the_rest_refused(void **state)
{
    enum { N = 240 };
    static cli_t cs[N];
    int refused = 0, served = 0;
    for (int i = 0; i < N; i++) {
        assert_int_equal(cli_connect(&cs[i], 0), 0);
        marie_loop_run_once(env.loop, 0);
    }
    for (int i = 0; i < N; i++) {
        assert_true(cli_wait(&cs[i], 1) || cs[i].eof);
        if (cs[i].ndocs && starts(cs[i].docs[0], "error|code=busy")) {
            assert_true(cli_wait_eof(&cs[i]));
            refused++;
            continue;
        }
        cli_send(&cs[i], "<subscribe channel=\"MANY\" type=\"pose2d_t\"/>");
    }
    assert_int_equal(refused, N - 200);
    marie_pose2d_t m = { 1, 2, 3 };
    uint8_t buf[64];
    int n = marie_pose2d_t_encode(buf, 0, sizeof buf, &m);
    pump_ms(100);
    lcm_publish(env.lcm, "MANY", buf, (unsigned)n);
    for (int i = 0; i < N; i++) {
        if (cs[i].eof)
            continue;
        assert_true(cli_wait(&cs[i], 3));
        assert_true(starts(cs[i].docs[2], "message|channel=MANY"));
        served++;
    }
    assert_int_equal(served, 200);
    for (int i = 0; i < N; i++)
        cli_free(&cs[i]);
    xb_server_stats_t st;
    int64_t end = marie_mono_us() + 5000000;    /* the bridge sees every close (a loaded CPU is slow) */
    do {
        marie_loop_run_once(env.loop, 2);
        xb_server_stats(env.srv, &st);
    } while (st.clients > 0 && marie_mono_us() < end);
    assert_int_equal(st.clients, 0);
    assert_int_equal(st.subscriptions, 0);
}

static int setup_slow(void **state)
{
    xb_server_cfg_t cfg;
    xb_server_cfg_defaults(&cfg);
    cfg.queue = 32;
    cfg.sndbuf = 4096;
    return setup_with(&cfg);
}

static void test_slow_client_loses_oldest_and_never_blocks(void **state)
{
    cli_t slow, fast;
    assert_int_equal(cli_connect(&slow, 2048), 0);
    assert_int_equal(cli_connect(&fast, 1 << 20), 0);
    cli_send(&slow, "<subscribe channel=\"POSE\" type=\"pose_cov_t\"/>");
    cli_send(&fast, "<subscribe channel=\"POSE\" type=\"pose_cov_t\"/>");
    assert_true(cli_wait(&fast, 2));
    pump_ms(50);
    enum { N = 2000 };
    marie_pose_cov_t m = { 0 };
    m.frame = (char *)"map";
    uint8_t buf[512];
    for (int i = 0; i < N; i++) {
        m.utime = i;
        int n = marie_pose_cov_t_encode(buf, 0, sizeof buf, &m);
        lcm_publish(env.lcm, "POSE", buf, (unsigned)n);
        if (i % 8 == 7) {
            /* In small bursts so only the slow client (which reads nothing) falls behind. */
            xb_server_stats_t now;
            int64_t until = marie_mono_us() + 200000;
            do {
                marie_loop_run_once(env.loop, 1);
                cli_pump(&fast);
                xb_server_stats(env.srv, &now);
            } while (now.received < (uint64_t)i + 1 && marie_mono_us() < until);
            marie_loop_run_once(env.loop, 0);
            cli_pump(&fast);
        }
    }
    int64_t until = marie_mono_us() + 500000;
    while (marie_mono_us() < until) {
        marie_loop_run_once(env.loop, 2);
        cli_pump(&fast);
    }
    xb_server_stats_t st;
    xb_server_stats(env.srv, &st);
    assert_true(st.received > N / 2);
    assert_int_equal(fast.ndocs, 2 + (int)st.received);    /* the fast client lost nothing */
    assert_true(st.dropped > 0);
    /* Now the slow client reads: a notice counts what it lost, then the newest messages. */
    int64_t end = marie_mono_us() + 2000000;
    while (marie_mono_us() < end) {
        marie_loop_run_once(env.loop, 2);
        cli_pump(&slow);
    }
    int notices = 0, msgs = 0;
    long long lost = 0, told = 0;
    for (int i = 0; i < slow.ndocs; i++) {
        if (starts(slow.docs[i], "dropped|count=")) {
            /* Each notice counts what was lost since the previous one the client got. */
            long long count = atoll(slow.docs[i] + strlen("dropped|count="));
            const char *t = strstr(slow.docs[i], "|total=");
            assert_non_null(t);
            long long total = atoll(t + strlen("|total="));
            if (count != total - told)
                fail_msg("notice %d: count %lld, but %lld lost since the last notice (total %lld)",
                         notices, count, total - told, total);
            assert_true(count > 0);
            told = total;
            notices++;
            lost += count;
        } else if (starts(slow.docs[i], "message")) {
            msgs++;
        }
    }
    assert_true(notices >= 1);
    assert_int_equal(lost + msgs, (long long)st.received);
    assert_non_null(strstr(slow.raw[slow.ndocs - 1].data, "<utime>1999</utime>"));
    cli_free(&slow);
    cli_free(&fast);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_every_type_both_directions, setup, teardown),
        cmocka_unit_test_setup_teardown(test_pull_gives_the_latest_value, setup, teardown),
        cmocka_unit_test_setup_teardown(test_semantic_errors_keep_the_connection, setup, teardown),
        cmocka_unit_test_setup_teardown(test_quiet_publishes_keep_order_and_lose_nothing, setup, teardown),
        cmocka_unit_test_setup_teardown(test_bad_streams_close_only_their_client, setup_small, teardown),
        cmocka_unit_test_setup_teardown(test_too_large_message_keeps_the_connection, setup_tiny_message, teardown),
        cmocka_unit_test_setup_teardown(test_hundreds_of_clients_and_the_rest_refused, setup_small, teardown),
        cmocka_unit_test_setup_teardown(test_slow_client_loses_oldest_and_never_blocks, setup_slow, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
