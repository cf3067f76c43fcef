/* xb_doc: cuts a stream into XML documents with expat, resetting the parser after each one. */
#include "adapters/xml_bridge/xb_doc.h"

#include <expat.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/random.h>
#include <time.h>
#include <unistd.h>
#include "core/log.h"

void xb_error_set(xb_error_t *e, const char *code, const char *fmt, ...)
{
    if (!e)
        return;
    snprintf(e->code, sizeof e->code, "%s", code);
    MARIE_VFORMAT(e->reason, fmt);
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

/* Reparse deferral came with expat 2.6.0, and with security backports that keep 2.5.0's version
 * number (Debian 12's 2.5.0-1+deb12u5): whether it exists is known only when linking, so the
 * bridge asks for it weakly and turns it off wherever it is (deferred, a document split in
 * small pieces waits for bytes that may never come, and is misparsed after a reset). */
XMLPARSEAPI(XML_Bool) XML_SetReparseDeferralEnabled(XML_Parser parser, XML_Bool enabled)
    __attribute__((weak));

/* Bump allocator for one document's tree; reset (not freed) between documents. */
typedef struct chunk {
    struct chunk *next;
    size_t size, used;
    char data[];
} chunk_t;

/* Texts up to this size grow inside the arena; longer ones move to a mapping of their own that
 * grows in place (mremap), so a long text costs its length once, whatever its chunking. */
#define TEXT_ARENA_MAX 16384

/* A node as the parser keeps it: the public part, and where its text may grow. */
typedef struct pnode {
    xb_node_t pub;
    size_t cap;                 /* bytes the text's storage holds, NUL included (0: none) */
    size_t map_len;             /* nonzero: the text is a private mapping of this length */
    struct pnode *next_map;     /* nodes with mapped texts, unmapped at reset */
} pnode_t;

struct xb_doc_parser {
    XML_Parser xp;
    xb_doc_limits_t lim;
    xb_doc_cb_t cb;
    void *user;
    chunk_t *chunks;            /* newest first */
    pnode_t *mapped;            /* nodes whose text is mapped */
    size_t arena_bytes;         /* chunk sizes */
    size_t expat_bytes;         /* what expat allocated for this parser */
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

/* ---- expat's allocations, charged to the parser they serve ----
 * Expat's allocator hooks take no context; the parser being worked on is set around each call
 * into expat, and every block remembers whom it was charged to. */
typedef struct {
    xb_doc_parser_t *owner;
    size_t size;
} mm_head_t;
#define MM_HEAD 16              /* keeps malloc's alignment for expat's blocks */
_Static_assert(sizeof(mm_head_t) <= MM_HEAD, "allocation header too large");

static __thread xb_doc_parser_t *mm_owner;

static void *mm_malloc(size_t n)
{
    char *b = n < SIZE_MAX - MM_HEAD ? malloc(n + MM_HEAD) : NULL;
    if (!b)
        return NULL;
    mm_head_t *h = (mm_head_t *)b;
    h->owner = mm_owner;
    h->size = n;
    if (h->owner)
        h->owner->expat_bytes += n;
    return b + MM_HEAD;
}

static void mm_free(void *ptr)
{
    if (!ptr)
        return;
    mm_head_t *h = (mm_head_t *)((char *)ptr - MM_HEAD);
    if (h->owner)
        h->owner->expat_bytes -= h->size;
    free(h);
}

static void *mm_realloc(void *ptr, size_t n)
{
    if (!ptr)
        return mm_malloc(n);
    mm_head_t *h = (mm_head_t *)((char *)ptr - MM_HEAD);
    xb_doc_parser_t *owner = h->owner;
    size_t old = h->size;
    char *b = n < SIZE_MAX - MM_HEAD ? realloc(h, n + MM_HEAD) : NULL;
    if (!b)
        return NULL;
    h = (mm_head_t *)b;
    h->size = n;
    if (owner)
        owner->expat_bytes += n - old;      /* modular: a shrink subtracts */
    return b + MM_HEAD;
}

static const XML_Memory_Handling_Suite mm_suite = { mm_malloc, mm_realloc, mm_free };

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
        p->arena_bytes += size;
    }
    void *r = c->data + c->used;
    c->used += n;
    return r;
}

