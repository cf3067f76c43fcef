/* xb_server: TCP clients speaking XML documents, bridged to LCM; the listening socket and every
 * client are fds of the process's marie loop. */
#include "adapters/xml_bridge/xb_server.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include "adapters/xml_bridge/xb_server_int.h"
#include "core/clear.h"
#include "core/err.h"
#include "core/log.h"
#include "core/time.h"

#define XB_PROTOCOL 1
#define CLOSE_GRACE_US 1000000      /* a closing client gets this long to take its last reply */

void xb_server_cfg_defaults(xb_server_cfg_t *cfg) { *cfg = (xb_server_cfg_t)XB_SERVER_DEFAULTS; }

int xb_server_cfg_check(const xb_server_cfg_t *c, char *why, size_t len)
{
    if (c->port < 0 || c->port > 65535)
        return marie_fail_why(why, len, "port %lld is not 0..65535", (long long)c->port);
    if (c->max_depth < 1 || c->max_clients < 1 || c->stall_ms < 1 || c->queue < 2)
        return marie_fail_why(why, len, "max_depth, max_clients and stall_ms at least 1, queue at least 2");
    if (c->max_document < 64 || c->max_memory < c->max_document || (uint64_t)c->max_memory > SIZE_MAX / 2)
        return marie_fail_why(why, len, "max_document at least 64 and at most max_memory");
    if (c->queue_bytes < 1 || c->max_message < 1 || c->max_message > INT32_MAX || c->sndbuf < 0 ||
        c->sndbuf > INT32_MAX)
        return marie_fail_why(why, len, "queue_bytes and max_message at least 1, sndbuf not negative");
    if (c->idle_s < 0 || c->evict_idle_ms < 0 || c->max_per_address < 0)
        return marie_fail_why(why, len, "idle_s, evict_idle_ms and max_per_address not negative");
    return 0;
}

void xb_bad_input(xb_server_t *s, const char *counter, const char *fmt, ...)
{
    char reason[320];
    MARIE_VFORMAT(reason, fmt);
    if (s->hooks.bad_input)
        s->hooks.bad_input(s->hooks.user, counter, reason);
    else
        marie_warn_ratelimited(5, "xml bridge: %s: %s", counter, reason);
}

/* ---- client lifecycle ---- */

/* Charges the client's parser memory to the bridge's document budget. */
static void charge(client_t *c)
{
    size_t now = c->parser ? xb_doc_parser_memory(c->parser) : 0;
    c->s->st.doc_bytes += now - c->mem;     /* modular: a decrease subtracts */
    c->mem = now;
}

static void client_close(client_t *c)
{
    xb_server_t *s = c->s;
    while (c->nsubs > 0) {
        sub_t *u = c->subs[--c->nsubs].sub;
        xb_sub_remove_client(s, u, c);
    }
    free(c->subs);
    if (c->fd >= 0) {
        marie_loop_remove_fd(s->loop, c->fd);
        close(c->fd);
    }
    for (int i = 0; i < c->qlen; i++)
        xb_msgbuf_unref(c->q[(c->qhead + i) % c->qcap].b);
    xb_msgbuf_unref(c->cur.b);
    free(c->q);
    MARIE_CLEAR(c->parser, xb_doc_parser_destroy);
    charge(c);
    if (c->prev)
        c->prev->next = c->next;
    else
        s->clients = c->next;
    if (c->next)
        c->next->prev = c->prev;
    s->st.clients--;
    free(c);
}

/* Tells the client why, stops reading, and closes once the reply is written (or soon). */
static void client_end(client_t *c, const char *code, const char *reason)
{
    if (c->closing_since)
        return;
    xb_reply_error(c, NULL, code, reason);     /* code and reason may be the parser's */
    /* Nothing more will be parsed: what the unfinished document held goes back at once. */
    MARIE_CLEAR(c->parser, xb_doc_parser_destroy);
    charge(c);
    c->closing_since = marie_mono_us();
    c->want_out = -1;           /* force the loop's update */
    xb_client_set_out(c, 1);
}

/* client_end for a bad stream or a stall. */
static void client_fail(client_t *c, const char *code, const char *reason)
{
    if (!c->closing_since)
        c->s->st.closed_bad++;
    client_end(c, code, reason);
}

/* Over budget, the clients holding the most for unfinished documents are closed, largest
 * first, until the rest fits: whoever sends the big document pays, not whoever comes next. */
