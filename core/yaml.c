/* yaml: YAML text (libfyaml events) into a node tree with file:line:col on every node, typed reads, errors. */
#include "core/clear.h"
#include "core/config.h"
#include "core/config_priv.h"

#include <ctype.h>
#include <dlfcn.h>
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <libfyaml.h>

#include "core/buf.h"
#include "core/err.h"
#include "core/log.h"

/* ---- errors ---- */

void marie_errors_add(marie_errors_t *e, const char *file, int line, int col, const char *fmt, ...)
{
    if (!e)
        return;
    char msg[768], full[1024];
    MARIE_VFORMAT(msg, fmt);
    if (line > 0)
        snprintf(full, sizeof full, "%s:%d:%d: %s", file ? file : "<config>", line, col, msg);
    else
        snprintf(full, sizeof full, "%s: %s", file ? file : "<config>", msg);
    char **n = realloc(e->msgs, (e->n + 1) * sizeof *n);
    char *copy = strdup(full);
    if (!n || !copy) {
        free(copy);
        if (n)
            e->msgs = n;
        return;
    }
    e->msgs = n;
    e->msgs[e->n++] = copy;
}

void marie_errors_print(const marie_errors_t *e, FILE *out)
{
    for (size_t i = 0; e && i < e->n; i++)
        fprintf(out, "%s\n", e->msgs[i]);
}

void marie_errors_clear(marie_errors_t *e)
{
    if (!e)
        return;
    for (size_t i = 0; i < e->n; i++)
        free(e->msgs[i]);
    MARIE_CLEAR(e->msgs, free);
    e->n = 0;
}

void marie_node_error(marie_errors_t *e, const marie_node_t *n, const char *fmt, ...)
{
    char msg[768];
    MARIE_VFORMAT(msg, fmt);
    marie_errors_add(e, n->file, n->line, n->col, "%s", msg);
}

/* ---- YAML tree ---- */

struct marie_doc {
    char *file;
    marie_node_t *root;
};

#define MAX_DEPTH 64

void marie_node_free(marie_node_t *n)
{
    if (!n)
        return;
    for (size_t i = 0; i < n->n; i++)
        marie_node_free(n->items[i]);
    free(n->items);
    free(n->index);
    free(n->key);
    free(n->value);
    free(n);
}

/* Maps longer than this get a hash index: duplicate checks and lookups stay linear in the
 * file's size (a linear scan per key made a 10 MB file take minutes). */
#define INDEX_MIN 8

static size_t key_hash(const char *k)
{
    size_t h = 1469598103934665603ull;
    for (; *k; k++)
        h = (h ^ (unsigned char)*k) * 1099511628211ull;
    return h;
}

/* Position + 1 of `key` in the map's index slot chain, or the empty slot where it would go. */
static size_t index_slot(const marie_node_t *m, const char *key)
{
    size_t mask = m->index_cap - 1, i = key_hash(key) & mask;
    while (m->index[i] && strcmp(m->items[m->index[i] - 1]->key, key) != 0)
        i = (i + 1) & mask;
    return i;
}

/* A table at least twice the map's length, holding every item (keys are unique). */
static int index_grow(marie_node_t *m)
{
    size_t cap = m->index_cap ? m->index_cap : 16;
    while (cap < 2 * m->n)
        cap *= 2;
    size_t *index = calloc(cap, sizeof *index);
    if (!index)
        return marie_fail(ENOMEM);
    free(m->index);
    m->index = index;
    m->index_cap = cap;
    for (size_t i = 0; i < m->n; i++)
        m->index[index_slot(m, m->items[i]->key)] = i + 1;
    return 0;
}

static const marie_node_t *map_find(const marie_node_t *m, const char *key)
{
    if (m->index) {
        size_t pos = m->index[index_slot(m, key)];
        return pos ? m->items[pos - 1] : NULL;
    }
    for (size_t i = 0; i < m->n; i++)
        if (strcmp(m->items[i]->key, key) == 0)
            return m->items[i];
    return NULL;
}

