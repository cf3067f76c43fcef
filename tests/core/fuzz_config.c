/* fuzz_config: any bytes given as a YAML document parse or fail cleanly, and typed reads of
 * every node never crash. */
#include <stdint.h>
#include <stdlib.h>

#include "core/config.h"
#include "core/log.h"

static void walk(const marie_node_t *n, marie_errors_t *e)
{
    int64_t i;
    double d;
    bool b;
    const char *s;
    marie_node_int(n, &i, e);
    marie_node_double(n, &d, e);
    marie_node_bool(n, &b, e);
    marie_node_str(n, &s, e);
    for (size_t k = 0; k < n->n; k++)
        walk(n->items[k], e);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    marie_log_set_threshold(MARIE_LOG_OFF);
    marie_errors_t e = {0};
    marie_doc_t *doc = marie_doc_parse("fuzz.yaml", (const char *)data, size, &e);
    if (doc) {
        walk(marie_doc_root(doc), &e);
        static const char *const keys[] = {"system", "components", NULL};
        marie_node_check_keys(marie_doc_root(doc), keys, "fuzz", &e);
        free(marie_node_canonical(marie_doc_root(doc)));
    }
    marie_doc_destroy(doc);
    marie_errors_clear(&e);
    return 0;
}
