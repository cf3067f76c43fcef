/* webserve: the web pages' server on the loop, shared by the viewer and the touch page. */
#include "tools/webcommon/webserve.h"

#include <errno.h>
#include <limits.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include "core/err.h"
#include "core/file.h"
#include "core/log.h"
#include "core/time.h"
#include "tools/webcommon/webproto.h"

#define CMD_MAX 4096            /* a page's command: longer text messages are refused */
#define MSG_MAX 65536           /* a page's message, fragments together */
#define FILE_MAX (4u << 20)
#define LINGER_US 2000000       /* after the last byte out, how long a closing client may talk */

/* Bytes for one or more clients, shared: a page's frame goes to every page with one copy. */
typedef struct {
    int refs;
    bool droppable;
    size_t len;
    uint8_t data[];
} frame_t;

typedef struct client {
    struct client *next;
    webserve_t *w;
    int fd, id;                 /* id: -1 until the connection is a page */
    bool page, counted, dead, closing, lingering;    /* counted: one of st.pages */
    short events;               /* asked of the loop */
    char addr[48];              /* the client's address, "127.0.0.1" */
    marie_buf_t in;             /* read and not yet used */
    marie_buf_t msg;            /* a page's fragmented message so far */
    int msg_op;
    frame_t **q;                /* to write, oldest first; off bytes of q[0] written */
    size_t nq, qcap, off, queued;
    int64_t since;              /* monotonic: connected, last request, or closing */
} client_t;

struct webserve {
    webserve_cfg_t cfg;
    marie_loop_t *loop;
    marie_timer_t *sweep;
    int lfd, port;              /* port: the one served on (the one picked for port 0) */
    char host[64];              /* of the page's address: bind, or 127.0.0.1 for every address */
    client_t *clients;
    int next_id;
    webserve_stats_t st;
};

/* ---------------------------------------------------------------- frames and queues */

static frame_t *frame_new(const void *head, size_t hl, const void *body, size_t bl, bool droppable)
{
    frame_t *f = malloc(sizeof *f + hl + bl);
    if (!f)
        return NULL;
    *f = (frame_t){1, droppable, hl + bl};
    memcpy(f->data, head, hl);
    if (bl)
        memcpy(f->data + hl, body, bl);
    return f;
}

static frame_t *ws_frame(int op, const void *data, size_t len, bool droppable)
{
    uint8_t head[10];
    return frame_new(head, webws_head(head, op, len), data, len, droppable);
}

static void frame_unref(frame_t *f)
{
    if (f && --f->refs == 0)
        free(f);
}

static void count(webserve_t *w, const char *counter, int64_t *stat)
{
    (*stat)++;
    if (w->cfg.comp)
        marie_component_count(w->cfg.comp, counter, 1);
}

static void bad(client_t *cl, const char *what)
{
    webserve_t *w = cl->w;
    w->st.bad_requests++;
    if (w->cfg.comp)
        marie_component_bad_input(w->cfg.comp, "web_requests", "%s: %s from %s", w->cfg.name, what, cl->addr);
    else
        marie_warn_ratelimited(10, "%s: %s from %s", w->cfg.name, what, cl->addr);
}

/* A page stops counting against WEBSERVE_MAX_PAGES once it closes, not when its socket does. */
static void page_gone(client_t *cl)
{
    if (cl->counted)
        cl->w->st.pages--;
    cl->counted = false;
}

static void client_kill(client_t *cl)
{
    if (cl->dead)
        return;
    cl->dead = true;
    marie_loop_remove_fd(cl->w->loop, cl->fd);
    close(cl->fd);
    page_gone(cl);
    cl->w->st.conns--;
    for (size_t i = 0; i < cl->nq; i++)
        frame_unref(cl->q[i]);
    cl->nq = cl->queued = cl->off = 0;
}

/* POLLOUT while bytes wait; POLLIN unless the input is full (a request held while its
 * answers wait unread), so a client that does not read is not read from either. */
