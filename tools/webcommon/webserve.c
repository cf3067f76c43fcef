/* webserve: the web pages' server (civetweb), shared by the viewer and the touch page. */
#include "tools/webcommon/webserve.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <civetweb.h>

#include "core/err.h"
#include "core/log.h"

typedef struct frame {
    struct frame *next;
    size_t len;
    char data[];
} frame_t;

typedef struct client {
    struct client *next;
    int id;
    char addr[48];              /* the page's address */
    struct mg_connection *conn;
    pthread_t writer;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    frame_t *head, *tail;
    size_t queued;
    bool closing, dead;
    int64_t dropped;
} client_t;

/* A command from a page, handed from civetweb's threads to the loop. */
typedef struct cmd {
    struct cmd *next;
    int client;                 /* -1: none */
    char addr[48];
    bool hello;                 /* a new client: send it the state */
    size_t len;
    char text[];
} cmd_t;

struct webserve {
    webserve_cfg_t cfg;
    marie_loop_t *loop;
    struct mg_context *http;
    char host[64];              /* of the page's address: bind, or 127.0.0.1 for every address */
    int port;                   /* the port served on (the one picked for port 0) */
    pthread_mutex_t mu;         /* clients list, cmd queue, frames_out */
    client_t *clients;
    int npages;                 /* clients on the list: at most WEBSERVE_MAX_PAGES */
    int next_client_id;
    cmd_t *cmd_head, *cmd_tail;
    int wake[2];
    int64_t frames_out;
};

static void *writer_main(void *arg)
{
    client_t *cl = arg;
    pthread_mutex_lock(&cl->mu);
    for (;;) {
        while (!cl->head && !cl->closing)
            pthread_cond_wait(&cl->cv, &cl->mu);
        if (!cl->head)
            break;
        frame_t *f = cl->head;
        cl->head = f->next;
        if (!cl->head)
            cl->tail = NULL;
        cl->queued -= f->len;
        bool dead = cl->dead;
        pthread_mutex_unlock(&cl->mu);
        if (!dead && mg_websocket_write(cl->conn, MG_WEBSOCKET_OPCODE_TEXT, f->data, f->len) <= 0)
            dead = true;
        free(f);
        pthread_mutex_lock(&cl->mu);
        cl->dead |= dead;
    }
    pthread_mutex_unlock(&cl->mu);
    return NULL;
}

/* Queue a frame for one client. Droppable frames (high-rate state) are dropped while the
 * client is more than 2 MB behind, so a slow browser never stalls the bus. */
static void client_send(client_t *cl, const char *data, size_t len, bool droppable)
{
    pthread_mutex_lock(&cl->mu);
    if (cl->dead || cl->closing || (droppable && cl->queued > (2u << 20))) {
        cl->dropped++;
        pthread_mutex_unlock(&cl->mu);
        return;
    }
    frame_t *f = malloc(sizeof *f + len);
    if (f) {
        f->next = NULL;
        f->len = len;
        memcpy(f->data, data, len);
        if (cl->tail)
            cl->tail->next = f;
        else
            cl->head = f;
        cl->tail = f;
        cl->queued += len;
        pthread_cond_signal(&cl->cv);
    } else {
        cl->dropped++;
    }
    pthread_mutex_unlock(&cl->mu);
}

void webserve_send(webserve_t *v, int id, const char *data, size_t len, bool droppable)
{
    pthread_mutex_lock(&v->mu);
    for (client_t *cl = v->clients; cl; cl = cl->next)
        if (id < 0 || cl->id == id) {
            client_send(cl, data, len, droppable);
            v->frames_out++;
        }
    pthread_mutex_unlock(&v->mu);
}

void webserve_send_json(webserve_t *v, int id, const marie_buf_t *b, bool droppable)
{
    if (!b->failed && b->len)
        webserve_send(v, id, b->data, b->len, droppable);
}

void webserve_notice(webserve_t *v, int id, const char *level, const char *text)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_puts(&b, "{\"type\":\"notice\",\"level\":");
    vj_str(&b, level);
    marie_buf_puts(&b, ",\"text\":");
    vj_str(&b, text);
    marie_buf_puts(&b, "}");
    webserve_send_json(v, id, &b, false);
    marie_buf_free(&b);
}

