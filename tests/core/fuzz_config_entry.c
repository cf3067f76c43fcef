/* fuzz_config_entry: any bytes as a system file; where it loads, each component read alone
 * from its lines (as marie-am starts it) has the configuration the whole file gives it, and a
 * spec made of the input's own bytes never crashes the reader. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/config_priv.h"
#include "core/log.h"

/* The text as a NUL-terminated copy the reader may empty in place. */
static char *copy(const uint8_t *data, size_t size)
{
    char *t = malloc(size + 1);
    if (t) {
        memcpy(t, data, size);
        t[size] = 0;
    }
    return t;
}

static void each_entry_alone(const marie_system_t *all, const uint8_t *data, size_t size)
{
    uint64_t h = marie_text_hash(data, size);
    for (size_t i = 0; i < all->ncomponents && i < 8; i++) {
        const marie_component_cfg_t *a = &all->components[i];
        char spec[96], *t = copy(data, size);
        if (!t || marie_system_entry_spec(all, a->name, h, spec, sizeof spec) < 0) {
            free(t);
            continue;
        }
        marie_system_t *one = marie_system_load_entry_text("fuzz.yaml", t, size, NULL, a->name, spec);
        const marie_component_cfg_t *b = marie_system_component(one, a->name);
        /* a file the whole loader takes must load alone, to the same configuration */
        if (!b || strcmp(marie_component_hash(a), marie_component_hash(b)) != 0)
            abort();
        marie_system_destroy(one);
        free(t);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    marie_log_set_threshold(MARIE_LOG_OFF);
    marie_errors_t e = {0};
    marie_system_t *all = marie_system_load_text("fuzz.yaml", (const char *)data, size, NULL, &e);
    marie_errors_clear(&e);
    if (all)
        each_entry_alone(all, data, size);
    marie_system_destroy(all);
    /* lines from the input's first bytes over the rest, for any name */
    if (size > 4) {
        char spec[96], *t = copy(data + 4, size - 4);
        snprintf(spec, sizeof spec, "%016llx %d-%d %d-%d", (unsigned long long)marie_text_hash(data + 4, size - 4),
                 data[0], data[0] + data[1], data[2], data[2] + data[3]);
        marie_system_destroy(t ? marie_system_load_entry_text("fuzz.yaml", t, size - 4, NULL, "a", spec) : NULL);
        free(t);
    }
    return 0;
}