static void update_events(client_t *cl)
{
    if (cl->dead)
        return;
    short ev = (short)((cl->in.len < cl->in.max || cl->closing ? POLLIN : 0) | (cl->nq ? POLLOUT : 0));
    if (ev != cl->events) {
        cl->events = ev;
        marie_loop_set_events(cl->w->loop, cl->fd, ev);
    }
}

/* Everything sent and the connection is to close: say so (FIN) and read what the client still
 * sends until it closes too, so the last answer is not lost to a reset. */
static void linger(client_t *cl)
{
    cl->lingering = true;
    cl->since = marie_mono_us();
    shutdown(cl->fd, SHUT_WR);
}

static void pop_written(client_t *cl, size_t n)
{
    size_t done = 0;
    while (done < cl->nq && n >= cl->q[done]->len - cl->off) {
        n -= cl->q[done]->len - cl->off;
        cl->queued -= cl->q[done]->len;
        frame_unref(cl->q[done++]);
        cl->off = 0;
    }
    cl->off += n;
    cl->nq -= done;
    memmove(cl->q, cl->q + done, cl->nq * sizeof *cl->q);
}

/* Writes what the socket takes now, never waiting; POLLOUT asked for while bytes wait. */
static void client_flush(client_t *cl)
{
    while (!cl->dead && cl->nq) {
        struct iovec iov[16];
        int k = 0;
        for (size_t i = 0; i < cl->nq && k < 16; i++, k++)
            iov[k] = (struct iovec){cl->q[i]->data + (i ? 0 : cl->off), cl->q[i]->len - (i ? 0 : cl->off)};
        struct msghdr mh = {.msg_iov = iov, .msg_iovlen = (size_t)k};
        ssize_t n = sendmsg(cl->fd, &mh, MSG_NOSIGNAL | MSG_DONTWAIT);
        if (n < 0 && errno == EINTR)
            continue;
        if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK))
            break;
        if (n < 0) {
            client_kill(cl);
            return;
        }
        pop_written(cl, (size_t)n);
    }
    if (!cl->dead && !cl->nq && cl->closing && !cl->lingering)
        linger(cl);
    update_events(cl);
}

/* Drops the page's oldest droppable frames not yet begun until len more bytes fit. */
static void make_room(client_t *cl, size_t len)
{
    size_t keep = 0;
    for (size_t i = 0; i < cl->nq; i++) {
        frame_t *f = cl->q[i];
        if ((i > 0 || cl->off == 0) && f->droppable && cl->queued + len > WEBSERVE_QUEUE_SOFT) {
            cl->queued -= f->len;
            frame_unref(f);
            count(cl->w, "web_dropped", &cl->w->st.dropped);
            continue;
        }
        cl->q[keep++] = f;
    }
    cl->nq = keep;
}

static void slow_close(client_t *cl)
{
    count(cl->w, "web_slow_closed", &cl->w->st.slow_closed);
    marie_warn_ratelimited(10, "%s: page %d (%s) has %zu bytes waiting: closed", cl->w->cfg.name, cl->id, cl->addr,
                           cl->queued);
    client_kill(cl);
}

static void client_push(client_t *cl, frame_t *f)
{
    if (cl->dead || cl->closing)
        return;
    if (f->droppable && cl->queued + f->len > WEBSERVE_QUEUE_SOFT)
        make_room(cl, f->len);
    if (f->droppable && cl->queued && cl->queued + f->len > WEBSERVE_QUEUE_SOFT) {
        count(cl->w, "web_dropped", &cl->w->st.dropped);
        return;
    }
    if (cl->queued + f->len > WEBSERVE_QUEUE_HARD || MARIE_GROW(cl->q, cl->qcap, cl->nq + 1) < 0) {
        slow_close(cl);
        return;
    }
    f->refs++;
    cl->q[cl->nq++] = f;
    cl->queued += f->len;
    if (cl->nq == 1)
        client_flush(cl);
}

static void push_owned(client_t *cl, frame_t *f)
{
    if (!f) {
        client_kill(cl);
        return;
    }
    client_push(cl, f);
    frame_unref(f);
}

