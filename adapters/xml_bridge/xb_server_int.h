/* xb_server_int: what the XML bridge server's files share (not for use outside xb_server*.c,
 * xb_out.c, xb_requests.c): the client, subscription and server records and their helpers. */
#ifndef XB_SERVER_INT_H
#define XB_SERVER_INT_H

#include <stddef.h>
#include <stdint.h>

#include <lcm/lcm.h>

#include "adapters/xml_bridge/xb_codec.h"
#include "adapters/xml_bridge/xb_doc.h"
#include "adapters/xml_bridge/xb_server.h"
#include "core/loop.h"
#include "core/typeinfo.h"

/* One outgoing document, shared by every client it goes to. */
typedef struct {
    int refs;
    size_t len;
    char data[];
} msgbuf_t;

typedef struct {
    msgbuf_t *b;
    int notice;                 /* a <dropped> notice, written out when it is sent */
    uint64_t told;              /* the total that notice states */
} qent_t;

#define NOTICE_MAX 96

typedef struct sub sub_t;
typedef struct client client_t;

typedef struct {
    sub_t *sub;
    int stream;                 /* deliver every message (else only keep the latest) */
} csub_t;

struct client {
    xb_server_t *s;
    int fd;
    xb_doc_parser_t *parser;
    client_t *prev, *next;
    qent_t *q;                  /* ring, grown on demand up to queue_docs + 2 entries */
    int qhead, qlen, qcap;
    size_t qbytes;              /* bytes in the ring */
    qent_t cur;                 /* the document being written, and how much of it is */
    size_t off;
    uint64_t dropped_total;     /* documents lost to this client */
    uint64_t dropped_told;      /* the total in the last notice written to it */
    int notices;                /* notices queued, not yet being written */
    csub_t *subs;
    int nsubs;
    size_t capsubs;
    int64_t partial_since;      /* monotonic us when an unfinished document began, or 0 */
    int64_t active_us;          /* monotonic us of its connection or its last complete document */
    char addr[48];              /* the peer's address, numeric */
    size_t mem;                 /* parser memory charged to the budget */
    int64_t closing_since;      /* nonzero: close once the queue is written */
    int want_out;
    int dead;                   /* close at the next safe point */
};

struct sub {
    xb_server_t *s;
    char *channel;
    const marie_typeinfo_t *type;
    marie_bus_sub_t *ls;
    client_t **clients;         /* subscribed clients; csub says whether they stream */
    int *stream;
    int nclients, nstream;
    size_t capclients;
    char *latest;               /* newest raw payload */
    size_t latest_len;
    int64_t latest_utime;       /* wall clock at receipt */
    int has_latest;
    sub_t *next;
};

/* A publish waiting in the batch: its strings and payload are in the server's `batch` buffer. */
typedef struct {
    client_t *c;
    size_t channel, id;         /* offsets of NUL-terminated texts; id SIZE_MAX when absent */
    size_t data, len;           /* the encoded payload */
} pend_t;

/* Publishes answered only on failure wait in a batch until the read that brought them is
 * parsed (or the batch is full, or another request comes), so the datagrams of one read leave
 * together and their receivers wake once for several. */
#define XB_BATCH_MSGS 32
#define XB_BATCH_BYTES 65536

struct xb_server {
    xb_server_cfg_t cfg;
    char bind[64];
    lcm_t *lcm;
    marie_loop_t *loop;
    xb_server_hooks_t hooks;
    int lfd, port;
    marie_timer_t *sweep;
    client_t *clients;
    sub_t *subs;
    xb_server_stats_t st;
    marie_buf_t out;               /* scratch for one outgoing document */
    marie_buf_t enc;               /* scratch for one encoded LCM payload */
    marie_buf_t batch;             /* pending publishes' channels, ids and payloads */
    pend_t pend[XB_BATCH_MSGS];
    int npend;
};

/* xb_server.c: bad input goes to the component's counters (or the log). */
void xb_bad_input(xb_server_t *s, const char *counter, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* xb_out.c: outgoing documents and each client's queue. */
msgbuf_t *xb_msgbuf_new(const char *data, size_t len);     /* one reference, NULL if no memory */
void xb_msgbuf_unref(msgbuf_t *b);                          /* NULL is a no-op */
void xb_client_set_out(client_t *c, int on);                /* watch for writability or not */
void xb_client_enqueue(client_t *c, msgbuf_t *b);           /* takes its own reference */
void xb_client_enqueue_text(client_t *c, const char *data, size_t len);
void xb_client_flush(client_t *c);                          /* writes what the socket takes */

/* xb_requests.c: replies, requests and the LCM subscriptions behind them. */
void xb_reply_error(client_t *c, const xb_node_t *req, const char *code, const char *reason);
void xb_on_document(void *user, xb_node_t *req);            /* xb_doc callback; user: client */
void xb_sub_remove_client(xb_server_t *s, sub_t *u, client_t *c);
void xb_sub_release(xb_server_t *s, sub_t *u);              /* frees u once it has no client */
void xb_publish_flush(xb_server_t *s);          /* publishes the batch, in order; replies to failures */

#endif