int marie_node_append(marie_node_t *parent, marie_node_t *child)
{
    /* Capacity doubles: it is full exactly when n is 0 or a power of two. */
    size_t n = parent->n;
    if ((n & (n - 1)) == 0) {
        marie_node_t **items = realloc(parent->items, (n ? 2 * n : 1) * sizeof *items);
        if (!items)
            return marie_fail(ENOMEM);
        parent->items = items;
    }
    parent->items[parent->n++] = child;
    if (parent->kind != MARIE_NODE_MAP || parent->n < INDEX_MIN)
        return 0;
    if (2 * parent->n > parent->index_cap) {
        /* indexes every item, the new one included; without memory, lookups stay linear */
        if (index_grow(parent) < 0) {
            MARIE_CLEAR(parent->index, free);
            parent->index_cap = 0;
        }
        return 0;
    }
    parent->index[index_slot(parent, child->key)] = parent->n;
    return 0;
}

/* ---- libfyaml, opened at run time ----
 * A component reads its YAML at start-up only; linked for good, libfyaml's pages (about
 * 440 kB) would stay resident in every process for its whole life. It is opened when a
 * document is parsed and closed by marie_yaml_unload(), which components call once started. */
#define FY_SONAME "libfyaml.so.0"

#define FY_FUNCS(X)                                                                              \
    X(diag_cfg_default) X(diag_create) X(diag_destroy) X(event_start_mark) X(parser_create)    \
    X(parser_destroy) X(parser_event_free) X(parser_get_stream_error) X(parser_parse)          \
    X(parser_set_string) X(token_get_text) X(token_scalar_style)

static struct {
#define FY_FIELD(f) __typeof__(fy_##f) *f;
    FY_FUNCS(FY_FIELD)
#undef FY_FIELD
} fy;

static pthread_mutex_t fy_lock = PTHREAD_MUTEX_INITIALIZER;
static void *fy_lib;
static unsigned fy_users;       /* documents being parsed now: the library stays open */

/* Opens libfyaml if it is not open and holds it until fy_put(). 0, or -1 with the reason in errs. */
static int fy_get(const char *name, marie_errors_t *errs)
{
    pthread_mutex_lock(&fy_lock);
    if (!fy_lib) {
        /* Lazily bound: libfyaml calls its own 650 functions through its PLT, and binding them
         * all at open took a tenth of a component's start-up; a parse binds the few it calls. */
        void *lib = dlopen(FY_SONAME, RTLD_LAZY | RTLD_LOCAL);
        bool ok = lib != NULL;
#define FY_LOAD(f) ok = ok && (*(void **)&fy.f = dlsym(lib, "fy_" #f)) != NULL;
        FY_FUNCS(FY_LOAD)
#undef FY_LOAD
        if (!ok) {
            const char *why = dlerror();
            marie_errors_add(errs, name, 0, 0, "cannot load the YAML library: %s", why ? why : FY_SONAME);
            if (lib)
                dlclose(lib);
            pthread_mutex_unlock(&fy_lock);
            errno = ENOENT;
            return -1;
        }
        fy_lib = lib;
    }
    fy_users++;
    pthread_mutex_unlock(&fy_lock);
    return 0;
}

static void fy_put(void)
{
    pthread_mutex_lock(&fy_lock);
    fy_users--;
    pthread_mutex_unlock(&fy_lock);
}

void marie_yaml_unload(void)
{
    pthread_mutex_lock(&fy_lock);
    if (fy_lib && fy_users == 0) {
        dlclose(fy_lib);
        fy_lib = NULL;
        memset(&fy, 0, sizeof fy);
    }
    pthread_mutex_unlock(&fy_lock);
}

static int (*interrupt_check)(void);

void marie_config_set_interrupt(int (*check)(void)) { interrupt_check = check; }

typedef struct {
    struct fy_parser *fyp;
    const char *file;
    marie_errors_t *errs;
    size_t errs_before;
    char diag[1024];            /* libfyaml's first error message */
    size_t diag_len;
    unsigned events;            /* counts down to the next interrupt check */
} builder_t;

static void mark_of(struct fy_event *ev, int *line, int *col)
{
    const struct fy_mark *m = fy.event_start_mark(ev);
    *line = m ? m->line + 1 : 0;
    *col = m ? m->column + 1 : 0;
}