/* ---------------------------------------------------------------- sending to pages */

void webserve_send(webserve_t *w, int id, const char *data, size_t len, bool droppable)
{
    frame_t *f = ws_frame(WEBWS_TEXT, data, len, droppable);
    for (client_t *cl = w->clients; cl; cl = cl->next)
        if (cl->page && !cl->dead && (id < 0 || cl->id == id)) {
            w->st.frames_out++;
            if (f)
                client_push(cl, f);
            else
                count(w, "web_dropped", &w->st.dropped);
        }
    frame_unref(f);
}

void webserve_send_json(webserve_t *w, int id, const marie_buf_t *b, bool droppable)
{
    if (!b->failed && b->len)
        webserve_send(w, id, b->data, b->len, droppable);
}

void webserve_notice(webserve_t *w, int id, const char *level, const char *text)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_puts(&b, "{\"type\":\"notice\",\"level\":");
    vj_str(&b, level);
    marie_buf_puts(&b, ",\"text\":");
    vj_str(&b, text);
    marie_buf_puts(&b, "}");
    webserve_send_json(w, id, &b, false);
    marie_buf_free(&b);
}

/* ---------------------------------------------------------------- HTTP */

static const char *reason(int status)
{
    switch (status) {
    case 101: return "Switching Protocols";
    case 200: return "OK";
    case 400: return "Bad Request";
    case 403: return "Forbidden";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 414: return "URI Too Long";
    case 426: return "Upgrade Required";
    case 431: return "Request Header Fields Too Large";
    case 503: return "Service Unavailable";
    case 505: return "HTTP Version Not Supported";
    default: return "Internal Server Error";
    }
}

/* An answer with a text body, after which the connection closes. */
static void http_error(client_t *cl, int status, const char *extra)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    const char *text = reason(status);
    marie_buf_printf(&b, "HTTP/1.1 %d %s\r\nContent-Type: text/plain\r\nContent-Length: %zu\r\n%sConnection: close\r\n\r\n%s\n",
                     status, text, strlen(text) + 1, extra ? extra : "", text);
    push_owned(cl, b.failed ? NULL : frame_new(b.data, b.len, NULL, 0, false));
    marie_buf_free(&b);
    cl->closing = true;
    if (!cl->dead && !cl->nq)
        linger(cl);
}

/* A malformed or forbidden request: counted, answered, the connection closed. */
static void refuse(client_t *cl, int status, const char *what, const char *extra)
{
    bad(cl, what);
    http_error(cl, status, extra);
}

static void http_file(client_t *cl, const webreq_t *r, const webserve_file_t *file, bool keep)
{
    char path[PATH_MAX + 32];
    snprintf(path, sizeof path, "%s/%s", cl->w->cfg.www, file->file);
    size_t len = 0;
    char *body = marie_file_read(path, FILE_MAX, &len);
    if (!body) {
        marie_warn_ratelimited(10, "%s: %s: %s", cl->w->cfg.name, path, strerror(errno));
        http_error(cl, 404, NULL);
        return;
    }
    char head[512];
    int hl = snprintf(head, sizeof head,
                      "HTTP/1.1 200 OK\r\nContent-Type: %s\r\nContent-Length: %zu\r\nCache-Control: no-cache\r\n"
                      "X-Content-Type-Options: nosniff\r\nConnection: %s\r\n\r\n",
                      file->mime, len, keep ? "keep-alive" : "close");
    bool head_only = strcmp(r->method, "HEAD") == 0;
    push_owned(cl, frame_new(head, (size_t)hl, body, head_only ? 0 : len, false));
    free(body);
    if (!keep) {
        cl->closing = true;
        if (!cl->dead && !cl->nq)
            linger(cl);
    }
}

/* Only pages served by this server may open the WebSocket: another site open in the same
 * browser must not be able to send orders to the robot. A client without Origin is no browser. */
static bool same_origin(const webreq_t *r)
{
    return !r->origin[0] || (strncmp(r->origin, "http://", 7) == 0 && strcmp(r->origin + 7, r->host) == 0);
}

