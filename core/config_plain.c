/* config_plain: the plain block YAML most marie files are written in, read without libfyaml.
 * A component reads its own entry at every start, and opening libfyaml for it (mapping,
 * relocating and closing a 0.5 MB library) was a fifth of the start's CPU. What is read here
 * is a strict subset: block mappings of plain keys, each with a plain word, a one-line flow
 * sequence of plain words, or a deeper block mapping, indented with spaces, with comments and
 * blank lines. Anything else (quotes, block sequences, anchors, tags, multi-line scalars, a key
 * given twice, an empty value, tabs, ...) is left to libfyaml, which reads it or reports it as
 * before: the tree built here is the one libfyaml gives, positions included (the differential
 * fuzz target fuzz_config_plain checks it). */
#include <ctype.h>
#include <errno.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "core/clear.h"
#include "core/config_priv.h"

#define PLAIN_MAX_BYTES (1 << 20)       /* longer files go to libfyaml (it checks for signals) */
#define PLAIN_MAX_DEPTH 32
#define WORD_MAX 256

typedef struct {
    const char *file, *p, *end;
    int line;                   /* of p, 1-based */
    const char *line_start;
} cursor_t;

static bool word_char(char c) { return c && (isalnum((unsigned char)c) || strchr("_./+-", c)); }

/* A plain word at p (what marie's plain_word takes: YAML reads it as that one plain scalar);
 * its length, 0 if there is none. */
static size_t word_at(const char *p, const char *end)
{
    size_t n = 0;
    while (p + n < end && word_char(p[n]))
        n++;
    if (n == 0 || n > WORD_MAX || (n == 1 && p[0] == '-') || (n >= 2 && p[0] == '-' && p[1] == '-') ||
        (n >= 2 && p[0] == '.' && p[1] == '.'))
        return 0;
    return n;
}

/* Spaces, then the end of the line or a comment (a '#' after at least one space, or alone on
 * its line: `at_start`). Moves c->p past the line's end. */
static bool line_rest(cursor_t *c, bool at_start)
{
    const char *s = c->p;
    while (c->p < c->end && *c->p == ' ')
        c->p++;
    /* a comment of printable ASCII and tabs: other bytes (a CR, a BOM, what YAML 1.1 took
     * for line breaks) are left to libfyaml */
    if (c->p < c->end && *c->p == '#' && (at_start || c->p > s))
        while (c->p < c->end && (*c->p == '\t' || (*c->p >= 0x20 && *c->p < 0x7f)))
            c->p++;
    if (c->p < c->end && *c->p != '\n')
        return false;
    if (c->p < c->end)
        c->p++;
    c->line++;
    c->line_start = c->p;
    return true;
}

static marie_node_t *node_new(const cursor_t *c, marie_node_kind_t kind, const char *at)
{
    marie_node_t *n = calloc(1, sizeof *n);
    if (n)
        *n = (marie_node_t){.kind = kind, .file = c->file, .line = c->line, .col = (int)(at - c->line_start) + 1};
    return n;
}

static marie_node_t *scalar_new(const cursor_t *c, const char *at, size_t len)
{
    marie_node_t *n = node_new(c, MARIE_NODE_SCALAR, at);
    if (n && !(n->value = strndup(at, len)))
        MARIE_CLEAR(n, marie_node_free);
    return n;
}

/* `[word, word, ...]` on one line, at c->p. */
static marie_node_t *flow_seq(cursor_t *c)
{
    marie_node_t *seq = node_new(c, MARIE_NODE_SEQ, c->p);
    c->p++;
    for (bool first = true; seq;) {
        while (c->p < c->end && *c->p == ' ')
            c->p++;
        if (c->p < c->end && *c->p == ']' && first) {
            c->p++;
            return seq;
        }
        size_t n = word_at(c->p, c->end);
        marie_node_t *item = n ? scalar_new(c, c->p, n) : NULL;
        if (!item || marie_node_append(seq, item) < 0) {
            marie_node_free(item);
            break;
        }
        c->p += n;
        while (c->p < c->end && *c->p == ' ')
            c->p++;
        if (c->p < c->end && *c->p == ']') {
            c->p++;
            return seq;
        }
        if (c->p >= c->end || *c->p != ',')
            break;
        c->p++;
        first = false;
    }
    marie_node_free(seq);
    return NULL;
}

