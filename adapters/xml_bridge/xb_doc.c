/* xb_doc: cuts a stream into XML documents with expat, resetting the parser after each one. */
#include "adapters/xml_bridge/xb_doc.h"

#include <dlfcn.h>
#include <expat.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <time.h>

void xb_error_set(xb_error_t *e, const char *code, const char *fmt, ...)
{
    if (!e)
        return;
    snprintf(e->code, sizeof e->code, "%s", code);
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(e->reason, sizeof e->reason, fmt, ap);
    va_end(ap);
}

const char *xb_node_attr(const xb_node_t *n, const char *name)
{
    for (const char **a = n->attrs; a && a[0]; a += 2)
        if (strcmp(a[0], name) == 0)
            return a[1];
    return NULL;
}

int xb_text_blank(const char *s, size_t len)
{
    for (size_t i = 0; i < len; i++)
        if (s[i] != ' ' && s[i] != '\t' && s[i] != '\n' && s[i] != '\r')
            return 0;
    return 1;
}

/* Bump allocator for one document's tree; reset (not freed) between documents. */
typedef struct chunk {
    struct chunk *next;
    size_t size, used;
    char data[];
} chunk_t;

struct xb_doc_parser {
    XML_Parser xp;
    xb_doc_limits_t lim;
    xb_doc_cb_t cb;
    void *user;
    chunk_t *chunks;            /* newest first */
    xb_node_t *root, *cur;
    int depth;
    int started;                /* a document's first byte has been fed since the reset */
    int failed;                 /* fatal error happened */
    int limit_hit;              /* a handler stopped the parser on a limit */
    int done;                   /* the document element has ended (parser suspended) */
    long long fed;              /* bytes given to expat since the reset */
    long long doc_end;          /* offset just past the document element's end tag */
    uint64_t documents;
    unsigned long salt;
    xb_error_t err;
};

/* Chunks start small (an idle client costs little) and double up to 64 KiB. */
static void *arena_alloc(xb_doc_parser_t *p, size_t n)
{
    n = (n + 15) & ~(size_t)15;
    chunk_t *c = p->chunks;
    if (!c || c->size - c->used < n) {
        size_t size = c ? c->size * 2 : 2048;
        if (size > 65536)
            size = 65536;
        if (size < n)
            size = n;
        c = malloc(sizeof *c + size);
        if (!c)
            return NULL;
        c->size = size;
        c->used = 0;
        c->next = p->chunks;
        p->chunks = c;
    }
    void *r = c->data + c->used;
    c->used += n;
    return r;
}

static void arena_reset(xb_doc_parser_t *p)
{
    /* Keep the largest chunk up to 64 KiB so the next document of the same size allocates
     * nothing; free the rest. */
    chunk_t *keep = NULL;
    for (chunk_t *c = p->chunks; c; c = c->next)
        if (c->size <= 65536 && (!keep || c->size > keep->size))
            keep = c;
    while (p->chunks) {
        chunk_t *n = p->chunks->next;
        if (p->chunks != keep)
            free(p->chunks);
        p->chunks = n;
    }
    if (keep) {
        keep->next = NULL;
        keep->used = 0;
    }
    p->chunks = keep;
}

static char *arena_strdup(xb_doc_parser_t *p, const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = arena_alloc(p, n);
    if (d)
        memcpy(d, s, n);
    return d;
}

static void fail(xb_doc_parser_t *p, const char *code, const char *fmt, const char *arg)
{
    if (p->limit_hit)
        return;
    p->limit_hit = 1;
    xb_error_set(&p->err, code, fmt, arg);
    XML_StopParser(p->xp, XML_FALSE);
}

static int over_size(xb_doc_parser_t *p)
{
    long long at = XML_GetCurrentByteIndex(p->xp) + XML_GetCurrentByteCount(p->xp);
    if (at > (long long)p->lim.max_doc_bytes) {
        char lim[32];
        snprintf(lim, sizeof lim, "%zu", p->lim.max_doc_bytes);
        fail(p, "too-large", "document larger than %s bytes", lim);
        return 1;
    }
    return 0;
}