static void enforce_budget(xb_server_t *s)
{
    while (s->st.doc_bytes > (uint64_t)s->cfg.max_memory) {
        client_t *big = NULL;
        for (client_t *c = s->clients; c; c = c->next)
            if (!c->closing_since && c->parser && xb_doc_parser_partial(c->parser) &&
                (!big || c->mem > big->mem))
                big = c;
        if (!big)
            return;
        char why[200];
        snprintf(why, sizeof why, "unfinished document holds %zu bytes, over its share (%zu) of "
                 "the bridge's %zu-byte document memory", big->mem,
                 (uint64_t)s->cfg.max_memory / (size_t)(s->st.clients ? s->st.clients : 1), (uint64_t)s->cfg.max_memory);
        xb_bad_input(s, "memory_budget", "%s", why);
        s->st.closed_memory++;
        client_fail(big, "no-memory", why);
    }
}

static void client_read(client_t *c)
{
    xb_server_t *s = c->s;
    char buf[65536];
    /* Bounded per wake-up so one busy client cannot starve the others. */
    for (int round = 0; round < 4 && !c->dead && !c->closing_since; round++) {
        ssize_t n = read(c->fd, buf, sizeof buf);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            if (errno != EAGAIN && errno != EWOULDBLOCK)
                c->dead = 1;
            break;
        }
        if (n == 0) {
            if (xb_doc_parser_partial(c->parser))
                xb_bad_input(s, "truncated_document", "client closed in the middle of a document");
            c->dead = 1;
            break;
        }
        int rc = xb_doc_parser_feed(c->parser, buf, (size_t)n);
        xb_publish_flush(s);
        if (rc < 0) {
            const xb_error_t *e = xb_doc_parser_error(c->parser);
            xb_bad_input(s, "bad_document", "%s: %s", e->code, e->reason);
            client_fail(c, e->code, e->reason);
            break;
        }
        if (xb_doc_parser_partial(c->parser)) {
            if (!c->partial_since)
                c->partial_since = marie_mono_us();
        } else {
            c->partial_since = 0;
        }
        charge(c);
        if (s->st.doc_bytes > (uint64_t)s->cfg.max_memory)
            enforce_budget(s);
        if ((size_t)n < sizeof buf)
            break;
    }
}

/* The loop finds a client's watch by fd each round, so closing here is safe. */
static void on_client(marie_loop_t *loop, int fd, short revents, void *user)
{
    client_t *c = user;
    if (c->closing_since && (revents & (POLLHUP | POLLERR)))
        c->dead = 1;
    else if (revents & (POLLIN | POLLHUP | POLLERR))
        client_read(c);
    if (!c->dead && (revents & POLLOUT))
        xb_client_flush(c);
    if (c->dead)
        client_close(c);
}

/* The client that has gone longest without a complete document, of those silent for at least
 * evict_idle_ms (only those from addr, when given); NULL when every one is active. */
static client_t *longest_idle(xb_server_t *s, const char *addr, int64_t now)
{
    client_t *best = NULL;
    if (s->cfg.evict_idle_ms <= 0)
        return NULL;
    for (client_t *c = s->clients; c; c = c->next)
        if (!c->closing_since && !c->dead && now - c->active_us >= (int64_t)s->cfg.evict_idle_ms * 1000 &&
            (!addr || strcmp(c->addr, addr) == 0) && (!best || c->active_us < best->active_us))
            best = c;
    return best;
}

/* Closes c to let a new client in: told why, and gone at once unless output is on its way. */
static void evict(xb_server_t *s, client_t *c, int64_t now, const char *scope)
{
    char why[160];
    snprintf(why, sizeof why, "closed to make room for a new client (%s: no request for %.1f s)", scope,
             (double)(now - c->active_us) * 1e-6);
    s->st.evicted++;
    if (s->hooks.count)
        s->hooks.count(s->hooks.user, "evicted_client", 1);
    client_end(c, "idle", why);
    xb_client_flush(c);
    if (c->dead)
        client_close(c);
}

/* Room for a client from addr: under the per-address cap and max_clients, by closing the
 * longest idle client (of that address for its cap) when full. -1 with why when every one
 * that holds a place is active. */
static int make_room(xb_server_t *s, const char *addr, char *why, size_t len)
{
    int64_t now = marie_mono_us();
    int live = 0, same = 0;
    for (client_t *c = s->clients; c; c = c->next)
        if (!c->closing_since && !c->dead) {
            live++;
            same += strcmp(c->addr, addr) == 0;
        }
    client_t *v;
    if (s->cfg.max_per_address > 0 && same >= s->cfg.max_per_address) {
        if (!(v = longest_idle(s, addr, now))) {
            snprintf(why, len, "%d clients from %s already connected, all active", same, addr);
            return -1;
        }
        evict(s, v, now, "its address's cap");
    } else if (live >= s->cfg.max_clients) {
        if (!(v = longest_idle(s, NULL, now))) {
            snprintf(why, len, "%d clients already connected, all active", live);
            return -1;
        }
        evict(s, v, now, "the bridge is full");
    }
    /* Clients still closing hold their fd for up to CLOSE_GRACE_US: bounded all the same. */
    if ((int64_t)s->st.clients >= 2 * (int64_t)s->cfg.max_clients) {
        snprintf(why, len, "%d clients connected or closing", (int)s->st.clients);
        return -1;
    }
    return 0;
}

