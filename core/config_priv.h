/* config_priv: what the parts of the system file's loader share (config.c loads the file,
 * config_component.c reads one component, config_hash.c hashes it, config_check.c checks the
 * result); private to core/config*.c. */
#ifndef MARIE_CONFIG_PRIV_H
#define MARIE_CONFIG_PRIV_H

#include "core/config.h"

/* A duration `key` read as `value` seconds: within what the managers can count (a day at most;
 * heartbeat_timeout 0, or 0.15 s and more). -1 with "file:line:col: ..." at n. */
int marie_config_seconds_ok(const marie_node_t *n, const char *key, double value, marie_errors_t *errs);

/* Everything about a loaded file that reading it does not already refuse, so that a file that
 * passes never crash-loops its components: names (components, groups, hosts: printable words of
 * at most 63 bytes), hosts listed once and at least one, channels LCM can carry, bus URLs, args as
 * a list, every profile's `extends` chain (applied or not), dependency cycles. 0 or -1 with
 * "file:line:col: ..." in errs. */
int marie_config_check(const marie_system_t *sys, marie_errors_t *errs);

/* A sequence of scalars (or one scalar) as a string vector; NULL/0 when n is NULL. 0 or -1. */
int marie_config_read_strv(const marie_node_t *n, char ***out, size_t *count, marie_errors_t *errs);
void marie_config_free_strv(char **v, size_t n);

/* A `restart:` entry (a policy word or a mapping) over r; nothing when n is NULL. 0 or -1. */
int marie_config_read_restart(const marie_node_t *n, marie_restart_cfg_t *r, marie_errors_t *errs);

/* The component entry n into c (zeroed first, restart from defaults); hosts checked against sys.
 * 0 or -1 with "file:line:col: ..." in errs; c is filled as far as it could be read either way. */
int marie_config_read_component(const marie_node_t *n, const marie_system_t *sys,
                                const marie_restart_cfg_t *defaults, marie_component_cfg_t *c,
                                marie_errors_t *errs);

/* marie_system_load_text reading only the component `only` (NULL: all): the other entries,
 * at every level, are skipped and not checked, nor are dependencies on them (config_entry.c). */
marie_system_t *marie_system_load_only(const char *path, const char *text, size_t len, const char *profile,
                                       const char *only, marie_errors_t *errs);

/* marie_system_load_entry on text already read (emptied in place), named file in messages. */
marie_system_t *marie_system_load_entry_text(const char *file, char *text, size_t len, const char *profile,
                                             const char *name, const char *spec);

/* The tree of text in the plain block subset of YAML that core/config_plain.c reads without
 * libfyaml (a root mapping), the same tree libfyaml gives; NULL with errno ENOTSUP for any
 * other text (libfyaml reads it, or reports it), or ENOMEM. */
marie_node_t *marie_yaml_plain(const char *file, const char *text, size_t len);
/* marie_doc_parse through libfyaml whatever the text (the plain reader's reference in tests). */
marie_doc_t *marie_doc_parse_library(const char *name, const char *text, size_t len, marie_errors_t *errs);
/* The tree's own helpers (core/yaml.c): a node and everything under it (NULL: a no-op); a
 * child appended to a sequence or mapping (0, or -1 with errno), indexed in a long mapping. */
void marie_node_free(marie_node_t *n);
int marie_node_append(marie_node_t *parent, marie_node_t *child);

#endif
