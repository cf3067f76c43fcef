/* progcheck: components' programs exist and their entries match what the programs declare. */
#ifndef MARIE_PROGCHECK_H
#define MARIE_PROGCHECK_H

#include <stdbool.h>

#include "core/config.h"
#include "proto/am_proto.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The program an `exec` runs: a bare name is looked up in self_dir (the manager's own
 * directory), then PATH (NULL when not found); a relative path with a '/' starts from the folder
 * of sys_file, the system file that names it, wherever the reader runs; an absolute one is used
 * as given. Caller frees. */
char *marie_am_resolve_exec(const char *self_dir, const char *sys_file, const char *name);

typedef struct marie_progcheck marie_progcheck_t;

/* self_dir as above; cache_dir keeps descriptions across runs (created if absent; NULL: this
 * process only). A description is keyed by the binary's path, device, inode, size and mtime
 * and the leading non-option args (marie-ca mailbox), so a rebuilt program is described again. */
marie_progcheck_t *marie_progcheck_create(const char *self_dir, const char *cache_dir);
void marie_progcheck_destroy(marie_progcheck_t *p);

/* From now on p runs no program: a check that would run one with --describe fails, and
 * marie_progcheck_must_run() says so (the caller checks again where a program may run). */
void marie_progcheck_cached_only(marie_progcheck_t *p);
bool marie_progcheck_must_run(const marie_progcheck_t *p);
/* Check every non-shell component (only those that run on only_host, when not NULL; a
 * component without host and without hosts runs on fallback_host): its exec exists and is
 * executable, and, when the program is built on libmarie, its params, ports and --param/--port
 * args match the program's --describe. 0, or -1 with file:line:col messages in errs. */
int marie_progcheck_system(marie_progcheck_t *p, const marie_system_t *sys, const char *only_host,
                           const char *fallback_host, marie_errors_t *errs);

/* How many programs were run with --describe so far (the others came from a cache). */

/* $XDG_CACHE_HOME/marie/describe, else $HOME/.cache/marie/describe (created); NULL if neither. */
char *marie_progcheck_default_cache(void);

#ifdef __cplusplus
}
#endif
#endif
