/* file: whole-file reads (bounded, so a huge or endless file such as a device or a FIFO cannot
 * exhaust memory) and where marie keeps state. */
#include "core/file.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/err.h"

void *marie_file_read(const char *path, size_t max, size_t *len)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return NULL;
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap + 1);
    if (!buf)
        goto err_close;
    for (;;) {
        if (n == cap) {
            if (cap >= max) {
                errno = EFBIG;
                goto err_free;
            }
            size_t ncap = cap * 2 > max ? max : cap * 2;
            char *g = realloc(buf, ncap + 1);
            if (!g)
                goto err_free;
            buf = g;
            cap = ncap;
        }
        ssize_t got = read(fd, buf + n, cap - n);
        if (got < 0 && errno == EINTR)
            continue;
        if (got < 0)
            goto err_free;
        if (got == 0)
            break;
        n += (size_t)got;
    }
    if (n > max) {
        errno = EFBIG;
        goto err_free;
    }
    close(fd);
    buf[n] = '\0';
    *len = n;
    return buf;
err_free:
    MARIE_KEEP_ERRNO(free(buf));
err_close:
    MARIE_KEEP_ERRNO(close(fd));
    return NULL;
}

/* mkdir -p: every missing component of dir. */
static int make_dirs(const char *dir, mode_t mode)
{
    char *p = strdup(dir);
    if (!p)
        return marie_fail(ENOMEM);
    int rc = 0;
    for (char *s = p + 1; rc == 0; s++) {
        if (*s != '/' && *s)
            continue;
        char c = *s;
        *s = 0;
        if (mkdir(p, mode) < 0 && errno != EEXIST)
            rc = -1;
        *s = c;
        if (!c)
            break;
    }
    MARIE_KEEP_ERRNO(free(p));
    return rc;
}

char *marie_state_dir(void)
{
    char *dir = NULL;
    const char *e = getenv("MARIE_STATE_DIR");
    const char *sd = getenv("STATE_DIRECTORY");       /* systemd's StateDirectory=, ':'-separated */
    const char *xdg = getenv("XDG_STATE_HOME"), *home = getenv("HOME");
    if (e && *e)
        dir = strdup(e);
    else if (sd && *sd)
        dir = strndup(sd, strcspn(sd, ":"));
    else if (geteuid() == 0)
        dir = strdup("/var/lib/marie");
    else if (xdg && *xdg == '/') {
        if (asprintf(&dir, "%s/marie", xdg) < 0)
            dir = NULL;
    } else if (home && *home == '/') {
        if (asprintf(&dir, "%s/.local/state/marie", home) < 0)
            dir = NULL;
    } else {
        return marie_fail_null(ENOENT);
    }
    if (!dir)
        return marie_fail_null(ENOMEM);
    if (make_dirs(dir, 0700) < 0) {
        MARIE_KEEP_ERRNO(free(dir));
        return NULL;
    }
    return dir;
}
