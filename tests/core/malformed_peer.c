/* malformed_peer: feeds running components every kind of malformed payload on their input ports
 * (pushed, and served as pull replies) and checks their heartbeats count each one while their
 * outputs stay sane. Used by tests/core/test_malformed_inputs.sh.
 *
 *   malformed_peer SPEC_FILE SECONDS
 *
 * SPEC_FILE lines (whitespace separated, '#' comments):
 *   in   COMPONENT TYPE CHANNEL push|pull   an input port (pull: answer CHANNEL.PULL requests);
 *        COMPONENT "*": an input of every component (pushed only)
 *   out  COMPONENT TYPE CHANNEL finite|zero|silent
 *        finite: every message well formed and finite; zero: also nothing moves (motor
 *        commands v = omega = 0, wheel velocities below 1e-3 rad/s); silent: nothing at all
 *   empty COMPONENT CHANNEL                 after the run a pull of CHANNEL must answer EMPTY
 * Prints one "ok: ..." or "FAIL: ..." line per component; exit 0 when all are ok. */
#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <poll.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <lcm/lcm.h>

#include "core/config.h"
#include "core/time.h"
#include "core/typeinfo.h"

#define MAXC 32
#define MAXP 256
#define BATCH 12          /* per port and round: well below LCM's 30-deep subscription queue */

typedef struct {
    uint8_t *data;
    size_t len;
} blob_t;

typedef struct {
    blob_t *v;
    size_t n, cap;
} variants_t;

typedef struct {
    char name[64];
    bool seen, running, dead;
    int state, pid;
    char reason[160];
    int64_t bad_input, late, hb_count;
    int64_t sent, served, garbage;  /* malformed payloads that must each be counted once */
    bool has_pull;
    char reply_channel[128];
    char fail[512];
} comp_t;

typedef struct {
    comp_t *c;
    const marie_type_t *t;
    char channel[128];
    char mode[16];
    bool in, pull;
    variants_t var;
    size_t next;
    int64_t outputs, last_request;
} port_t;

static comp_t comps[MAXC];
static int ncomps;
static port_t ports[MAXP];
static int nports;
static lcm_t *lcm;

static void failf(comp_t *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void failf(comp_t *c, const char *fmt, ...)
{
    if (c->fail[0])
        return;     /* the first failure says most */
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->fail, sizeof c->fail, fmt, ap);
    va_end(ap);
}

static comp_t *comp(const char *name)
{
    for (int i = 0; i < ncomps; i++)
        if (strcmp(comps[i].name, name) == 0)
            return &comps[i];
    if (ncomps == MAXC)
        return NULL;
    comp_t *c = &comps[ncomps++];
    snprintf(c->name, sizeof c->name, "%s", name);
    return c;
}

/* ---- a well-formed sample of any type, with the places worth breaking ---- */

enum { SITE_COUNT, SITE_STRLEN, SITE_FLOAT, SITE_DOUBLE };
typedef struct {
    size_t off;
    int kind;
} site_t;

typedef struct {
    uint8_t buf[1 << 16];
    size_t len;
    site_t sites[512];
    int nsites;
} sample_t;

static void put_be(uint8_t *p, uint64_t v, int n)
{
    for (int i = n - 1; i >= 0; i--, v >>= 8)
        p[i] = (uint8_t)v;
}

static int put(sample_t *s, uint64_t v, int n, int kind)
{
    if (s->len + (size_t)n > sizeof s->buf)
        return -1;
    if (kind >= 0 && s->nsites < 512)
        s->sites[s->nsites++] = (site_t){s->len, kind};
    put_be(s->buf + s->len, v, n);
    s->len += (size_t)n;
    return 0;
}

static bool is_count(const marie_typeinfo_t *t, int i)
{
    for (int j = i + 1; j < t->nfields; j++)
        for (int d = 0; d < t->fields[j].ndims; d++)
            if (t->fields[j].dims[d].len_field == i)
                return true;
    return false;
}