/* Builds the node starting with event `ev` (owned by the caller); NULL on error. */
static marie_node_t *build_node(builder_t *b, struct fy_event *ev, int depth)
{
    marie_node_t *n = calloc(1, sizeof *n);
    if (!n)
        return NULL;
    n->file = b->file;
    mark_of(ev, &n->line, &n->col);
    if (depth > MAX_DEPTH) {
        marie_node_error(b->errs, n, "nesting deeper than %d levels", MAX_DEPTH);
        goto err;
    }
    switch (ev->type) {
    case FYET_SCALAR: {
        size_t len;
        const char *text = fy.token_get_text(ev->scalar.value, &len);
        n->kind = MARIE_NODE_SCALAR;
        n->value = strndup(text ? text : "", text ? len : 0);
        enum fy_scalar_style st = fy.token_scalar_style(ev->scalar.value);
        n->quoted = st == FYSS_SINGLE_QUOTED || st == FYSS_DOUBLE_QUOTED;
        if (!n->value)
            goto err;
        return n;
    }
    case FYET_ALIAS:
        marie_node_error(b->errs, n, "YAML aliases are not supported in marie files");
        goto err;
    case FYET_SEQUENCE_START:
    case FYET_MAPPING_START: {
        int is_map = ev->type == FYET_MAPPING_START;
        enum fy_event_type end = is_map ? FYET_MAPPING_END : FYET_SEQUENCE_END;
        n->kind = is_map ? MARIE_NODE_MAP : MARIE_NODE_SEQ;
        for (;;) {
            struct fy_event *kev = fy.parser_parse(b->fyp);
            if (!kev)
                goto err;
            if (kev->type == end) {
                fy.parser_event_free(b->fyp, kev);
                return n;
            }
            char *key = NULL;
            int kline = 0, kcol = 0;
            struct fy_event *vev = kev;
            if (is_map) {
                mark_of(kev, &kline, &kcol);
                if (kev->type != FYET_SCALAR) {
                    marie_errors_add(b->errs, b->file, kline, kcol, "mapping keys must be plain scalars");
                    fy.parser_event_free(b->fyp, kev);
                    goto err;
                }
                size_t len;
                const char *text = fy.token_get_text(kev->scalar.value, &len);
                key = strndup(text ? text : "", text ? len : 0);
                fy.parser_event_free(b->fyp, kev);
                const marie_node_t *first = key ? map_find(n, key) : NULL;
                if (first) {
                    marie_errors_add(b->errs, b->file, kline, kcol, "duplicate key '%s' (first at line %d)",
                                     key, first->key_line);
                    free(key);
                    goto err;
                }
                if (interrupt_check && ++b->events % 4096 == 0 && interrupt_check()) {
                    marie_errors_add(b->errs, b->file, kline, kcol, "interrupted while parsing");
                    free(key);
                    errno = EINTR;
                    goto err;
                }
                vev = fy.parser_parse(b->fyp);
                if (!vev || !key) {
                    free(key);
                    if (vev)
                        fy.parser_event_free(b->fyp, vev);
                    goto err;
                }
            }
            marie_node_t *child = build_node(b, vev, depth + 1);
            fy.parser_event_free(b->fyp, vev);
            if (!child) {
                free(key);
                goto err;
            }
            child->key = key;
            child->key_line = kline;
            child->key_col = kcol;
            if (marie_node_append(n, child) < 0) {
                marie_node_free(child);
                goto err;
            }
        }
    }
    default:
        marie_node_error(b->errs, n, "unexpected YAML event %d", (int)ev->type);
        goto err;
    }
err:
    marie_node_free(n);
    return NULL;
}

/* libfyaml prints "file:line:col: error: text" and then the source line; keep the text. */
static void on_diag_output(struct fy_diag *diag, void *user, const char *buf, size_t len)
{
    builder_t *b = user;
    size_t room = sizeof b->diag - 1 - b->diag_len;
    if (len > room)
        len = room;
    memcpy(b->diag + b->diag_len, buf, len);
    b->diag_len += len;
    b->diag[b->diag_len] = 0;
}

static void report_diag(builder_t *b)
{
    if (b->errs && b->errs->n > b->errs_before)
        return;  /* already reported by the tree builder */
    int line = 1, col = 1;
    const char *text = "cannot parse";
    char *at = strstr(b->diag, ": error: ");
    if (at) {
        /* Walk back over ":line:col" just before ": error: ". */
        char *colon2 = NULL, *colon1 = NULL;
        for (char *q = at - 1; q > b->diag; q--) {
            if (*q == ':') {
                if (!colon2)
                    colon2 = q;
                else {
                    colon1 = q;
                    break;
                }
            }
        }
        if (colon1 && colon2) {
            line = atoi(colon1 + 1);
            col = atoi(colon2 + 1);
        }
        text = at + strlen(": error: ");
        char *nl = strchr(text, '\n');
        if (nl)
            *nl = 0;
    }
    marie_errors_add(b->errs, b->file, line, col, "YAML: %s", text);
}

