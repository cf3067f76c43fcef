/* logcap: captured component output: a pure line splitter, a line rate limit and a
 * size-rotated log file. */
#ifndef MARIE_LOGCAP_H
#define MARIE_LOGCAP_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define MARIE_LINE_MAX 1024     /* longer lines are cut into pieces of this size */

typedef void (*marie_line_cb_t)(const char *line, size_t len, void *user);

/* Splits a byte stream into lines ('\n', with a trailing '\r' removed). */
typedef struct {
    char buf[MARIE_LINE_MAX];
    size_t len;
} marie_linebuf_t;

void marie_linebuf_feed(marie_linebuf_t *lb, const char *data, size_t len, marie_line_cb_t cb, void *user);
void marie_linebuf_flush(marie_linebuf_t *lb, marie_line_cb_t cb, void *user);   /* a partial last line */

/* Token bucket: `rate` lines per second, bursts up to `burst`. */
typedef struct {
    double rate, burst, tokens;
    int64_t last_us;
} marie_ratelimit_t;

void marie_ratelimit_init(marie_ratelimit_t *rl, double rate, double burst);
int marie_ratelimit_take(marie_ratelimit_t *rl, int64_t now_us);   /* 1: pass, 0: drop */

/* Append-only log file, renamed to path.1 .. path.KEEP when it passes max_bytes. A missing file
 * is created at its first line (open checks that its folder would take it: NULL with errno if
 * not). */
typedef struct marie_logfile marie_logfile_t;
marie_logfile_t *marie_logfile_open(const char *path, int64_t max_bytes, int keep);
int marie_logfile_write(marie_logfile_t *lf, const char *data, size_t len);   /* 0, or -1 with errno */
void marie_logfile_close(marie_logfile_t *lf);     /* NULL is a no-op */

/* The last n lines of a file (and of its .1 predecessor when the file is short), each
 * passed to cb oldest first. 0, or -1 with errno. */
int marie_logfile_tail(const char *path, int n, marie_line_cb_t cb, void *user);

#ifdef __cplusplus
}
#endif
#endif