static void ws_upgrade(client_t *cl, const webreq_t *r)
{
    webserve_t *w = cl->w;
    char accept[29];
    if (strcmp(r->version, "13") != 0) {
        refuse(cl, 426, "WebSocket of another version", "Sec-WebSocket-Version: 13\r\n");
        return;
    }
    if (strcmp(r->method, "GET") != 0 || !r->conn_upgrade || webws_accept(r->key, accept) < 0) {
        refuse(cl, 400, "malformed WebSocket handshake", NULL);
        return;
    }
    if (!same_origin(r)) {
        marie_warn_ratelimited(10, "web page: WebSocket from origin %s refused (host %s)", r->origin, r->host);
        refuse(cl, 403, "WebSocket from a foreign origin", NULL);
        return;
    }
    if (w->st.pages >= WEBSERVE_MAX_PAGES) {
        w->st.refused++;
        marie_warn_ratelimited(10, "%s: %d pages open already: another one refused", w->cfg.name, WEBSERVE_MAX_PAGES);
        http_error(cl, 503, "Retry-After: 1\r\n");
        return;
    }
    char head[160];
    int hl = snprintf(head, sizeof head,
                      "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                      "Sec-WebSocket-Accept: %s\r\n\r\n", accept);
    cl->page = cl->counted = true;
    cl->id = w->next_id++;
    w->st.pages++;
    cl->in.max = MSG_MAX + 14;                  /* a whole frame, its header included */
    marie_buf_init(&cl->msg, MSG_MAX);
    push_owned(cl, frame_new(head, (size_t)hl, NULL, 0, false));
    if (!cl->dead)
        w->cfg.on_cmd(w->cfg.user, cl->id, cl->addr, true, "", 0);
}

static void http_request(client_t *cl, const webreq_t *r)
{
    webserve_t *w = cl->w;
    cl->since = marie_mono_us();
    if (r->has_body)
        refuse(cl, 400, "request with a body", NULL);
    else if (strcmp(r->path, "/ws") == 0 && r->upgrade_ws)
        ws_upgrade(cl, r);
    else if (strcmp(r->method, "GET") != 0 && strcmp(r->method, "HEAD") != 0)
        http_error(cl, 405, "Allow: GET, HEAD\r\n");
    else {
        bool keep = r->minor >= 1 ? !r->conn_close : r->conn_keep_alive;
        const webserve_file_t *file = NULL;
        for (size_t i = 0; i < w->cfg.nfiles && !file; i++)
            if (strcmp(r->path, w->cfg.files[i].uri) == 0)
                file = &w->cfg.files[i];
        if (file)
            http_file(cl, r, file, keep);
        else
            http_error(cl, 404, NULL);
    }
}

static void consume(marie_buf_t *b, size_t n)
{
    memmove(b->data, b->data + n, b->len - n);
    b->len -= n;
}

/* Requests one after another (a browser's keep-alive); not while the answers wait unread. */
static void http_input(client_t *cl)
{
    while (!cl->dead && !cl->closing && !cl->page && cl->queued <= WEBSERVE_QUEUE_SOFT && cl->in.len) {
        webreq_t r;
        int status = 0;
        const char *why = NULL;
        int n = webreq_parse(&r, cl->in.data, cl->in.len, &status, &why);
        if (n == 0)
            return;
        if (n < 0) {
            refuse(cl, status, why, NULL);
            return;
        }
        consume(&cl->in, (size_t)n);
        http_request(cl, &r);
    }
}

/* ---------------------------------------------------------------- WebSocket */

static void ws_close(client_t *cl, uint16_t code, const char *why)
{
    uint8_t body[64] = {(uint8_t)(code >> 8), (uint8_t)code};
    size_t n = strlen(why) < sizeof body - 2 ? strlen(why) : sizeof body - 2;
    memcpy(body + 2, why, n);
    push_owned(cl, ws_frame(WEBWS_CLOSE, body, n + 2, false));
    page_gone(cl);
    cl->closing = true;
    if (!cl->dead && !cl->nq)
        linger(cl);
}

static void ws_failed(client_t *cl, uint16_t code, const char *why)
{
    bad(cl, why);
    ws_close(cl, code, why);
}

static void ws_message(client_t *cl, int op, const uint8_t *data, size_t len)
{
    if (op != WEBWS_TEXT)
        return;                                 /* the pages send text only */
    if (len > CMD_MAX) {
        bad(cl, "command over 4096 bytes");
        return;
    }
    char text[CMD_MAX + 1];
    memcpy(text, data, len);
    text[len] = 0;
    cl->w->cfg.on_cmd(cl->w->cfg.user, cl->id, cl->addr, false, text, len);
}

/* A data frame: a message, or a fragment of one (assembled up to MSG_MAX). */
static void ws_data(client_t *cl, const webws_frame_t *f, const uint8_t *p, size_t len)
{
    if ((f->op == WEBWS_CONT) != (cl->msg_op != 0)) {
        ws_failed(cl, 1002, f->op ? "new message inside a fragmented one" : "continuation of nothing");
    } else if (f->fin && f->op != WEBWS_CONT) {
        ws_message(cl, f->op, p, len);
    } else if (marie_buf_put(&cl->msg, p, len) < 0) {
        ws_failed(cl, 1009, "message over 64 KiB");
    } else {
        if (f->op != WEBWS_CONT)
            cl->msg_op = f->op;
        if (f->fin) {
            int op = cl->msg_op;
            cl->msg_op = 0;
            ws_message(cl, op, (const uint8_t *)cl->msg.data, cl->msg.len);
            marie_buf_reset(&cl->msg);
        }
    }
}

/* One whole frame, unmasked: pings answered, a close answered and the page closed. */
static void ws_frame_in(client_t *cl, const webws_frame_t *f, const uint8_t *p)
{
    size_t len = (size_t)f->len;
    if (f->op == WEBWS_PING)
        push_owned(cl, ws_frame(WEBWS_PONG, p, len, false));
    else if (f->op == WEBWS_CLOSE)
        ws_close(cl, len >= 2 ? (uint16_t)(p[0] << 8 | p[1]) : 1000, "");
    else if (f->op != WEBWS_PONG)
        ws_data(cl, f, p, len);
}

static void ws_input(client_t *cl)
{
    while (!cl->dead && !cl->closing && cl->in.len) {
        webws_frame_t f;
        const char *why = NULL;
        uint8_t *buf = (uint8_t *)cl->in.data;
        int hl = webws_parse(&f, buf, cl->in.len, &why);
        if (hl < 0 || (hl > 0 && !f.masked) || (hl > 0 && f.len > MSG_MAX)) {
            ws_failed(cl, hl < 0 || !f.masked ? 1002 : 1009, hl < 0 ? why : !f.masked ? "unmasked frame" : "frame over 64 KiB");
            return;
        }
        if (hl == 0 || cl->in.len < (size_t)hl + f.len)
            return;
        webws_unmask(buf + hl, (size_t)f.len, f.mask, 0);
        ws_frame_in(cl, &f, buf + hl);
        if (!cl->dead)
            consume(&cl->in, (size_t)hl + (size_t)f.len);
    }
}

/* ---------------------------------------------------------------- the loop's side */

static void reap(webserve_t *w)
{
    for (client_t **pp = &w->clients; *pp;) {
        client_t *cl = *pp;
        if (!cl->dead) {
            pp = &cl->next;
            continue;
        }
        *pp = cl->next;
        marie_buf_free(&cl->in);
        marie_buf_free(&cl->msg);
        free(cl->q);
        free(cl);
    }
}

static void client_read(client_t *cl)
{
    char scratch[4096];
    if (cl->closing) {                          /* what a closing client says is not read */
        ssize_t n = read(cl->fd, scratch, sizeof scratch);
        if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR))
            client_kill(cl);
        return;
    }
    size_t room = cl->in.max - cl->in.len < sizeof scratch ? cl->in.max - cl->in.len : sizeof scratch;
    if (room == 0 || marie_buf_reserve(&cl->in, room) < 0) {
        update_events(cl);                      /* full: read again once the head is used */
        return;
    }
    ssize_t n = read(cl->fd, cl->in.data + cl->in.len, room);
    if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR)) {
        client_kill(cl);
        return;
    }
    if (n > 0)
        cl->in.len += (size_t)n;
    if (cl->page)
        ws_input(cl);
    else
        http_input(cl);
    if (!cl->dead && cl->page && !cl->closing && cl->in.len)
        ws_input(cl);                           /* the frames right after the handshake */
    update_events(cl);
}