static void XMLCALL on_start(void *ud, const XML_Char *name, const XML_Char **attrs)
{
    xb_doc_parser_t *p = ud;
    if (p->limit_hit || over_size(p))
        return;
    if (++p->depth > p->lim.max_depth) {
        char lim[16];
        snprintf(lim, sizeof lim, "%d", p->lim.max_depth);
        fail(p, "too-deep", "elements nested deeper than %s", lim);
        return;
    }
    size_t na = 0;
    while (attrs[na])
        na++;
    xb_node_t *n = arena_alloc(p, sizeof *n);
    const char **a = arena_alloc(p, (na + 1) * sizeof *a);
    if (!n || !a) {
        fail(p, "no-memory", "%s", "out of memory");
        return;
    }
    memset(n, 0, sizeof *n);
    n->name = arena_strdup(p, name);
    for (size_t i = 0; i < na; i++)
        a[i] = arena_strdup(p, attrs[i]);
    a[na] = NULL;
    n->attrs = a;
    n->text = (char *)"";
    n->parent = p->cur;
    if (p->cur) {
        if (p->cur->last)
            p->cur->last->next = n;
        else
            p->cur->first = n;
        p->cur->last = n;
        p->cur->nchildren++;
    } else {
        p->root = n;
    }
    p->cur = n;
}

static void XMLCALL on_end(void *ud, const XML_Char *name)
{
    xb_doc_parser_t *p = ud;
    if (p->limit_hit)
        return;
    p->depth--;
    p->cur = p->cur ? p->cur->parent : NULL;
    if (p->depth == 0) {
        p->doc_end = XML_GetCurrentByteIndex(p->xp) + XML_GetCurrentByteCount(p->xp);
        p->done = 1;
        XML_StopParser(p->xp, XML_TRUE);
    }
}

static void XMLCALL on_text(void *ud, const XML_Char *s, int len)
{
    xb_doc_parser_t *p = ud;
    if (p->limit_hit || !p->cur || over_size(p))
        return;
    xb_node_t *n = p->cur;
    chunk_t *c = p->chunks;
    /* Extend in place when the text is the arena's last allocation (the usual case). */
    if (n->text_len > 0 && c && n->text >= c->data && n->text < c->data + c->used) {
        size_t off = (size_t)(n->text - c->data);
        size_t have = (n->text_len + 1 + 15) & ~(size_t)15;
        size_t need = (n->text_len + (size_t)len + 1 + 15) & ~(size_t)15;
        if (off + have == c->used && off + need <= c->size) {
            c->used = off + need;
            memcpy(n->text + n->text_len, s, (size_t)len);
            n->text_len += (size_t)len;
            n->text[n->text_len] = '\0';
            return;
        }
    }
    char *t = arena_alloc(p, n->text_len + (size_t)len + 1);
    if (!t) {
        fail(p, "no-memory", "%s", "out of memory");
        return;
    }
    memcpy(t, n->text, n->text_len);
    memcpy(t + n->text_len, s, (size_t)len);
    n->text_len += (size_t)len;
    t[n->text_len] = '\0';
    n->text = t;
}

static void XMLCALL on_doctype(void *ud, const XML_Char *name, const XML_Char *sysid,
                               const XML_Char *pubid, int has_internal_subset)
{
    fail(ud, "malformed", "%s", "document type declarations are not accepted");
}

/* Expat 2.6 (and Debian 12's security updates of 2.5) defers parsing a token until more bytes
 * arrive, to bound the cost of huge tokens fed in tiny pieces; a document cut off the stream
 * then ends later than its last byte, and a client writing byte by byte sees its documents
 * refused. The bridge bounds token sizes itself (max_document), so deferral is turned off where
 * the library has the switch. Looked up at run time: older expat headers do not declare it. */
static void no_reparse_deferral(XML_Parser xp)
{
    typedef XML_Bool (*set_deferral_fn)(XML_Parser, XML_Bool);
    static set_deferral_fn set;
    static int looked;
    if (!looked) {
        set = (set_deferral_fn)dlsym(RTLD_DEFAULT, "XML_SetReparseDeferralEnabled");
        looked = 1;
    }
    if (set)
        set(xp, XML_FALSE);
}

static int setup(xb_doc_parser_t *p)
{
    if (!p->xp)
        p->xp = XML_ParserCreate("UTF-8");
    else if (!XML_ParserReset(p->xp, "UTF-8"))
        return -1;
    if (!p->xp)
        return -1;
    /* One random hash salt per parser: a reset would otherwise draw a new one every time. */
    XML_SetHashSalt(p->xp, p->salt);
    no_reparse_deferral(p->xp);
    XML_SetUserData(p->xp, p);
    XML_SetElementHandler(p->xp, on_start, on_end);
    XML_SetCharacterDataHandler(p->xp, on_text);
    XML_SetStartDoctypeDeclHandler(p->xp, on_doctype);
#if XML_MAJOR_VERSION > 2 || (XML_MAJOR_VERSION == 2 && XML_MINOR_VERSION >= 6)
    /* Replies must not wait for the next bytes; the size limit bounds reparsing instead. */
    XML_SetReparseDeferralEnabled(p->xp, XML_FALSE);
#endif
    arena_reset(p);
    p->root = p->cur = NULL;
    p->depth = 0;
    p->started = 0;
    p->done = 0;
    p->fed = 0;
    return 0;
}

