/* file: whole-file reads for map images, keys and system files, bounded so a huge or endless
 * file (a device, a FIFO) cannot exhaust memory. */
#include "core/file.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

void *marie_file_read(const char *path, size_t max, size_t *len)
{
    int e, fd = open(path, O_RDONLY | O_CLOEXEC);
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
    e = errno;
    free(buf);
    errno = e;
err_close:
    e = errno;
    close(fd);
    errno = e;
    return NULL;
}
