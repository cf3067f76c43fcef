/* buf: the growable text buffer (the viewer's JSON, the XML bridge's documents). Always
 * NUL-terminated after its len bytes; appends past max (or out of memory) fail, leave the
 * text as it was, and set `failed`, so a writer may append a whole document and check once.
 * Also the one way an array grows (marie_grow). */
#ifndef MARIE_BUF_H
#define MARIE_BUF_H

#include <stdbool.h>
#include <stddef.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    char *data;                 /* NULL until the first append */
    size_t len, cap, max;
    bool failed;                /* an append failed: the text is incomplete */
} marie_buf_t;

/* max: the most bytes of text it may hold; 0: no limit of its own (1 GiB). */
void marie_buf_init(marie_buf_t *b, size_t max);
void marie_buf_free(marie_buf_t *b);
/* Empty again (and not failed); keeps its memory. */
void marie_buf_reset(marie_buf_t *b);
/* Room for `extra` more bytes (and the terminator): 0, or -1 and `failed`. */
int marie_buf_reserve(marie_buf_t *b, size_t extra);
/* Appends: 0, or -1 and `failed` (nothing of this append is kept). */
int marie_buf_put(marie_buf_t *b, const void *data, size_t len);
int marie_buf_puts(marie_buf_t *b, const char *s);
int marie_buf_printf(marie_buf_t *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* s as a JSON string, quotes included (NULL as ""): '"' and '\\' escaped, control characters
 * as \u00XX, well-formed UTF-8 kept, any other byte as U+FFFD, so the text is always valid JSON
 * whatever a name or a log line holds. 0, or -1 and `failed`. */
int marie_buf_json_str(marie_buf_t *b, const char *s);
/* The same, written to f. */
void marie_json_fputs(FILE *f, const char *s);

/* Room for `need` elements of `elem` bytes in the array *p, whose room is *cap elements: the
 * room doubles (from 16) until need fits; the elements are kept, the new room is not zeroed.
 * 0, or -1 with errno ENOMEM and *p, *cap as they were. p is the address of the array's
 * pointer (T **): MARIE_GROW(arr, cap, need) passes it, and the element's size, for you. */
int marie_grow(void **p, size_t *cap, size_t need, size_t elem);
#define MARIE_GROW(arr, cap, need) marie_grow((void **)&(arr), &(cap), (need), sizeof *(arr))

#ifdef __cplusplus
}
#endif
#endif
