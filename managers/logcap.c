/* logcap: line splitting, rate limiting and rotation of captured output. */
#include "managers/logcap.h"

#include <errno.h>
#include <limits.h>
#include <stdbool.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/err.h"

static void emit(marie_linebuf_t *lb, marie_line_cb_t cb, void *user)
{
    size_t n = lb->len;
    if (n > 0 && lb->buf[n - 1] == '\r')
        n--;
    cb(lb->buf, n, user);
    lb->len = 0;
}

void marie_linebuf_feed(marie_linebuf_t *lb, const char *data, size_t len, marie_line_cb_t cb, void *user)
{
    while (len > 0) {
        const char *nl = memchr(data, '\n', len);
        size_t take = nl ? (size_t)(nl - data) : len;
        size_t room = sizeof lb->buf - lb->len;
        if (take >= room) {
            /* overlong line: emit what fits, keep going with the rest */
            memcpy(lb->buf + lb->len, data, room);
            lb->len += room;
            emit(lb, cb, user);
            data += room;
            len -= room;
            continue;
        }
        memcpy(lb->buf + lb->len, data, take);
        lb->len += take;
        data += take;
        len -= take;
        if (nl) {
            emit(lb, cb, user);
            data++;
            len--;
        }
    }
}

void marie_linebuf_flush(marie_linebuf_t *lb, marie_line_cb_t cb, void *user)
{
    if (lb->len > 0)
        emit(lb, cb, user);
}

void marie_ratelimit_init(marie_ratelimit_t *rl, double rate, double burst)
{
    rl->rate = rate;
    rl->burst = burst < 1 ? 1 : burst;
    rl->tokens = rl->burst;
    rl->last_us = 0;
}

int marie_ratelimit_take(marie_ratelimit_t *rl, int64_t now_us)
{
    if (rl->rate <= 0)
        return 1;
    if (rl->last_us != 0 && now_us > rl->last_us) {
        rl->tokens += (double)(now_us - rl->last_us) * 1e-6 * rl->rate;
        if (rl->tokens > rl->burst)
            rl->tokens = rl->burst;
    }
    rl->last_us = now_us;
    if (rl->tokens >= 1.0) {
        rl->tokens -= 1.0;
        return 1;
    }
    return 0;
}

struct marie_logfile {
    char *path;
    int fd;
    int64_t size, max_bytes;
    int keep;
};

static int logfile_reopen(marie_logfile_t *lf)
{
    if (lf->fd >= 0)
        close(lf->fd);
    lf->fd = open(lf->path, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0640);
    if (lf->fd < 0)
        return -1;
    struct stat st;
    lf->size = fstat(lf->fd, &st) == 0 ? st.st_size : 0;
    return 0;
}

/* Whether the folder of path would take a new file (search and write). */
static bool folder_takes(const char *path)
{
    char dir[PATH_MAX];
    const char *slash = strrchr(path, '/');
    if (!slash)
        return access(".", W_OK | X_OK) == 0;
    snprintf(dir, sizeof dir, "%.*s", (int)(slash - path) + (slash == path), path);
    return access(dir, W_OK | X_OK) == 0;
}

/* A file that exists is opened at once (its size counts toward rotation); a missing one is
 * created at its first line. A bring-up of 45 on a new state directory created 45 files before
 * its first component started (about 30 % of marie-am's CPU in the bring-up, perf record), and
 * a component that never prints needs none. Its folder is checked now, so that a state
 * directory that cannot take it is said at once, as before. */
marie_logfile_t *marie_logfile_open(const char *path, int64_t max_bytes, int keep)
{
    marie_logfile_t *lf = calloc(1, sizeof *lf);
    if (!lf)
        return NULL;
    lf->fd = -1;
    lf->path = strdup(path);
    lf->max_bytes = max_bytes;
    lf->keep = keep < 1 ? 1 : keep;
    if (!lf->path)
        goto err;
    lf->fd = open(path, O_WRONLY | O_APPEND | O_CLOEXEC);
    struct stat st;
    if (lf->fd >= 0)
        lf->size = fstat(lf->fd, &st) == 0 ? st.st_size : 0;
    else if (errno != ENOENT || !folder_takes(path))
        goto err;
    return lf;
err:
    MARIE_KEEP_ERRNO(marie_logfile_close(lf));
    return NULL;
}

static void logfile_rotate(marie_logfile_t *lf)
{
    size_t n = strlen(lf->path) + 16;
    char from[n], to[n];
    for (int i = lf->keep - 1; i >= 1; i--) {
        snprintf(from, n, "%s.%d", lf->path, i);
        snprintf(to, n, "%s.%d", lf->path, i + 1);
        rename(from, to);
    }
    snprintf(to, n, "%s.1", lf->path);
    rename(lf->path, to);
    logfile_reopen(lf);
}

int marie_logfile_write(marie_logfile_t *lf, const char *data, size_t len)
{
    if (lf->fd < 0 && logfile_reopen(lf) < 0)       /* its first line (or gone since) */
        return -1;
    if (lf->max_bytes > 0 && lf->size + (int64_t)len > lf->max_bytes && lf->size > 0)
        logfile_rotate(lf);
    if (lf->fd < 0)
        return marie_fail(EBADF);
    ssize_t w = write(lf->fd, data, len);
    if (w < 0)
        return -1;
    lf->size += w;
    return 0;
}

void marie_logfile_close(marie_logfile_t *lf)
{
    if (!lf)
        return;
    if (lf->fd >= 0)
        close(lf->fd);
    free(lf->path);
    free(lf);
}

/* Collect lines of one file into a ring of the last n. */
static int tail_file(const char *path, int n, char **ring, int *count, int *head)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return -1;
    char line[MARIE_LINE_MAX + 128];
    while (fgets(line, sizeof line, f)) {
        size_t l = strlen(line);
        if (l && line[l - 1] == '\n')
            line[--l] = 0;
        int slot = (*head + *count) % n;
        if (*count == n) {
            slot = *head;
            *head = (*head + 1) % n;
        } else {
            (*count)++;
        }
        free(ring[slot]);
        ring[slot] = strdup(line);
    }
    fclose(f);
    return 0;
}

int marie_logfile_tail(const char *path, int n, marie_line_cb_t cb, void *user)
{
    if (n <= 0)
        return 0;
    char **ring = calloc((size_t)n, sizeof *ring);
    if (!ring)
        return marie_fail(ENOMEM);
    int count = 0, head = 0;
    size_t pl = strlen(path) + 4;
    char prev[pl];
    snprintf(prev, pl, "%s.1", path);
    tail_file(prev, n, ring, &count, &head);
    int rc = tail_file(path, n, ring, &count, &head);
    int err = rc < 0 ? errno : 0;
    if (err == ENOENT && count > 0)
        rc = err = 0;
    for (int i = 0; i < count; i++) {
        const char *l = ring[(head + i) % n];
        if (l)
            cb(l, strlen(l), user);
    }
    for (int i = 0; i < n; i++)
        free(ring[i]);
    free(ring);
    return rc < 0 ? marie_fail(err) : 0;
}