/* Integers 1 (counts 2), floats 1.0, strings "ab". */
static int gen_struct(const marie_typeinfo_t *t, sample_t *s, int depth)
{
    int64_t values[256] = {0};
    for (int i = 0; i < t->nfields && depth < 8; i++) {
        const marie_tfield_t *f = &t->fields[i];
        int64_t count = 1;
        for (int d = 0; d < f->ndims; d++)
            count *= f->dims[d].len_field >= 0 ? values[f->dims[d].len_field] : f->dims[d].size;
        for (int64_t k = 0; k < count; k++) {
            int rc = 0;
            switch (f->prim) {
            case MARIE_PRIM_INT8: case MARIE_PRIM_BYTE: case MARIE_PRIM_BOOL: rc = put(s, 1, 1, -1); break;
            case MARIE_PRIM_INT16: rc = put(s, 1, 2, -1); break;
            case MARIE_PRIM_INT32: case MARIE_PRIM_INT64: {
                bool cnt = f->ndims == 0 && is_count(t, i);
                if (f->ndims == 0 && i < 256)
                    values[i] = cnt ? 2 : 1;
                rc = put(s, cnt ? 2 : 1, f->prim == MARIE_PRIM_INT32 ? 4 : 8, cnt ? SITE_COUNT : -1);
                break;
            }
            /* A field that gives NaN a meaning (a laser's ranges, REP 117) is no place to lie. */
            case MARIE_PRIM_FLOAT:
                rc = put(s, 0x3f800000u, 4, k == 0 && !(f->flags & MARIE_TFIELD_NONFINITE) ? SITE_FLOAT : -1);
                break;
            case MARIE_PRIM_DOUBLE: rc = put(s, 0x3ff0000000000000ull, 8, k == 0 ? SITE_DOUBLE : -1); break;
            case MARIE_PRIM_STRING:
                rc = put(s, 3, 4, SITE_STRLEN);
                rc = rc ? rc : put(s, 0x616200, 3, -1);
                break;
            case MARIE_PRIM_STRUCT: rc = gen_struct(f->sub, s, depth + 1); break;
            }
            if (rc < 0)
                return -1;
        }
    }
    return 0;
}

static uint64_t rng = 0x9e3779b97f4a7c15ull;
static uint64_t rnd(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return rng;
}

static void add(variants_t *v, const void *data, size_t len)
{
    if (v->n == v->cap) {
        v->cap = v->cap ? 2 * v->cap : 64;
        v->v = realloc(v->v, v->cap * sizeof *v->v);
    }
    v->v[v->n].data = malloc(len ? len : 1);
    memcpy(v->v[v->n].data, data, len);
    v->v[v->n++].len = len;
}

/* A copy of the sample with n bytes at off replaced by value. */
static void add_patched(variants_t *v, const sample_t *s, size_t off, uint64_t value, int n)
{
    uint8_t *b = malloc(s->len);
    memcpy(b, s->buf, s->len);
    put_be(b + off, value, n);
    add(v, b, s->len);
    free(b);
}

/* Every malformed variant of type t: wrong fingerprint, truncations, trailing bytes, lying
 * counts and string lengths, a string without its NUL, NaN and infinities, random bytes. */
