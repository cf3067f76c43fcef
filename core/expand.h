/* expand: ${NAME} and ${NAME:-default} in parameter strings, from the environment. */
#ifndef MARIE_EXPAND_H
#define MARIE_EXPAND_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Expands every ${NAME} (NAME set and not empty, else an error) and ${NAME:-default} (default
 * when NAME is unset or empty) in `in`; a '$' not followed by '{' is kept as it is.
 * Returns a new string the caller frees, or NULL with errno set (EINVAL: an unset variable
 * or an unclosed "${", explained in why[why_len]; ENOMEM). */
char *marie_expand_env(const char *in, char *why, size_t why_len);

/* Launch arguments (marie up FILE -a name=value): every ${name} and ${name:-default} of `in`
 * whose name is one of args ("name=value") becomes the value; every other ${...} is kept as it
 * is, for the components' environment. used[i] (args' count, may be NULL) is set for each
 * argument met. A new string the caller frees, or NULL with errno (EINVAL: an argument not
 * name=value, explained in why; ENOMEM). */
char *marie_expand_args(const char *in, char *const *args, size_t nargs, int *used, char *why, size_t why_len);

#ifdef __cplusplus
}
#endif
#endif
