/* fuzz_config_plain: wherever the plain reader (core/config_plain.c) takes a text, libfyaml reads
 * it too and gives the same tree: kinds, keys, values and every line and column. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/config_priv.h"
#include "core/log.h"

static int same_str(const char *a, const char *b) { return (!a && !b) || (a && b && strcmp(a, b) == 0); }

/* 0 when the trees match, else 1 after printing where they part. */
static int differ(const marie_node_t *a, const marie_node_t *b)
{
    if (a->kind == b->kind && a->line == b->line && a->col == b->col && same_str(a->key, b->key) &&
        a->key_line == b->key_line && a->key_col == b->key_col && same_str(a->value, b->value) &&
        a->quoted == b->quoted && a->n == b->n) {
        for (size_t i = 0; i < a->n; i++)
            if (differ(a->items[i], b->items[i]))
                return 1;
        return 0;
    }
    fprintf(stderr, "plain %d:%d key %s@%d:%d '%s' n=%zu, libfyaml %d:%d key %s@%d:%d '%s' n=%zu\n", a->line, a->col,
            a->key ? a->key : "-", a->key_line, a->key_col, a->value ? a->value : "", a->n, b->line, b->col,
            b->key ? b->key : "-", b->key_line, b->key_col, b->value ? b->value : "", b->n);
    return 1;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    marie_log_set_threshold(MARIE_LOG_OFF);
    marie_node_t *plain = marie_yaml_plain("fuzz.yaml", (const char *)data, size);
    if (!plain)
        return 0;
    marie_errors_t e = {0};
    marie_doc_t *doc = marie_doc_parse_library("fuzz.yaml", (const char *)data, size, &e);
    if (!doc) {
        fprintf(stderr, "the plain reader took a text libfyaml refuses:\n");
        marie_errors_print(&e, stderr);
        abort();
    }
    if (differ(plain, marie_doc_root(doc)))
        abort();
    marie_node_free(plain);
    marie_doc_destroy(doc);
    marie_errors_clear(&e);
    return 0;
}
