/* file: read a whole file into memory, with a size limit. */
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

#ifdef __cplusplus
}
#endif
#endif