static int make_variants(const marie_type_t *t, variants_t *v)
{
    static sample_t s;
    memset(&s, 0, sizeof s);
    const marie_typeinfo_t *ti = marie_typeinfo_by_fingerprint(t->hash());
    if (!ti || put(&s, (uint64_t)ti->fingerprint, 8, -1) < 0 || gen_struct(ti, &s, 0) < 0)
        return -1;
    if (marie_typeinfo_check(ti, s.buf, s.len) != 0)
        return -1;      /* the generator itself is wrong */
    add_patched(v, &s, 7, s.buf[7] ^ 0x01, 1);
    const marie_type_t *other = marie_types[0] == t ? marie_types[1] : marie_types[0];
    uint8_t fp[16];
    put_be(fp, (uint64_t)other->hash(), 8);
    memcpy(fp + 8, s.buf + 8, 8);
    add(v, fp, s.len >= 16 ? 16 : 8);
    size_t cuts[] = {0, 4, 7, 8, s.len / 2, s.len - 1};
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++)
        if (cuts[i] < s.len)
            add(v, s.buf, cuts[i]);
    uint8_t *longer = calloc(1, s.len + 3);
    memcpy(longer, s.buf, s.len);
    add(v, longer, s.len + 3);
    free(longer);
    int nfloat = 0;
    for (int i = 0; i < s.nsites; i++) {
        const site_t *st = &s.sites[i];
        if (st->kind == SITE_COUNT) {
            uint32_t lies[] = {0x7fffffffu, 0xffffffffu, 0x80000000u, 3, 0x10000};
            for (size_t k = 0; k < 5; k++)
                add_patched(v, &s, st->off, lies[k], 4);
        } else if (st->kind == SITE_STRLEN) {
            uint32_t lies[] = {(uint32_t)-7, 0x7fffffffu, 0, 4, 0x10000};
            for (size_t k = 0; k < 5; k++)
                add_patched(v, &s, st->off, lies[k], 4);
            add_patched(v, &s, st->off + 6, 'x', 1);    /* "ab" without its NUL */
        } else if (nfloat++ < 16) {
            bool d = st->kind == SITE_DOUBLE;
            uint64_t bad[3] = {d ? 0x7ff8000000000000ull : 0x7fc00000u, d ? 0x7ff0000000000000ull : 0x7f800000u,
                               d ? 0xfff0000000000000ull : 0xff800000u};
            for (int k = 0; k < 3; k++)
                add_patched(v, &s, st->off, bad[k], d ? 8 : 4);
        }
    }
    uint8_t r[300];
    for (int k = 0; k < 6; k++) {
        size_t n = 1 + rnd() % (sizeof r - 1);
        for (size_t i = 0; i < n; i++)
            r[i] = (uint8_t)rnd();
        if (k >= 3 && n >= 8) {
            memcpy(r, s.buf, 8);    /* the right fingerprint, then noise */
            if (n == s.len)
                n--;
        }
        add(v, r, n);
    }
    /* Every variant must be one the checker refuses, or the expected counts are wrong. */
    size_t kept = 0;
    for (size_t i = 0; i < v->n; i++) {
        if (marie_typeinfo_check_flags(ti, v->v[i].data, v->v[i].len, MARIE_CHECK_FINITE) == 0) {
            free(v->v[i].data);
            continue;
        }
        v->v[kept++] = v->v[i];
    }
    v->n = kept;
    return 0;
}

/* ---- bus ---- */

static void on_heartbeat(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    marie_heartbeat_t hb;
    if (marie_decode_checked(&marie_type_heartbeat_t, rb->data, rb->data_size, &hb) < 0)
        return;
    for (int i = 0; i < ncomps; i++) {
        comp_t *c = &comps[i];
        if (strcmp(c->name, hb.component) != 0)
            continue;
        c->seen = true;
        c->state = hb.state;
        c->pid = hb.pid;
        c->running = hb.state == MARIE_LIFECYCLE_COMMAND_T_STATE_RUNNING;
        c->dead = hb.state == MARIE_LIFECYCLE_COMMAND_T_STATE_EXITED || hb.state == MARIE_LIFECYCLE_COMMAND_T_STATE_FAILED;
        snprintf(c->reason, sizeof c->reason, "%s", hb.reason);
        c->bad_input = hb.bad_input;
        c->late = 0;
        for (int k = 0; k < hb.ncounters; k++)
            if (strcmp(hb.counters[k].name, "late_pull_replies") == 0)
                c->late = hb.counters[k].value;
        c->hb_count++;
        snprintf(c->reply_channel, sizeof c->reply_channel, "MARIE_REPLY.%.60s.%d", hb.component, hb.pid);
    }
    marie_heartbeat_t_decode_cleanup(&hb);
}

static void publish_reply(const char *channel, int64_t id, const char *of, int8_t status, const blob_t *b)
{
    marie_pull_reply_t r = {.utime = marie_wall_us(), .request_id = id, .channel = (char *)of, .status = status,
                            .data = (uint8_t *)""};
    if (b) {
        r.fingerprint = marie_payload_fingerprint(b->data, b->len);
        r.size = (int32_t)b->len;
        r.data = b->len ? b->data : (uint8_t *)"";
    }
    int n = marie_pull_reply_t_encoded_size(&r);
    uint8_t *buf = malloc((size_t)n);
    if (marie_pull_reply_t_encode(buf, 0, n, &r) == n)
        lcm_publish(lcm, channel, buf, (unsigned)n);
    free(buf);
}