static void arena_reset(xb_doc_parser_t *p)
{
    for (pnode_t *n = p->mapped; n; n = n->next_map)
        munmap(n->pub.text, n->map_len);
    p->mapped = NULL;
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
    p->arena_bytes = 0;
    if (keep) {
        keep->next = NULL;
        keep->used = 0;
        p->arena_bytes = keep->size;
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
    pnode_t *pn = arena_alloc(p, sizeof *pn);
    const char **a = arena_alloc(p, (na + 1) * sizeof *a);
    if (!pn || !a) {
        fail(p, "no-memory", "%s", "out of memory");
        return;
    }
    memset(pn, 0, sizeof *pn);
    xb_node_t *n = &pn->pub;
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

static size_t page_round(size_t n)
{
    size_t pg = (size_t)sysconf(_SC_PAGESIZE);
    return (n + pg - 1) / pg * pg;
}

/* Makes room for `need` bytes of text (NUL included) in n's storage, keeping the text; 0 or -1.
 * Storage grows geometrically, so a text costs O(length) whatever the size of its pieces. */
static int text_reserve(xb_doc_parser_t *p, pnode_t *n, size_t need)
{
    xb_node_t *x = &n->pub;
    if (need <= n->cap)
        return 0;
    if (n->map_len) {
        size_t len = page_round(need + need / 4);
        void *m = mremap(x->text, n->map_len, len, MREMAP_MAYMOVE);
        if (m == MAP_FAILED)
            return -1;
        x->text = m;
        n->map_len = n->cap = len;
        return 0;
    }
    /* Extend in place when the text is the arena's last allocation (the usual case). */
    chunk_t *c = p->chunks;
    size_t round = (need + 15) & ~(size_t)15;
    if (n->cap && c && x->text >= c->data && x->text < c->data + c->used) {
        size_t off = (size_t)(x->text - c->data);
        if (off + n->cap == c->used && off + round <= c->size) {
            c->used = off + round;
            n->cap = round;
            return 0;
        }
    }
    char *t;
    size_t cap;
    if (need <= TEXT_ARENA_MAX) {
        cap = n->cap ? 2 * need : round;     /* first piece exact: most texts come whole */
        if (cap > TEXT_ARENA_MAX)
            cap = TEXT_ARENA_MAX;
        cap = (cap + 15) & ~(size_t)15;
        if (!(t = arena_alloc(p, cap)))
            return -1;
    } else {
        cap = page_round(need + need / 4);
        t = mmap(NULL, cap, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (t == MAP_FAILED)
            return -1;
        n->map_len = cap;
        n->next_map = p->mapped;
        p->mapped = n;
    }
    memcpy(t, x->text, x->text_len + 1);
    x->text = t;
    n->cap = cap;
    return 0;
}

static void XMLCALL on_text(void *ud, const XML_Char *s, int len)
{
    xb_doc_parser_t *p = ud;
    if (p->limit_hit || !p->cur || over_size(p))
        return;
    pnode_t *n = (pnode_t *)p->cur;      /* every node is a pnode_t */
    xb_node_t *x = &n->pub;
    if (text_reserve(p, n, x->text_len + (size_t)len + 1) < 0) {
        fail(p, "no-memory", "%s", "out of memory");
        return;
    }
    memcpy(x->text + x->text_len, s, (size_t)len);
    x->text_len += (size_t)len;
    x->text[x->text_len] = '\0';
}

static void XMLCALL on_doctype(void *ud, const XML_Char *name, const XML_Char *sysid,
                               const XML_Char *pubid, int has_internal_subset)
{
    fail(ud, "malformed", "%s", "document type declarations are not accepted");
}

static int setup(xb_doc_parser_t *p)
{
    xb_doc_parser_t *prev = mm_owner;
    mm_owner = p;
    int ok = p->xp ? XML_ParserReset(p->xp, "UTF-8")
                   : (p->xp = XML_ParserCreate_MM("UTF-8", &mm_suite, NULL)) != NULL;
    mm_owner = prev;
    if (!ok)
        return -1;
    /* One random hash salt per parser: a reset would otherwise draw a new one every time. */
    XML_SetHashSalt(p->xp, p->salt);
    XML_SetUserData(p->xp, p);
    XML_SetElementHandler(p->xp, on_start, on_end);
    XML_SetCharacterDataHandler(p->xp, on_text);
    XML_SetStartDoctypeDeclHandler(p->xp, on_doctype);
    /* Replies must not wait for the next bytes; the size limit bounds reparsing instead. */
    if (XML_SetReparseDeferralEnabled)
        XML_SetReparseDeferralEnabled(p->xp, XML_FALSE);
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
    if (p->xp) {
        xb_doc_parser_t *prev = mm_owner;
        mm_owner = p;
        XML_ParserFree(p->xp);
        mm_owner = prev;
    }
    arena_reset(p);
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
        xb_doc_parser_t *prev = mm_owner;
        mm_owner = p;
        enum XML_Status st = XML_Parse(p->xp, s, n, XML_FALSE);
        mm_owner = prev;
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

size_t xb_doc_parser_memory(const xb_doc_parser_t *p)
{
    /* A mapping's pages count once written: its reserve beyond the text costs nothing. */
    size_t mapped = 0;
    for (const pnode_t *n = p->mapped; n; n = n->next_map)
        mapped += page_round(n->pub.text_len + 1);
    return sizeof *p + p->arena_bytes + mapped + p->expat_bytes;
}
