/* xb_doc: streaming parser (expat) that cuts a byte stream into XML documents and hands each
 * one over as an element tree, within limits on document size and nesting depth. */
#ifndef XB_DOC_H
#define XB_DOC_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* An error as the bridge reports it: a short machine-readable code and a human reason. */
typedef struct {
    char code[32];
    char reason[256];
} xb_error_t;

void xb_error_set(xb_error_t *e, const char *code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

typedef struct xb_node xb_node_t;
struct xb_node {
    const char *name;
    const char **attrs;         /* name, value, name, value, ..., NULL */
    char *text;                 /* character data directly inside, NUL-terminated */
    size_t text_len;
    xb_node_t *parent, *first, *last, *next;
    int nchildren;
};

const char *xb_node_attr(const xb_node_t *n, const char *name);   /* NULL if absent */
/* True when the text is empty or only XML whitespace. */
int xb_text_blank(const char *s, size_t len);

typedef struct {
    size_t max_doc_bytes;       /* from the first byte of a document to its end tag */
    int max_depth;              /* element nesting, the document element being 1 */
} xb_doc_limits_t;

#define XB_DOC_DEFAULT_MAX_BYTES (1u << 20)
#define XB_DOC_DEFAULT_MAX_DEPTH 32

/* Called once per complete document. The tree lives until the callback returns. The callback
 * must not destroy the parser. */
typedef void (*xb_doc_cb_t)(void *user, xb_node_t *root);

typedef struct xb_doc_parser xb_doc_parser_t;

xb_doc_parser_t *xb_doc_parser_create(const xb_doc_limits_t *lim, xb_doc_cb_t cb, void *user);
void xb_doc_parser_destroy(xb_doc_parser_t *p);     /* NULL is a no-op */
/* Feeds stream bytes; complete documents go to the callback. Returns 0, or -1 after a fatal
 * error (malformed XML, a DTD, a document over the limits): the stream cannot be resynchronised
 * and every later call returns -1. */
int xb_doc_parser_feed(xb_doc_parser_t *p, const void *buf, size_t len);
const xb_error_t *xb_doc_parser_error(const xb_doc_parser_t *p);
/* Nonzero while part of a document has been received but not its end. */
int xb_doc_parser_partial(const xb_doc_parser_t *p);
/* Bytes the parser holds now: the tree and text of the document being received, and expat's
 * own buffers. Linear in the size of that document. */
size_t xb_doc_parser_memory(const xb_doc_parser_t *p);

#ifdef __cplusplus
}
#endif
#endif