static void push_cmd(webserve_t *v, const client_t *cl, bool hello, const char *text, size_t len)
{
    cmd_t *c = malloc(sizeof *c + len + 1);
    if (!c)
        return;
    c->next = NULL;
    c->client = cl->id;
    memcpy(c->addr, cl->addr, sizeof c->addr);
    c->hello = hello;
    c->len = len;
    memcpy(c->text, text, len);
    c->text[len] = 0;
    pthread_mutex_lock(&v->mu);
    if (v->cmd_tail)
        v->cmd_tail->next = c;
    else
        v->cmd_head = c;
    v->cmd_tail = c;
    pthread_mutex_unlock(&v->mu);
    char one = 1;
    if (write(v->wake[1], &one, 1) < 0 && errno != EAGAIN)
        marie_warn("%s: wake-up pipe: %s", v->cfg.name, strerror(errno));
}

/* ---------------------------------------------------------------- civetweb handlers */

static bool pages_full(webserve_t *v)
{
    pthread_mutex_lock(&v->mu);
    bool full = v->npages >= WEBSERVE_MAX_PAGES;
    pthread_mutex_unlock(&v->mu);
    if (full)
        marie_warn_ratelimited(10, "%s: %d pages open already: another one refused", v->cfg.name,
                               WEBSERVE_MAX_PAGES);
    return full;
}

/* A page over the bound (two opened at the same moment) is told to try again later (1013). */
static void refuse_page(struct mg_connection *conn)
{
    static const char why[] = "\x03\xf5too many pages";
    mg_websocket_write(conn, MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE, why, sizeof why - 1);
}

/* Only pages served by this server may open the WebSocket: another site open in the same
 * browser must not be able to send orders to the robot. Nor may a page past the bound. */
static int ws_connect(const struct mg_connection *conn, void *ud)
{
    const char *origin = mg_get_header(conn, "Origin");
    const char *host = mg_get_header(conn, "Host");
    if (pages_full(ud))
        return 1;
    if (!origin)
        return 0;                               /* not a browser */
    if (!host || strncmp(origin, "http://", 7) != 0 || strcmp(origin + 7, host) != 0) {
        marie_warn_ratelimited(10, "web page: WebSocket from origin %s refused (host %s)", origin,
                               host ? host : "?");
        return 1;
    }
    return 0;
}

static void ws_ready(struct mg_connection *conn, void *ud)
{
    webserve_t *v = ud;
    client_t *cl = calloc(1, sizeof *cl);
    if (!cl) {
        refuse_page(conn);
        return;
    }
    cl->conn = conn;
    snprintf(cl->addr, sizeof cl->addr, "%s", mg_get_request_info(conn)->remote_addr);
    pthread_mutex_init(&cl->mu, NULL);
    pthread_cond_init(&cl->cv, NULL);
    pthread_mutex_lock(&v->mu);
    bool room = v->npages < WEBSERVE_MAX_PAGES && pthread_create(&cl->writer, NULL, writer_main, cl) == 0;
    if (room) {
        cl->id = v->next_client_id++;
        cl->next = v->clients;
        v->clients = cl;
        v->npages++;
    }
    pthread_mutex_unlock(&v->mu);
    if (!room) {
        pthread_mutex_destroy(&cl->mu);
        pthread_cond_destroy(&cl->cv);
        free(cl);
        refuse_page(conn);
        return;
    }
    mg_set_user_connection_data(conn, cl);
    push_cmd(v, cl, true, "", 0);
}

static int ws_data(struct mg_connection *conn, int bits, char *data, size_t len, void *ud)
{
    webserve_t *v = ud;
    client_t *cl = mg_get_user_connection_data(conn);
    int op = bits & 0xf;
    if (op == MG_WEBSOCKET_OPCODE_CONNECTION_CLOSE)
        return 0;
    if (op == MG_WEBSOCKET_OPCODE_TEXT && cl && len <= 4096)
        push_cmd(v, cl, false, data, len);
    return 1;
}

static void ws_close(const struct mg_connection *conn, void *ud)
{
    webserve_t *v = ud;
    client_t *cl = mg_get_user_connection_data(conn);
    if (!cl)
        return;
    pthread_mutex_lock(&v->mu);
    for (client_t **pp = &v->clients; *pp; pp = &(*pp)->next)
        if (*pp == cl) {
            *pp = cl->next;
            v->npages--;
            break;
        }
    pthread_mutex_unlock(&v->mu);
    pthread_mutex_lock(&cl->mu);
    cl->closing = true;
    cl->dead = true;
    pthread_cond_signal(&cl->cv);
    pthread_mutex_unlock(&cl->mu);
    pthread_join(cl->writer, NULL);
    for (frame_t *f = cl->head, *n; f; f = n) {
        n = f->next;
        free(f);
    }
    pthread_mutex_destroy(&cl->mu);
    pthread_cond_destroy(&cl->cv);
    free(cl);
}

