/* config_entry: one component's entry of a system file, for the process that runs it. marie-am
 * has read and checked the whole file; the component it starts needs its own entry and the
 * file's settings, not the other entries (parsing them was most of a start: docs/managers.md,
 * "What one start costs"). The manager gives it the lines of the file's `components:` mapping,
 * the lines of its entry and a hash of the text; the component blanks the other entries' lines
 * (so every message keeps its line and column) and reads what is left. */
#include "core/clear.h"
#include "core/config_priv.h"
#include "core/file.h"

#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define ENTRY_MAX_BYTES (16 << 20)      /* as load_system in component.c reads a file */

/* FNV-1a's step taken over 8 bytes at a time, with a shift so that the high bits reach the low
 * ones: a component hashes the whole file's text at each start, and a byte at a time (with the
 * blanking below) was 15 % of its start's instructions (docs/managers.md, "What one start
 * costs"). It tells a changed text from the manager's, nothing more. */
uint64_t marie_text_hash(const void *text, size_t len)
{
    const unsigned char *p = text;
    uint64_t h = 0xcbf29ce484222325ull ^ len;
    size_t i = 0;
    for (; i + 8 <= len; i += 8) {
        uint64_t w;
        memcpy(&w, p + i, 8);
        h = (h ^ w) * 0x100000001b3ull;
        h ^= h >> 29;
    }
    for (; i < len; i++)
        h = (h ^ p[i]) * 0x100000001b3ull;
    return h;
}

/* The root's key after `components`: where the mapping's last entry ends (INT_MAX: the end). */
static int components_end(const marie_node_t *root, const marie_node_t *comps)
{
    for (size_t i = 0; i + 1 < root->n; i++)
        if (root->items[i] == comps)
            return root->items[i + 1]->key_line - 1;
    return INT_MAX;
}

int marie_system_entry_spec(const marie_system_t *sys, const char *name, uint64_t text_hash, char *out, size_t size)
{
    const marie_node_t *root = sys ? marie_doc_root(sys->doc) : NULL;
    const marie_node_t *comps = marie_node_get(root, "components");
    if (!comps || comps->kind != MARIE_NODE_MAP || !comps->n || !name)
        return -1;
    /* one entry after another, each starting on a line of its own below `components:` */
    int prev = comps->key_line, keep_from = 0, keep_to = 0, end = components_end(root, comps);
    for (size_t i = 0; i < comps->n; i++) {
        int line = comps->items[i]->key_line;
        if (line <= prev || line > end)
            return -1;
        prev = line;
        /* its entry; the first where it has none but a profile's (so that `components:` stays a
         * mapping: the loader skips an entry of another name) */
        if (strcmp(comps->items[i]->key, name) == 0 || i == 0) {
            keep_from = line;
            keep_to = i + 1 < comps->n ? comps->items[i + 1]->key_line - 1 : end;
        }
    }
    int n = snprintf(out, size, "%016" PRIx64 " %d-%d %d-%d", text_hash, comps->items[0]->key_line, end, keep_from,
                     keep_to);
    return n > 0 && (size_t)n < size ? 0 : -1;
}

/* text with the lines from..to emptied, except keep_from..keep_to (1-based, inclusive); its
 * new length. A line at a time (memchr), not a byte at a time. */
static size_t blank_lines(char *text, size_t len, int from, int to, int keep_from, int keep_to)
{
    char *w = text, *r = text, *end = text + len;
    for (int line = 1; r < end; line++) {
        char *nl = memchr(r, '\n', (size_t)(end - r));
        size_t n = nl ? (size_t)(nl - r) : (size_t)(end - r);
        bool gone = line >= from && line <= to && !(line >= keep_from && line <= keep_to);
        if (!gone) {
            memmove(w, r, n);
            w += n;
        }
        if (nl)
            *w++ = '\n';
        r += n + (nl != NULL);
    }
    return (size_t)(w - text);
}

marie_system_t *marie_system_load_entry_text(const char *file, char *text, size_t len, const char *profile,
                                             const char *name, const char *spec)
{
    uint64_t hash;
    int from, to, keep_from, keep_to;
    if (!spec || !name || sscanf(spec, "%" SCNx64 " %d-%d %d-%d", &hash, &from, &to, &keep_from, &keep_to) != 5 ||
        marie_text_hash(text, len) != hash)
        return NULL;
    marie_errors_t errs = {0};
    len = blank_lines(text, len, from, to, keep_from, keep_to);
    marie_system_t *sys = marie_system_load_only(file, text, len, profile, name, &errs);
    marie_errors_clear(&errs);
    if (sys && !marie_system_component(sys, name))
        MARIE_CLEAR(sys, marie_system_destroy);
    return sys;
}

marie_system_t *marie_system_load_entry(const char *path, const char *origin, const char *profile, const char *name,
                                        const char *spec)
{
    size_t len;
    char *text = spec && name ? marie_file_read(path, ENTRY_MAX_BYTES, &len) : NULL;
    marie_system_t *sys = text ? marie_system_load_entry_text(origin ? origin : path, text, len, profile, name, spec)
                               : NULL;
    free(text);
    return sys;
}
