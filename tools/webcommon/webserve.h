/* webserve: the web pages' server (civetweb): a few known files, one WebSocket per page with a
 * writer thread each, and the pages' commands handed to the process's loop. Shared by the
 * engineers' viewer and the touch page. civetweb serves a connection per worker thread and
 * writes a WebSocket blocking, so the threads stay (docs/architecture.md); they are bounded:
 * WEBSERVE_MAX_PAGES pages at once, the next one refused until one closes. */
#ifndef TOOLS_WEBSERVE_H
#define TOOLS_WEBSERVE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "core/loop.h"
#include "tools/webcommon/vjson.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct webserve webserve_t;

/* Pages open at once (a WebSocket each, with a civetweb worker and a writer thread); the
 * server's other WEBSERVE_HTTP_THREADS workers serve the files meanwhile. */
#define WEBSERVE_MAX_PAGES 8
#define WEBSERVE_HTTP_THREADS 8

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
} webserve_cfg_t;

/* Serves on bind:port (the component's bind and http_port parameters, e.g. 127.0.0.1 and 8080;
 * port 0: any free port), with the WebSocket at /ws (same-origin pages only). NULL with a reason
 * in why. */
webserve_t *webserve_start(marie_loop_t *loop, const char *bind, int port, const webserve_cfg_t *cfg, char *why,
                           size_t len);
/* Closes every page and joins their writers; NULL is a no-op. */
void webserve_stop(webserve_t *w);
/* The page's address, http://HOST:PORT/ (127.0.0.1 when serving on every address), into
 * buf; also written to url_file, a line, when that is a path (scripts and tests read it). */
void webserve_url(const webserve_t *w, const char *url_file, char *buf, size_t len);
/* Sends text to page `id`, or to every page when id < 0. Droppable frames (high-rate state)
 * are dropped while a page is more than 2 MB behind, so a slow browser never stalls the bus. */
void webserve_send(webserve_t *w, int id, const char *data, size_t len, bool droppable);
void webserve_send_json(webserve_t *w, int id, const marie_buf_t *b, bool droppable);
/* {"type":"notice","level":...,"text":...} */
void webserve_notice(webserve_t *w, int id, const char *level, const char *text);
int64_t webserve_frames_out(webserve_t *w);

#ifdef __cplusplus
}
#endif
#endif