xb_doc_parser_t *xb_doc_parser_create(const xb_doc_limits_t *lim, xb_doc_cb_t cb, void *user)
{
    xb_doc_parser_t *p = calloc(1, sizeof *p);
    if (!p)
        return NULL;
    p->lim.max_doc_bytes = lim && lim->max_doc_bytes ? lim->max_doc_bytes : XB_DOC_DEFAULT_MAX_BYTES;
    p->lim.max_depth = lim && lim->max_depth > 0 ? lim->max_depth : XB_DOC_DEFAULT_MAX_DEPTH;
    p->cb = cb;
    p->user = user;
    if (getrandom(&p->salt, sizeof p->salt, 0) != sizeof p->salt)
        p->salt = (unsigned long)(uintptr_t)p ^ (unsigned long)time(NULL);
    if (setup(p) < 0) {
        xb_doc_parser_destroy(p);
        return NULL;
    }
    return p;
}

void xb_doc_parser_destroy(xb_doc_parser_t *p)
{
    if (!p)
        return;
    if (p->xp)
        XML_ParserFree(p->xp);
    while (p->chunks) {
        chunk_t *n = p->chunks->next;
        free(p->chunks);
        p->chunks = n;
    }
    free(p);
}

static int fatal(xb_doc_parser_t *p)
{
    if (!p->limit_hit) {
        enum XML_Error e = XML_GetErrorCode(p->xp);
        xb_error_set(&p->err, e == XML_ERROR_NO_MEMORY ? "no-memory" : "malformed",
                     "line %lu column %lu: %s", (unsigned long)XML_GetCurrentLineNumber(p->xp),
                     (unsigned long)XML_GetCurrentColumnNumber(p->xp), XML_ErrorString(e));
    }
    p->failed = 1;
    return -1;
}

int xb_doc_parser_feed(xb_doc_parser_t *p, const void *buf, size_t len)
{
    const char *s = buf;
    if (p->failed)
        return -1;
    while (len > 0) {
        if (!p->started) {
            /* Whitespace between documents is not part of either (an XML declaration must
             * be the very first thing a document's parser sees). */
            while (len > 0 && (*s == ' ' || *s == '\t' || *s == '\n' || *s == '\r')) {
                s++;
                len--;
            }
            if (len == 0)
                return 0;
            p->started = 1;
        }
        /* Expat copies what follows a suspension (the end of a document) into its own buffer:
         * small pieces keep that copy small when many documents share one read. */
        int n = len > 2048 ? 2048 : (int)len;
        enum XML_Status st = XML_Parse(p->xp, s, n, XML_FALSE);
        if (st == XML_STATUS_ERROR || p->limit_hit)
            return fatal(p);
        if (st == XML_STATUS_SUSPENDED && p->done) {
            size_t used = (size_t)(p->doc_end - p->fed);
            if (used > (size_t)n)
                used = (size_t)n;
            p->documents++;
            if (p->cb && p->root)
                p->cb(p->user, p->root);
            if (setup(p) < 0) {
                xb_error_set(&p->err, "no-memory", "%s", "cannot reset the XML parser");
                p->failed = 1;
                return -1;
            }
            s += used;
            len -= used;
            continue;
        }
        p->fed += n;
        if (p->fed > (long long)p->lim.max_doc_bytes) {
            xb_error_set(&p->err, "too-large", "document larger than %zu bytes", p->lim.max_doc_bytes);
            p->failed = 1;
            return -1;
        }
        s += n;
        len -= (size_t)n;
    }
    return 0;
}

const xb_error_t *xb_doc_parser_error(const xb_doc_parser_t *p)
{
    return &p->err;
}

int xb_doc_parser_partial(const xb_doc_parser_t *p)
{
    return p->started && !p->failed;
}

uint64_t xb_doc_parser_documents(const xb_doc_parser_t *p)
{
    return p->documents;
}