/* libfyaml 0.7.12 can spin forever on a directive line holding a NUL byte, so text that
 * is not plain YAML for marie (NUL bytes, directives) is refused before it gets there. */
static int prescan(const char *name, const char *text, size_t len, marie_errors_t *errs)
{
    int line = 1, col = 1;
    for (size_t i = 0; i < len; i++, col++) {
        if (text[i] == 0) {
            marie_errors_add(errs, name, line, col, "NUL byte: this is not a text file");
            return -1;
        }
        if (text[i] == '%' && col == 1) {
            marie_errors_add(errs, name, line, col, "YAML directives are not supported in marie files");
            return -1;
        }
        if (text[i] == '\n') {
            line++;
            col = 0;
        }
    }
    return 0;
}

static marie_doc_t *doc_parse(const char *name, const char *text, size_t len, marie_errors_t *errs)
{
    marie_doc_t *doc = calloc(1, sizeof *doc);
    if (!doc)
        return NULL;
    doc->file = strdup(name);
    builder_t b = {.file = doc->file, .errs = errs, .errs_before = errs ? errs->n : 0};
    struct fy_diag_cfg dcfg;
    fy.diag_cfg_default(&dcfg);
    dcfg.fp = NULL;
    dcfg.output_fn = on_diag_output;
    dcfg.user = &b;
    dcfg.colorize = false;
    struct fy_diag *diag = fy.diag_create(&dcfg);
    struct fy_parse_cfg cfg = {.flags = FYPCF_QUIET, .diag = diag};
    struct fy_parser *fyp = diag ? fy.parser_create(&cfg) : NULL;
    b.fyp = fyp;
    if (!fyp || !doc->file || fy.parser_set_string(fyp, text, len) != 0)
        goto err;
    struct fy_event *ev;
    size_t ndocs = 0;
    while ((ev = fy.parser_parse(fyp)) != NULL) {
        enum fy_event_type t = ev->type;
        if (t == FYET_SEQUENCE_START || t == FYET_MAPPING_START || t == FYET_SCALAR || t == FYET_ALIAS) {
            marie_node_t *root = build_node(&b, ev, 0);
            fy.parser_event_free(fyp, ev);
            if (!root)
                goto fail;
            if (ndocs++ > 0) {
                marie_errors_add(errs, name, root->line, root->col, "only one YAML document is allowed");
                marie_node_free(root);
                goto err;
            }
            doc->root = root;
            continue;
        }
        fy.parser_event_free(fyp, ev);
    }
    if (fy.parser_get_stream_error(fyp))
        goto fail;
    if (!doc->root) {
        marie_errors_add(errs, name, 1, 1, "the file is empty");
        goto err;
    }
    fy.parser_destroy(fyp);
    fy.diag_destroy(diag);
    return doc;
fail:
    report_diag(&b);
err:
    if (fyp)
        fy.parser_destroy(fyp);
    if (diag)
        fy.diag_destroy(diag);
    marie_doc_destroy(doc);
    return NULL;
}

/* A lone plain word ("0", "1.5", "true", "emu:can0" is not one): what every parameter's default
 * and most --param values are. Letters, digits and _ . / + -, not opening a document marker
 * nor being a lone "-": YAML reads it as that one plain scalar, so it is built here without
 * the library (parsing each default through it was a sixth of a component's start). */
static bool plain_word(const char *text, size_t len)
{
    if (len == 0 || len > 256 || (len == 1 && text[0] == '-') || strncmp(text, "--", len < 2 ? len : 2) == 0 ||
        strncmp(text, "..", len < 2 ? len : 2) == 0)
        return false;
    for (size_t i = 0; i < len; i++)
        if (!isalnum((unsigned char)text[i]) && !strchr("_./+-", text[i]))
            return false;
    return true;
}

