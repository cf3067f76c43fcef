/* spec: a component's self-description (PROG --describe) and the check of a system file entry against it. */
#ifndef MARIE_SPEC_H
#define MARIE_SPEC_H

#include <stdbool.h>
#include <stdio.h>

#include "core/component.h"
#include "core/config.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Written into every description; a program whose file does not contain it is not built on
 * libmarie and is never run with --describe. */
#define MARIE_SPEC_MARKER "marie-component-describe/1"

/* Print def's ports and parameters as one JSON object:
 *   {"describe": MARKER, "kind": K, "ports": [{"name", "dir", "mech", "type", "channel"}],
 *    "params": [{"name", "type": int|double|bool|string|node, "default", "help"}]}
 * A null channel must be bound by the configuration; a null default makes the parameter required. */
void marie_spec_describe(const marie_component_def_t *def, FILE *out);

/* s as a JSON string ("null" for NULL). */
void marie_spec_json_str(FILE *f, const char *s);

/* What a component was configured with, once created (for a runtime in another language that
 * resolves its configuration with libmarie, python/marie): one JSON object
 *   {"name", "kind", "host", "group", "url", "clock": "wall"|"sim", "key_file", "system", "profile",
 *    "heartbeat_timeout_s", "spin_us", "hash", "types": [dirs], "params": {NAME: value},
 *    "ports": {NAME: {"channel", "url", "shm"}}}
 * A node parameter's value is its canonical YAML text. */
void marie_spec_resolved(const marie_component_t *c, FILE *out);

/* Is this parsed document a description? */
bool marie_spec_valid(const marie_node_t *spec);

/* Check a component's entry (params, ports, --param/--port in its args) against its program's
 * description: unknown parameters and ports, wrong types, non-finite numbers, missing required
 * parameters, unbound ports. 0, or -1 with file:line:col messages added to errs. */
int marie_spec_check(const marie_node_t *spec, const marie_component_cfg_t *c, marie_errors_t *errs);

#ifdef __cplusplus
}
#endif
#endif