static void on_client(marie_loop_t *loop, int fd, short revents, void *user)
{
    client_t *cl = user;
    webserve_t *w = cl->w;
    if (revents & POLLNVAL)
        client_kill(cl);
    if (!cl->dead && (revents & POLLOUT)) {
        client_flush(cl);
        if (!cl->dead && !cl->nq && !cl->page) {
            http_input(cl);                     /* requests held while their answers waited */
            update_events(cl);
        }
    }
    if (!cl->dead && (revents & (POLLIN | POLLHUP | POLLERR)))
        client_read(cl);
    reap(w);
}

static void client_new(webserve_t *w, int fd, const struct sockaddr_storage *sa, socklen_t sl)
{
    client_t *cl = calloc(1, sizeof *cl);
    if (!cl || marie_loop_add_fd(w->loop, fd, POLLIN, on_client, cl) < 0) {
        marie_warn("%s: cannot take a connection: %s", w->cfg.name, strerror(errno));
        free(cl);
        close(fd);
        return;
    }
    *cl = (client_t){.w = w, .fd = fd, .id = -1, .events = POLLIN, .since = marie_mono_us(), .next = w->clients};
    if (getnameinfo((const struct sockaddr *)sa, sl, cl->addr, sizeof cl->addr, NULL, 0, NI_NUMERICHOST) != 0)
        snprintf(cl->addr, sizeof cl->addr, "?");
    marie_buf_init(&cl->in, WEBREQ_HEAD_MAX);
    w->clients = cl;
    w->st.conns++;
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
}

