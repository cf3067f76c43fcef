/* webserve: the web pages' server on the process's loop: a few known files over HTTP/1.1 and one
 * WebSocket per page (webproto.c), every socket an fd of the loop, written without waiting.
 * Shared by the engineers' viewer and the touch page. Each page has a bounded queue: a page
 * that reads too slowly loses its oldest state frames (counted) and, past the hard bound, is
 * closed; it never holds up the loop or the other pages. */
#ifndef TOOLS_WEBSERVE_H
#define TOOLS_WEBSERVE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/component.h"
#include "core/loop.h"
#include "tools/webcommon/vjson.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct webserve webserve_t;

/* Pages open at once (a WebSocket each); connections at once (pages and file requests). */
#define WEBSERVE_MAX_PAGES 8
#define WEBSERVE_MAX_CONNS 64
/* A page's queue: droppable frames go, oldest first, while more than SOFT bytes wait; a page
 * with more than HARD bytes waiting is closed (it reconnects and is sent the state afresh). */
#define WEBSERVE_QUEUE_SOFT (2u << 20)
#define WEBSERVE_QUEUE_HARD (16u << 20)
/* A connection that has not sent a whole request head this long after the last is closed. */
#define WEBSERVE_REQUEST_TIMEOUT_MS 10000

/* A file of the page: served at uri from the www folder; nothing else is. */
typedef struct {
    const char *uri, *file, *mime;
} webserve_file_t;

/* A command from a page (text, a JSON object), or hello = true when a page connected (send it
 * the present state); addr is the page's address as the server saw it ("127.0.0.1"). Runs in
 * the loop's thread. */
typedef void (*webserve_cmd_fn)(void *user, int client, const char *addr, bool hello, const char *text, size_t len);

typedef struct {
    const char *www;                /* folder of the files */
    const webserve_file_t *files;   /* the page's files (copied by reference: static tables) */
    size_t nfiles;
    const char *name;               /* in log messages */
    webserve_cmd_fn on_cmd;
    void *user;
    /* Optional: malformed requests and frames are counted as its bad input ("web_requests"),
     * dropped frames and closed slow pages as its "web_dropped" and "web_slow_closed". */
    marie_component_t *comp;
} webserve_cfg_t;

typedef struct {
    int64_t frames_out;         /* frames handed to pages (one per page per send) */
    int64_t dropped;            /* frames a slow page lost */
    int64_t slow_closed;        /* pages closed past WEBSERVE_QUEUE_HARD */
    int64_t bad_requests;       /* malformed requests and frames, refused origins */
    int64_t refused;            /* pages and connections over the bounds */
    int pages, conns;           /* open now */
} webserve_stats_t;

/* Serves on bind:port (the component's bind and http_port parameters, e.g. 127.0.0.1 and 8080;
 * port 0: any free port), with the WebSocket at /ws (same-origin pages only). NULL with a reason
 * in why. */
webserve_t *webserve_start(marie_loop_t *loop, const char *bind, int port, const webserve_cfg_t *cfg, char *why,
                           size_t len);
/* Closes every page and connection; NULL is a no-op. */
void webserve_stop(webserve_t *w);
/* The page's address, http://HOST:PORT/ (127.0.0.1 when serving on every address), into
 * buf; also written to url_file, a line, when that is a path (scripts and tests read it). */
void webserve_url(const webserve_t *w, const char *url_file, char *buf, size_t len);
/* Sends text to page `id`, or to every page when id < 0: written now as far as the socket
 * takes it, the rest queued for the loop. Droppable frames (high-rate state) make room by
 * dropping the page's oldest droppable frames while it is more than WEBSERVE_QUEUE_SOFT behind. */
void webserve_send(webserve_t *w, int id, const char *data, size_t len, bool droppable);
void webserve_send_json(webserve_t *w, int id, const marie_buf_t *b, bool droppable);
/* {"type":"notice","level":...,"text":...} */
void webserve_notice(webserve_t *w, int id, const char *level, const char *text);
int64_t webserve_frames_out(webserve_t *w);
void webserve_stats(const webserve_t *w, webserve_stats_t *s);

#ifdef __cplusplus
}
#endif
#endif