typedef struct {
    marie_node_t *map;
    int indent;
} level_t;

/* One `key: ...` line at c->p (past its indent) into the innermost map. *pending: the key node
 * waiting for a deeper block, when the line ends after the colon. 0, or -1: not plain. */
static int key_line(cursor_t *c, level_t *top, marie_node_t **pending)
{
    const char *k = c->p;
    size_t kn = word_at(k, c->end);
    if (kn == 0 || !isalnum((unsigned char)k[0]) || k + kn >= c->end || k[kn] != ':')
        return -1;
    c->p = k + kn + 1;
    if (c->p < c->end && *c->p != ' ' && *c->p != '\n')
        return -1;              /* "a:b" is a scalar, not a key */
    while (c->p < c->end && *c->p == ' ')
        c->p++;
    marie_node_t *v = NULL;
    bool nested = c->p >= c->end || *c->p == '\n' || *c->p == '#';
    if (nested)
        v = node_new(c, MARIE_NODE_MAP, c->p);          /* its position: its first key's */
    else if (*c->p == '[')
        v = flow_seq(c);
    else {
        size_t n = word_at(c->p, c->end);
        v = n ? scalar_new(c, c->p, n) : NULL;
        c->p += n;
    }
    if (!v || !(v->key = strndup(k, kn)) || marie_node_get(top->map, v->key) || marie_node_append(top->map, v) < 0) {
        marie_node_free(v);
        return -1;
    }
    v->key_line = c->line;
    v->key_col = (int)(k - c->line_start) + 1;
    *pending = nested ? v : NULL;
    return line_rest(c, nested) ? 0 : -1;
}

/* The line's indent, or -1 when it holds nothing (blank, a comment): then skipped. */
static int indent_of(cursor_t *c, bool *bad)
{
    const char *s = c->p;
    while (c->p < c->end && *c->p == ' ')
        c->p++;
    if (c->p >= c->end || *c->p == '\n' || *c->p == '#') {
        c->p = s;
        *bad = !line_rest(c, true);
        return -1;
    }
    return (int)(c->p - s);
}

/* Opens the pending key's block at this line, or closes blocks down to its indent. */
static level_t *place(level_t *lv, level_t *top, marie_node_t **pending, int indent, const cursor_t *c)
{
    if (*pending) {
        if (indent <= top->indent || top - lv + 1 >= PLAIN_MAX_DEPTH)
            return NULL;        /* an empty value, or too deep */
        (*pending)->line = c->line;
        (*pending)->col = indent + 1;
        *++top = (level_t){*pending, indent};
        *pending = NULL;
        return top;
    }
    while (top > lv && indent < top->indent)
        top--;
    return indent == top->indent ? top : NULL;
}

marie_node_t *marie_yaml_plain(const char *file, const char *text, size_t len)
{
    if (len > PLAIN_MAX_BYTES || memchr(text, 0, len)) {
        errno = ENOTSUP;
        return NULL;
    }
    cursor_t c = {.file = file, .p = text, .end = text + len, .line = 1, .line_start = text};
    level_t lv[PLAIN_MAX_DEPTH], *top = NULL;
    marie_node_t *pending = NULL, *root = NULL;
    while (c.p < c.end) {
        bool bad = false;
        int indent = indent_of(&c, &bad);
        if (bad)
            goto not_plain;
        if (indent < 0)
            continue;
        if (!root) {
            if (indent != 0 || !(root = node_new(&c, MARIE_NODE_MAP, c.p)))
                goto not_plain;
            lv[0] = (level_t){root, 0};
            top = lv;
        } else if (!(top = place(lv, top, &pending, indent, &c)))
            goto not_plain;
        if (key_line(&c, top, &pending) < 0)
            goto not_plain;
    }
    if (root && !pending)
        return root;
not_plain:
    marie_node_free(root);
    errno = ENOTSUP;
    return NULL;
}