/* At the bound, the connection that has waited longest without a whole request makes room
 * (pages are never let go so), so half-open requests cannot keep the pages' files from a browser. */
static bool evict_idle(webserve_t *w)
{
    client_t *oldest = NULL;
    for (client_t *cl = w->clients; cl; cl = cl->next)
        if (!cl->dead && !cl->page && !cl->nq && (!oldest || cl->since < oldest->since))
            oldest = cl;
    if (!oldest)
        return false;
    w->st.refused++;
    marie_warn_ratelimited(10, "%s: %d connections open: the longest idle (%s) closed", w->cfg.name,
                           WEBSERVE_MAX_CONNS, oldest->addr);
    client_kill(oldest);
    return true;
}

static void on_listen(marie_loop_t *loop, int fd, short revents, void *user)
{
    webserve_t *w = user;
    for (int i = 0; i < 16; i++) {
        struct sockaddr_storage sa;
        socklen_t sl = sizeof sa;
        int c = accept4(fd, (struct sockaddr *)&sa, &sl, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (c < 0) {
            if (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR && errno != ECONNABORTED)
                marie_warn_ratelimited(10, "%s: accept: %s", w->cfg.name, strerror(errno));
            return;
        }
        if (w->st.conns >= WEBSERVE_MAX_CONNS && !evict_idle(w)) {
            w->st.refused++;
            marie_warn_ratelimited(10, "%s: %d connections open already: another one refused", w->cfg.name,
                                   WEBSERVE_MAX_CONNS);
            close(c);
            continue;
        }
        client_new(w, c, &sa, sl);
    }
}

/* Once a second: a connection that sends no whole request in time, or a closing one that does
 * not close, is let go. */
static void on_sweep(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    webserve_t *w = user;
    int64_t now = marie_mono_us();
    for (client_t *cl = w->clients; cl; cl = cl->next) {
        if (cl->lingering && now - cl->since > LINGER_US)
            client_kill(cl);
        else if (!cl->page && !cl->closing && !cl->nq && now - cl->since > WEBSERVE_REQUEST_TIMEOUT_MS * 1000LL)
            client_kill(cl);
    }
    reap(w);
}

static int listen_on(webserve_t *w, const char *host, int port)
{
    char ps[16];
    snprintf(ps, sizeof ps, "%d", port);
    struct addrinfo hints = {.ai_flags = AI_PASSIVE | AI_NUMERICSERV, .ai_socktype = SOCK_STREAM}, *ai = NULL;
    if (getaddrinfo(host, ps, &hints, &ai) != 0 || !ai)
        return marie_fail(EADDRNOTAVAIL);
    int fd = socket(ai->ai_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0), one = 1;
    if (fd < 0 || setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) < 0 ||
        bind(fd, ai->ai_addr, ai->ai_addrlen) < 0 || listen(fd, 64) < 0) {
        MARIE_KEEP_ERRNO(freeaddrinfo(ai));
        if (fd >= 0)
            MARIE_KEEP_ERRNO(close(fd));
        return -1;
    }
    freeaddrinfo(ai);
    struct sockaddr_storage sa;
    socklen_t sl = sizeof sa;
    getsockname(fd, (struct sockaddr *)&sa, &sl);
    w->port = ntohs(sa.ss_family == AF_INET6 ? ((struct sockaddr_in6 *)&sa)->sin6_port : ((struct sockaddr_in *)&sa)->sin_port);
    w->lfd = fd;
    return 0;
}