static void refuse(xb_server_t *s, int fd, const char *why)
{
    char msg[256];
    int n = snprintf(msg, sizeof msg, "<error code=\"busy\" reason=\"%s\"/>\n", why);
    ssize_t w = send(fd, msg, (size_t)n, MSG_NOSIGNAL);
    (void)w;
    close(fd);
    s->st.refused++;
    xb_bad_input(s, "refused_client", "%s", why);
}

static void peer_address(const struct sockaddr_storage *sa, char *out, size_t len)
{
    const void *a = sa->ss_family == AF_INET6 ? (const void *)&((const struct sockaddr_in6 *)sa)->sin6_addr
                                              : (const void *)&((const struct sockaddr_in *)sa)->sin_addr;
    if (!inet_ntop(sa->ss_family, a, out, (socklen_t)len))
        snprintf(out, len, "?");
}

static void accept_clients(xb_server_t *s)
{
    for (int i = 0; i < 64; i++) {
        struct sockaddr_storage sa;
        socklen_t sl = sizeof sa;
        int fd = accept4(s->lfd, (struct sockaddr *)&sa, &sl, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd < 0) {
            if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)
                marie_warn_ratelimited(5, "xml bridge: accept: %s", strerror(errno));
            return;
        }
        char addr[48], why[200];
        peer_address(&sa, addr, sizeof addr);
        if (make_room(s, addr, why, sizeof why) < 0) {
            refuse(s, fd, why);
            continue;
        }
        int one = 1;
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        if (s->cfg.sndbuf > 0)
            setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &(int){ (int)s->cfg.sndbuf }, sizeof(int));
        client_t *c = calloc(1, sizeof *c);
        xb_doc_limits_t lim = { (size_t)s->cfg.max_document, s->cfg.max_depth };
        if (!c || !(c->parser = xb_doc_parser_create(&lim, xb_on_document, c))) {
            free(c);
            close(fd);
            continue;
        }
        c->s = s;
        c->fd = fd;
        c->active_us = marie_mono_us();
        snprintf(c->addr, sizeof c->addr, "%s", addr);
        if (marie_loop_add_fd(s->loop, fd, POLLIN, on_client, c) < 0) {
            xb_doc_parser_destroy(c->parser);
            free(c->q);
            free(c);
            close(fd);
            continue;
        }
        charge(c);
        c->next = s->clients;
        if (s->clients)
            s->clients->prev = c;
        s->clients = c;
        s->st.clients++;
        s->st.accepted++;
        char hello[256];
        int n = snprintf(hello, sizeof hello,
                         "<hello protocol=\"%d\" max_document=\"%lld\" max_depth=\"%lld\" queue=\"%lld\"/>\n",
                         XB_PROTOCOL, (long long)s->cfg.max_document, (long long)s->cfg.max_depth,
                         (long long)s->cfg.queue);
        xb_client_enqueue_text(c, hello, (size_t)n);
    }
}

static void on_listen(marie_loop_t *loop, int fd, short revents, void *user)
{
    accept_clients(user);
}

static void on_sweep(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    xb_server_t *s = user;
    int64_t now = marie_mono_us();
    for (client_t *c = s->clients, *next; c; c = next) {
        next = c->next;
        if (c->closing_since && now - c->closing_since > CLOSE_GRACE_US)
            c->dead = 1;
        else if (!c->closing_since && c->partial_since &&
                 now - c->partial_since > (int64_t)s->cfg.stall_ms * 1000) {
            xb_bad_input(s, "stalled_client", "document unfinished for %lld ms", (long long)s->cfg.stall_ms);
            client_fail(c, "stalled", "document left unfinished too long");
        } else if (!c->closing_since && !c->partial_since && c->nsubs == 0 && s->cfg.idle_s > 0 &&
                   now - c->active_us > (int64_t)s->cfg.idle_s * 1000000) {
            char why[96];
            snprintf(why, sizeof why, "no request for %lld s and no subscription", (long long)s->cfg.idle_s);
            s->st.closed_idle++;
            if (s->hooks.count)
                s->hooks.count(s->hooks.user, "idle_closed", 1);
            client_end(c, "idle", why);
        }
        if (c->dead)
            client_close(c);
    }
}