static bool serving = true;

static void on_pull(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    port_t *p = user;
    marie_pull_request_t q;
    if (marie_decode_checked(&marie_type_pull_request_t, rb->data, rb->data_size, &q) < 0)
        return;
    p->last_request = marie_mono_us();
    if (serving && p->next < p->var.n) {
        publish_reply(q.reply_channel, q.request_id, p->channel, MARIE_PULL_REPLY_T_STATUS_OK, &p->var.v[p->next++]);
        p->c->served++;
    } else {
        publish_reply(q.reply_channel, q.request_id, p->channel, MARIE_PULL_REPLY_T_STATUS_EMPTY, NULL);
    }
    marie_pull_request_t_decode_cleanup(&q);
}

static void on_output(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    port_t *p = user;
    p->outputs++;
    if (strcmp(p->mode, "silent") == 0) {
        failf(p->c, "published %u bytes on %s from malformed input only", rb->data_size, ch);
        return;
    }
    void *m = calloc(1, p->t->size);
    const char *why;
    if (!m)
        return;
    if (marie_decode_input(p->t, rb->data, rb->data_size, m, &why) < 0) {
        failf(p->c, "published a message on %s that its receivers drop (%s)", ch, why);
    } else {
        const marie_motor_command_t *mc = m;
        const marie_wheel_encoders_t *we = m;
        bool zero = strcmp(p->mode, "zero") == 0;
        if (zero && p->t == &marie_type_motor_command_t && (mc->v != 0 || mc->omega != 0))
            failf(p->c, "commanded v=%g omega=%g on %s with no valid input", mc->v, mc->omega, ch);
        if (zero && p->t == &marie_type_wheel_encoders_t && (fabs(we->left_velocity) > 1e-3 || fabs(we->right_velocity) > 1e-3))
            failf(p->c, "wheels turn (%g, %g rad/s) on %s with no valid command", we->left_velocity, we->right_velocity, ch);
        p->t->decode_cleanup(m);
    }
    free(m);
}

static void spin(int64_t ms)
{
    int64_t end = marie_mono_us() + ms * 1000;
    int64_t left;
    while ((left = end - marie_mono_us()) > 0) {
        struct pollfd pfd = {lcm_get_fileno(lcm), POLLIN, 0};
        if (poll(&pfd, 1, (int)(left / 1000) + 1) > 0)
            lcm_handle(lcm);
    }
}

/* Spin until pred holds for every component (or seconds pass); true if it did. */
static bool wait_all(bool (*pred)(comp_t *), double seconds)
{
    int64_t end = marie_mono_us() + (int64_t)(seconds * 1e6);
    for (;;) {
        bool all = true;
        for (int i = 0; i < ncomps; i++)
            all = all && (comps[i].fail[0] || pred(&comps[i]));
        if (all)
            return true;
        if (marie_mono_us() > end)
            return false;
        spin(20);
    }
}

/* Components start with nothing counted, and every malformed payload must be counted once;
 * a pull reply that came after its requester gave up is counted as late instead (the peer
 * cannot tell which of the late ones were malformed, so they widen the range downwards). */
static int64_t expected(const comp_t *c) { return c->sent + c->served + c->garbage; }
static bool is_running(comp_t *c) { return c->running || c->dead; }
static bool sent_counted(comp_t *c) { return c->dead || c->bad_input >= c->sent; }
static bool all_counted(comp_t *c) { return c->dead || c->bad_input >= expected(c) - c->late; }

/* Every malformed payload served, or the port left alone for 2 s (some are pulled once, at start). */
static bool pulls_done(comp_t *c)
{
    for (int i = 0; i < nports; i++) {
        const port_t *p = &ports[i];
        if (p->c == c && p->pull && p->next < p->var.n && marie_mono_us() - p->last_request < 2000000)
            return false;
    }
    return true;
}

