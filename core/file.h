/* file: read a whole file into memory, with a size limit; the state directory. */
#ifndef MARIE_FILE_H
#define MARIE_FILE_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Reads the file at path. Returns a buffer of *len bytes plus a terminating NUL (so text can be
 * used as a string), which the caller frees; NULL with errno on failure (EFBIG when the file
 * is larger than max bytes, ENOMEM, or open/read's errno). */
void *marie_file_read(const char *path, size_t max, size_t *len);

/* Where marie keeps state that must survive a restart (SharedMap and Switch logs, the managers'
 * order marks): the first of $MARIE_STATE_DIR, systemd's $STATE_DIRECTORY, /var/lib/marie as
 * root, $XDG_STATE_HOME/marie, ~/.local/state/marie; created (mode 0700) if missing. Never the
 * working directory. Returns a path the caller frees, or NULL with errno (ENOENT: none of them
 * can be had). */
char *marie_state_dir(void);

#ifdef __cplusplus
}
#endif
#endif