static marie_doc_t *word_doc(const char *name, const char *text, size_t len)
{
    marie_doc_t *doc = calloc(1, sizeof *doc);
    marie_node_t *n = calloc(1, sizeof *n);
    if (!doc || !n || !(doc->file = strdup(name)) || !(n->value = strndup(text, len))) {
        free(n);
        marie_doc_destroy(doc);
        return NULL;
    }
    *n = (marie_node_t){.kind = MARIE_NODE_SCALAR, .file = doc->file, .line = 1, .col = 1, .value = n->value};
    doc->root = n;
    return doc;
}

/* Plain block YAML (core/config_plain.c) without the library; NULL: the library reads it. */
static marie_doc_t *plain_doc(const char *name, const char *text, size_t len)
{
    marie_doc_t *doc = calloc(1, sizeof *doc);
    if (doc && (doc->file = strdup(name)) && (doc->root = marie_yaml_plain(doc->file, text, len)))
        return doc;
    marie_doc_destroy(doc);
    return NULL;
}

marie_doc_t *marie_doc_parse_library(const char *name, const char *text, size_t len, marie_errors_t *errs)
{
    if (prescan(name, text, len, errs) < 0 || fy_get(name, errs) < 0)
        return NULL;
    marie_doc_t *doc = doc_parse(name, text, len, errs);
    fy_put();
    return doc;
}

static marie_doc_t *doc_build(const char *name, const char *text, size_t len, marie_errors_t *errs)
{
    if (plain_word(text, len))
        return word_doc(name, text, len);
    marie_doc_t *doc = plain_doc(name, text, len);
    return doc ? doc : marie_doc_parse_library(name, text, len, errs);
}

#define MAX_FILE_SIZE (16 << 20)

marie_doc_t *marie_doc_load(const char *path, marie_errors_t *errs)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        marie_errors_add(errs, path, 0, 0, "cannot open: %s", strerror(errno));
        return NULL;
    }
    char *text = malloc(MAX_FILE_SIZE + 1);
    size_t len = text ? fread(text, 1, MAX_FILE_SIZE + 1, f) : 0;
    int failed = !text || ferror(f);
    fclose(f);
    marie_doc_t *doc = NULL;
    if (failed)
        marie_errors_add(errs, path, 0, 0, "cannot read: %s", strerror(errno ? errno : EIO));
    else if (len > MAX_FILE_SIZE) {
        /* Point at the first byte past the limit, so an editor can go there. */
        int line = 1, col = 1;
        for (size_t i = 0; i < MAX_FILE_SIZE; i++, col++)
            if (text[i] == '\n') {
                line++;
                col = 0;
            }
        marie_errors_add(errs, path, line, col, "the file is larger than %d MB (the limit falls here)",
                         MAX_FILE_SIZE >> 20);
    }
    else
        doc = doc_build(path, text, len, errs);
    free(text);
    return doc;
}

marie_doc_t *marie_doc_parse(const char *name, const char *text, size_t len, marie_errors_t *errs)
{
    return doc_build(name, text, len, errs);
}

void marie_doc_destroy(marie_doc_t *doc)
{
    if (!doc)
        return;
    marie_node_free(doc->root);
    free(doc->file);
    free(doc);
}

const marie_node_t *marie_doc_root(const marie_doc_t *doc) { return doc ? doc->root : NULL; }

const marie_node_t *marie_node_get(const marie_node_t *map, const char *key)
{
    if (!map || map->kind != MARIE_NODE_MAP)
        return NULL;
    return map_find(map, key);
}

static const char *node_label(const marie_node_t *n)
{
    return n->key ? n->key : "value";
}

static int expect_scalar(const marie_node_t *n, const char *what, marie_errors_t *errs)
{
    if (n->kind == MARIE_NODE_SCALAR)
        return 0;
    marie_node_error(errs, n, "%s: expected %s, got a %s", node_label(n), what,
               n->kind == MARIE_NODE_MAP ? "mapping" : "sequence");
    return -1;
}

int marie_node_int(const marie_node_t *n, int64_t *out, marie_errors_t *errs)
{
    if (expect_scalar(n, "an integer", errs) < 0)
        return -1;
    char *end;
    errno = 0;
    long long v = strtoll(n->value, &end, 0);
    if (n->quoted || !n->value[0] || *end || errno) {
        marie_node_error(errs, n, "%s: expected an integer, got '%s'", node_label(n), n->value);
        return -1;
    }
    *out = v;
    return 0;
}