/* Malformed pull replies: the reply channel's own decoder is an input too. */
static void send_garbage_replies(comp_t *c)
{
    uint8_t buf[64];
    memset(buf, 0xee, sizeof buf);
    lcm_publish(lcm, c->reply_channel, buf, sizeof buf);
    put_be(buf, (uint64_t)marie_type_pull_reply_t.hash(), 8);
    lcm_publish(lcm, c->reply_channel, buf, 20);                  /* truncated */
    lcm_publish(lcm, c->reply_channel, buf, 8);
    c->garbage += 3;
}

static int load_spec(const char *path)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        perror(path);
        return -1;
    }
    char line[512], kind[16], name[64], type[64], channel[128], mode[16];
    while (fgets(line, sizeof line, f)) {
        if (line[0] == '#' || sscanf(line, "%15s", kind) != 1)
            continue;
        port_t *p = &ports[nports];
        int n = sscanf(line, "%15s %63s %63s %127s %15s", kind, name, type, channel, mode);
        bool empty = strcmp(kind, "empty") == 0;
        bool all = strcmp(name, "*") == 0;     /* an input every component has */
        if (nports == MAXP || (empty ? n < 3 : n < 5) || (all ? (empty || strcmp(kind, "in") != 0)
                                                              : !(p->c = comp(name)))) {
            fprintf(stderr, "malformed_peer: bad spec line: %s", line);
            fclose(f);
            return -1;
        }
        if (empty) {
            snprintf(p->channel, sizeof p->channel, "%s", type);
            snprintf(p->mode, sizeof p->mode, "empty");
            nports++;
            continue;
        }
        p->t = marie_type_find(type);
        if (!p->t) {
            fprintf(stderr, "malformed_peer: unknown type %s\n", type);
            fclose(f);
            return -1;
        }
        snprintf(p->channel, sizeof p->channel, "%s", channel);
        snprintf(p->mode, sizeof p->mode, "%s", mode);
        p->in = strcmp(kind, "in") == 0;
        p->pull = p->in && !all && strcmp(mode, "pull") == 0;
        if (p->c)
            p->c->has_pull = p->c->has_pull || p->pull;
        if (p->in && make_variants(p->t, &p->var) < 0) {
            fprintf(stderr, "malformed_peer: cannot make a sample of %s\n", type);
            fclose(f);
            return -1;
        }
        nports++;
    }
    fclose(f);
    return 0;
}

static void subscribe_all(void)
{
    lcm_subscribe(lcm, "MARIE_HEARTBEAT", on_heartbeat, NULL);
    for (int i = 0; i < nports; i++) {
        port_t *p = &ports[i];
        char ch[160];
        if (p->pull) {
            snprintf(ch, sizeof ch, "%s.PULL", p->channel);
            lcm_subscription_t *s = lcm_subscribe(lcm, ch, on_pull, p);
            lcm_subscription_set_queue_capacity(s, 1000);
        } else if (!p->in && strcmp(p->mode, "empty") != 0) {
            lcm_subscription_t *s = lcm_subscribe(lcm, p->channel, on_output, p);
            lcm_subscription_set_queue_capacity(s, 1000);
        }
    }
}

/* Pushes: in rounds of BATCH per port, each round waiting until the heartbeats have counted it. */
static void push_all(void)
{
    for (bool more = true; more;) {
        more = false;
        for (int k = 0; k < BATCH; k++) {
            for (int i = 0; i < nports; i++) {
                port_t *p = &ports[i];
                if (!p->in || p->pull || p->next >= p->var.n || (p->c && (p->c->fail[0] || p->c->dead)))
                    continue;
                const blob_t *b = &p->var.v[p->next++];
                lcm_publish(lcm, p->channel, b->data, (unsigned)b->len);
                for (int j = 0; j < ncomps; j++)
                    if (!p->c || p->c == &comps[j])
                        comps[j].sent++;
                more = more || p->next < p->var.n;
            }
            spin(1);
        }
        wait_all(sent_counted, 8);
    }
}

static void on_reply(const lcm_recv_buf_t *rb, const char *ch, void *user);