/* The page is three known files: nothing else under www is served (no directory listing,
 * CGI or SSI, whatever the folder holds). */
static int http_page(struct mg_connection *conn, void *ud)
{
    webserve_t *v = ud;
    const char *uri = mg_get_request_info(conn)->local_uri;
    for (size_t i = 0; uri && i < v->cfg.nfiles; i++)
        if (strcmp(uri, v->cfg.files[i].uri) == 0) {
            char path[PATH_MAX + 32];
            snprintf(path, sizeof path, "%s/%s", v->cfg.www, v->cfg.files[i].file);
            mg_send_mime_file(conn, path, v->cfg.files[i].mime);
            return 200;
        }
    mg_send_http_error(conn, 404, "%s", "not found");
    return 404;
}

static int log_message(const struct mg_connection *conn, const char *msg)
{
    marie_warn_ratelimited(10, "web page: http: %s", msg);
    return 1;
}

static void on_wake(marie_loop_t *loop, int fd, short revents, void *user)
{
    webserve_t *v = user;
    char buf[256];
    while (read(fd, buf, sizeof buf) > 0)
        ;
    for (;;) {
        pthread_mutex_lock(&v->mu);
        cmd_t *c = v->cmd_head;
        if (c) {
            v->cmd_head = c->next;
            if (!v->cmd_head)
                v->cmd_tail = NULL;
        }
        pthread_mutex_unlock(&v->mu);
        if (!c)
            break;
        v->cfg.on_cmd(v->cfg.user, c->client, c->addr, c->hello, c->text, c->len);
        free(c);
    }
}

webserve_t *webserve_start(marie_loop_t *loop, const char *bind, int port, const webserve_cfg_t *cfg, char *why,
                           size_t len)
{
    webserve_t *v = calloc(1, sizeof *v);
    if (!v) {
        snprintf(why, len, "out of memory");
        return NULL;
    }
    v->cfg = *cfg;
    snprintf(v->host, sizeof v->host, "%s", strcmp(bind, "0.0.0.0") == 0 ? "127.0.0.1" : bind);
    v->loop = loop;
    v->wake[0] = v->wake[1] = -1;
    pthread_mutex_init(&v->mu, NULL);
    if (pipe2(v->wake, O_NONBLOCK | O_CLOEXEC) < 0 || marie_loop_add_fd(loop, v->wake[0], POLLIN, on_wake, v) < 0) {
        snprintf(why, len, "cannot set up the loop: %s", strerror(errno));
        MARIE_KEEP_ERRNO(webserve_stop(v));
        return NULL;
    }
    char listen[128], threads[16];
    snprintf(threads, sizeof threads, "%d", WEBSERVE_MAX_PAGES + WEBSERVE_HTTP_THREADS);
    snprintf(listen, sizeof listen, "%s:%d", bind, port);
    const char *opts[] = {
        "listening_ports", listen, "num_threads", threads, "websocket_timeout_ms", "3600000", "tcp_nodelay", "1", NULL,
    };
    struct mg_callbacks cb = {0};
    cb.log_message = log_message;
    mg_init_library(0);
    v->http = mg_start(&cb, v, opts);
    if (!v->http) {
        snprintf(why, len, "cannot serve HTTP on %s (port in use?)", listen);
        errno = EADDRINUSE;
        MARIE_KEEP_ERRNO(webserve_stop(v));
        return NULL;
    }
    mg_set_websocket_handler(v->http, "/ws", ws_connect, ws_ready, ws_data, ws_close, v);
    mg_set_request_handler(v->http, "/", http_page, v);
    struct mg_server_port sp[4];
    int np = mg_get_server_ports(v->http, 4, sp);
    v->port = np > 0 ? sp[0].port : port;
    return v;
}

void webserve_stop(webserve_t *v)
{
    if (!v)
        return;
    if (v->http)
        mg_stop(v->http);               /* closes every WebSocket: their writers are joined */
    for (cmd_t *x = v->cmd_head, *n; x; x = n) {
        n = x->next;
        free(x);
    }
    if (v->wake[0] >= 0) {
        marie_loop_remove_fd(v->loop, v->wake[0]);
        close(v->wake[0]);
        close(v->wake[1]);
    }
    pthread_mutex_destroy(&v->mu);
    free(v);
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

int64_t webserve_frames_out(webserve_t *v)
{
    pthread_mutex_lock(&v->mu);
    int64_t n = v->frames_out;
    pthread_mutex_unlock(&v->mu);
    return n;
}