webserve_t *webserve_start(marie_loop_t *loop, const char *bind, int port, const webserve_cfg_t *cfg, char *why,
                           size_t len)
{
    webserve_t *w = calloc(1, sizeof *w);
    if (!w) {
        snprintf(why, len, "out of memory");
        return NULL;
    }
    w->cfg = *cfg;
    w->loop = loop;
    w->lfd = -1;
    snprintf(w->host, sizeof w->host, "%s", strcmp(bind, "0.0.0.0") == 0 ? "127.0.0.1" : bind);
    if (listen_on(w, bind, port) < 0) {
        snprintf(why, len, "cannot serve HTTP on %s:%d (port in use?): %s", bind, port, strerror(errno));
        MARIE_KEEP_ERRNO(webserve_stop(w));
        return NULL;
    }
    if (marie_loop_add_fd(loop, w->lfd, POLLIN, on_listen, w) < 0 ||
        !(w->sweep = marie_loop_add_wall_timer(loop, 1000000, on_sweep, w))) {
        snprintf(why, len, "cannot set up the loop: %s", strerror(errno));
        MARIE_KEEP_ERRNO(webserve_stop(w));
        return NULL;
    }
    return w;
}

void webserve_stop(webserve_t *w)
{
    if (!w)
        return;
    for (client_t *cl = w->clients; cl; cl = cl->next) {
        if (cl->page && !cl->closing)
            ws_close(cl, 1001, "server stopping");   /* as far as the socket takes it now */
        client_kill(cl);
    }
    reap(w);
    marie_loop_remove_timer(w->loop, w->sweep);
    if (w->lfd >= 0) {
        marie_loop_remove_fd(w->loop, w->lfd);
        close(w->lfd);
    }
    free(w);
}

void webserve_url(const webserve_t *w, const char *url_file, char *buf, size_t len)
{
    snprintf(buf, len, "http://%s:%d/", w->host, w->port);
    FILE *f = url_file && *url_file ? fopen(url_file, "w") : NULL;
    if (f) {
        fprintf(f, "%s\n", buf);
        fclose(f);
    }
}

int64_t webserve_frames_out(webserve_t *w)
{
    return w->st.frames_out;
}

void webserve_stats(const webserve_t *w, webserve_stats_t *s)
{
    *s = w->st;
}