xb_server_t *xb_server_create(const xb_server_cfg_t *cfg, lcm_t *lcm, marie_loop_t *loop,
                              const xb_server_hooks_t *hooks)
{
    xb_server_t *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    if (cfg)
        s->cfg = *cfg;
    else
        xb_server_cfg_defaults(&s->cfg);
    if (xb_server_cfg_check(&s->cfg, NULL, 0) < 0) {
        free(s);
        return marie_fail_null(EINVAL);
    }
    snprintf(s->bind, sizeof s->bind, "%s", s->cfg.bind ? s->cfg.bind : "127.0.0.1");
    s->cfg.bind = s->bind;
    if (hooks)
        s->hooks = *hooks;
    s->lcm = lcm;
    s->loop = loop;
    s->lfd = -1;
    /* The largest outgoing document: a max-size payload as base64 XML plus the envelope. */
    marie_buf_init(&s->out, (size_t)s->cfg.max_message * 4 + 4096);
    marie_buf_init(&s->enc, (size_t)s->cfg.max_message);
    marie_buf_init(&s->batch, 0);

    struct addrinfo hints = { .ai_family = AF_UNSPEC, .ai_socktype = SOCK_STREAM,
                              .ai_flags = AI_PASSIVE | AI_NUMERICSERV };
    struct addrinfo *ai = NULL;
    char port[16];
    snprintf(port, sizeof port, "%lld", (long long)s->cfg.port);
    int rc = getaddrinfo(s->bind[0] ? s->bind : NULL, port, &hints, &ai);
    if (rc != 0) {
        marie_error("xml bridge: bad bind address '%s': %s", s->bind, gai_strerror(rc));
        errno = EINVAL;
        goto err;
    }
    s->lfd = socket(ai->ai_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    int one = 1;
    if (s->lfd < 0 || setsockopt(s->lfd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) < 0 ||
        bind(s->lfd, ai->ai_addr, ai->ai_addrlen) < 0 || listen(s->lfd, 1024) < 0) {
        int e = errno;
        marie_error("xml bridge: cannot listen on %s:%lld: %s", s->bind, (long long)s->cfg.port, strerror(e));
        freeaddrinfo(ai);
        errno = e;
        goto err;
    }
    freeaddrinfo(ai);
    struct sockaddr_storage sa;
    socklen_t sl = sizeof sa;
    getsockname(s->lfd, (struct sockaddr *)&sa, &sl);
    s->port = ntohs(sa.ss_family == AF_INET6 ? ((struct sockaddr_in6 *)&sa)->sin6_port
                                             : ((struct sockaddr_in *)&sa)->sin_port);

    if ((rc = marie_loop_add_fd(loop, s->lfd, POLLIN, on_listen, s)) < 0)
        goto err;
    /* A bridge forwards floods: up to 256 messages per wake-up. */
    if (s->cfg.handle_lcm && (rc = marie_loop_add_bus(loop, lcm, 256)) < 0) {
        MARIE_KEEP_ERRNO(marie_loop_remove_fd(loop, s->lfd));
        goto err;
    }
    s->sweep = marie_loop_add_wall_timer(loop, 100000, on_sweep, s);
    if (!s->sweep) {
        marie_loop_remove_fd(loop, s->lfd);
        if (s->cfg.handle_lcm)
            marie_loop_remove_bus(loop, lcm);
        goto err;
    }
    return s;
err:
    if (s->lfd >= 0)
        close(s->lfd);
    marie_buf_free(&s->out);
    marie_buf_free(&s->enc);
    marie_buf_free(&s->batch);
    free(s);
    return NULL;
}

void xb_server_destroy(xb_server_t *s)
{
    if (!s)
        return;
    xb_publish_flush(s);
    while (s->clients)
        client_close(s->clients);
    while (s->subs) {
        sub_t *u = s->subs;
        u->nclients = 0;
        xb_sub_release(s, u);
    }
    marie_loop_remove_timer(s->loop, s->sweep);
    marie_loop_remove_fd(s->loop, s->lfd);
    if (s->cfg.handle_lcm)
        marie_loop_remove_bus(s->loop, s->lcm);
    close(s->lfd);
    marie_buf_free(&s->out);
    marie_buf_free(&s->enc);
    marie_buf_free(&s->batch);
    free(s);
}

int xb_server_port(const xb_server_t *s)
{
    return s->port;
}

void xb_server_stats(const xb_server_t *s, xb_server_stats_t *st)
{
    *st = s->st;
}