int marie_node_double(const marie_node_t *n, double *out, marie_errors_t *errs)
{
    if (expect_scalar(n, "a number", errs) < 0)
        return -1;
    char *end;
    errno = 0;
    double v = strtod(n->value, &end);
    /* NaN and infinities (nan, inf, YAML's .nan and .inf) are no setting: a rate, timeout or
     * distance must be a finite number. */
    if (n->quoted || !n->value[0] || *end || errno || !isfinite(v)) {
        marie_node_error(errs, n, "%s: expected a %snumber, got '%s'", node_label(n),
                         !n->quoted && n->value[0] && (!*end || strcasestr(n->value, "nan") || strcasestr(n->value, "inf"))
                             ? "finite " : "", n->value);
        return -1;
    }
    *out = v;
    return 0;
}

int marie_node_bool(const marie_node_t *n, bool *out, marie_errors_t *errs)
{
    if (expect_scalar(n, "true or false", errs) < 0)
        return -1;
    static const char *const yes[] = {"true", "yes", "on"}, *const no[] = {"false", "no", "off"};
    for (int i = 0; !n->quoted && i < 3; i++) {
        if (strcasecmp(n->value, yes[i]) == 0) { *out = true; return 0; }
        if (strcasecmp(n->value, no[i]) == 0) { *out = false; return 0; }
    }
    marie_node_error(errs, n, "%s: expected true or false, got '%s'", node_label(n), n->value);
    return -1;
}

int marie_node_str(const marie_node_t *n, const char **out, marie_errors_t *errs)
{
    if (expect_scalar(n, "a string", errs) < 0)
        return -1;
    *out = n->value;
    return 0;
}

int marie_node_check_keys(const marie_node_t *map, const char *const *allowed, const char *what,
                          marie_errors_t *errs)
{
    if (map->kind != MARIE_NODE_MAP) {
        marie_node_error(errs, map, "%s: expected a mapping", what);
        return -1;
    }
    int rc = 0;
    for (size_t i = 0; i < map->n; i++) {
        const marie_node_t *c = map->items[i];
        int ok = 0;
        for (const char *const *a = allowed; *a && !ok; a++)
            ok = strcmp(*a, c->key) == 0;
        if (!ok) {
            char list[512] = "";
            for (const char *const *a = allowed; *a; a++)
                snprintf(list + strlen(list), sizeof list - strlen(list), "%s%s", a == allowed ? "" : ", ", *a);
            marie_errors_add(errs, c->file, c->key_line, c->key_col, "unknown key '%s' in %s (known: %s)",
                             c->key, what, list);
            rc = -1;
        }
    }
    return rc;
}

/* ---- canonical text (sorted keys) for hashing ---- */

static void sb_str(marie_buf_t *s, const char *text)
{
    marie_buf_printf(s, "%zu:", strlen(text));
    marie_buf_puts(s, text);
}

static int cmp_key(const void *a, const void *b)
{
    return strcmp((*(marie_node_t *const *)a)->key, (*(marie_node_t *const *)b)->key);
}

static void canonical(marie_buf_t *s, const marie_node_t *n)
{
    if (!n) {
        marie_buf_put(s, "~", 1);
        return;
    }
    if (n->kind == MARIE_NODE_SCALAR) {
        sb_str(s, n->value);
        return;
    }
    marie_node_t **items = malloc((n->n ? n->n : 1) * sizeof *items);
    if (!items) { s->failed = true; return; }
    if (n->n)                   /* an empty map or sequence has no items array */
        memcpy(items, n->items, n->n * sizeof *items);
    if (n->kind == MARIE_NODE_MAP)
        qsort(items, n->n, sizeof *items, cmp_key);
    marie_buf_put(s, n->kind == MARIE_NODE_MAP ? "{" : "[", 1);
    for (size_t i = 0; i < n->n; i++) {
        if (n->kind == MARIE_NODE_MAP) {
            sb_str(s, items[i]->key);
            marie_buf_put(s, "=", 1);
        }
        canonical(s, items[i]);
        marie_buf_put(s, ",", 1);
    }
    marie_buf_put(s, n->kind == MARIE_NODE_MAP ? "}" : "]", 1);
    free(items);
}

char *marie_node_canonical(const marie_node_t *n)
{
    marie_buf_t s;
    marie_buf_init(&s, 0);
    canonical(&s, n);
    if (s.failed) {
        marie_buf_free(&s);
        return NULL;
    }
    return s.data ? s.data : strdup("");
}