static void check_empty_pulls(void)
{
    for (int i = 0; i < nports; i++) {
        port_t *p = &ports[i];
        if (strcmp(p->mode, "empty") != 0 || p->c->fail[0])
            continue;
        marie_pull_request_t q = {.utime = marie_wall_us(), .request_id = 4242, .requester = "malformed_peer",
                                  .channel = p->channel, .reply_channel = "MALFORMED_PEER_REPLY", .timeout_ms = 0};
        static int got;
        got = -1;
        lcm_subscription_t *s = lcm_subscribe(lcm, "MALFORMED_PEER_REPLY", on_reply, &got);
        char ch[160];
        snprintf(ch, sizeof ch, "%s.PULL", p->channel);
        for (int k = 0; k < 5 && got < 0; k++) {
            marie_pull_request_t_publish(lcm, ch, &q);
            spin(200);
        }
        lcm_unsubscribe(lcm, s);
        if (got != MARIE_PULL_REPLY_T_STATUS_EMPTY)
            failf(p->c, "a pull of %s answered status %d, not EMPTY: it stored malformed input", p->channel, got);
    }
}

static void on_reply(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    marie_pull_reply_t r;
    if (marie_decode_checked(&marie_type_pull_reply_t, rb->data, rb->data_size, &r) < 0)
        return;
    *(int *)user = r.status;
    marie_pull_reply_t_decode_cleanup(&r);
}

static void report(comp_t *c)
{
    int64_t want = expected(c);
    if (!c->fail[0] && c->dead)
        failf(c, "stopped running (state %d: %s)", c->state, c->reason);
    if (!c->fail[0] && c->hb_count < 2)
        failf(c, "stopped sending heartbeats");
    if (!c->fail[0] && (c->bad_input > want || c->bad_input < want - c->late))
        failf(c, "counted %" PRId64 " bad inputs, expected %" PRId64 " (pushed %" PRId64 ", served by pull %" PRId64
              ", bad replies %" PRId64 ", late %" PRId64 ")", c->bad_input, want, c->sent, c->served, c->garbage,
              c->late);
    if (c->fail[0])
        printf("FAIL: %s: %s\n", c->name, c->fail);
    else
        printf("ok: %s: %" PRId64 " malformed payloads counted (%" PRId64 " pushed, %" PRId64 " pulled, %" PRId64
               " bad replies, %" PRId64 " replies late)\n", c->name, c->bad_input, c->sent, c->served, c->garbage, c->late);
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: malformed_peer SPEC_FILE SECONDS\n");
        return 2;
    }
    double limit = atof(argv[2]);
    int64_t t0 = marie_mono_us();
    if (load_spec(argv[1]) < 0 || !(lcm = lcm_create(marie_default_url())))
        return 2;
    subscribe_all();
    if (!wait_all(is_running, limit / 3))
        for (int i = 0; i < ncomps; i++)
            if (!comps[i].running)
                failf(&comps[i], comps[i].seen ? "not running (state %d: %s)" : "no heartbeat", comps[i].state,
                      comps[i].reason);
    push_all();
    double left = limit - (double)(marie_mono_us() - t0) / 1e6;
    wait_all(pulls_done, left / 2);
    /* A component subscribes to its reply channel at its first pull. */
    for (int i = 0; i < nports; i++)
        if (ports[i].pull && ports[i].last_request && !ports[i].c->garbage && !ports[i].c->dead)
            send_garbage_replies(ports[i].c);
    serving = false;
    /* Everything sent and served: wait for a heartbeat that counts it all, then two more to
     * catch a count that runs past (each payload must be counted exactly once). */
    wait_all(all_counted, 8);
    for (int i = 0; i < ncomps; i++)
        comps[i].hb_count = 0;
    int64_t end = marie_mono_us() + 3500000;
    for (bool all = false; !all && marie_mono_us() < end; spin(50)) {
        all = true;
        for (int i = 0; i < ncomps; i++)
            all = all && (comps[i].hb_count >= 2 || comps[i].fail[0]);
    }
    check_empty_pulls();
    int bad = 0;
    for (int i = 0; i < ncomps; i++) {
        report(&comps[i]);
        bad += comps[i].fail[0] != 0;
    }
    lcm_destroy(lcm);
    for (int i = 0; i < nports; i++) {
        for (size_t k = 0; k < ports[i].var.n; k++)
            free(ports[i].var.v[k].data);
        free(ports[i].var.v);
    }
    return bad ? 1 : 0;
}
