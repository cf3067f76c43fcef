/* syncshim: an LD_PRELOAD library for tests that traces, in order, a process's writes to files
 * under $SYNCSHIM_DIR, its fsync/fdatasync calls, renames and links there, and its datagrams,
 * into $SYNCSHIM_TRACE; a datagram sent while a write or a rename is not yet synced is
 * marked, since SIGKILL keeps the page cache and only a power loss would show it. With
 * SYNCSHIM_CACHE=1 it plays that power loss: writes to those files are held in the process
 * until their fsync/fdatasync, so whatever was not synced dies with it. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/types.h>
#include <unistd.h>

#define MAXFD 4096
static unsigned char watched[MAXFD];    /* 1 file under the directory, 2 the directory */
static unsigned char dirty[MAXFD];
static int lost_dirty;                  /* closed before it was synced */
static int dir_dirty;                   /* a rename or link there, directory not synced */
static int trace_fd = -1;
static struct {
    char *buf;
    size_t len, cap;
} held[MAXFD];                          /* SYNCSHIM_CACHE: written, not yet synced */

/* Lines go out by system call: the shim's own output must not be traced. */
static void trace(const char *fmt, ...)
{
    if (trace_fd < 0) {
        const char *p = getenv("SYNCSHIM_TRACE");
        if (!p || (trace_fd = (int)syscall(SYS_openat, AT_FDCWD, p, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644)) < 0)
            return;
    }
    char line[128];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    if (n > 0)
        syscall(SYS_write, trace_fd, line, (size_t)n < sizeof line ? (size_t)n : sizeof line - 1);
}

/* 1 for a path under the directory, 2 for the directory itself, else 0. A SharedMap's
 * FILE.lock is not watched: besides the lock it holds only a note of the last record
 * acknowledged, advisory and never synced by design (docs/ca.md). */
static int classify(const char *path)
{
    const char *d = getenv("SYNCSHIM_DIR");
    size_t n = d ? strlen(d) : 0, len = path ? strlen(path) : 0;
    if (!n || !path || strncmp(path, d, n) != 0 || (len > 5 && strcmp(path + len - 5, ".lock") == 0))
        return 0;
    return path[n] == 0 ? 2 : path[n] == '/' ? 1 : 0;
}

static int any_dirty(void)
{
    if (lost_dirty || dir_dirty)
        return 1;
    for (int i = 0; i < MAXFD; i++)
        if (dirty[i])
            return 1;
    return 0;
}

#define REAL(ret, name, ...) \
    static ret (*real_)(__VA_ARGS__); \
    if (!real_) \
        real_ = (ret (*)(__VA_ARGS__))dlsym(RTLD_NEXT, name)

static int opened(int fd, const char *path)
{
    if (fd >= 0 && fd < MAXFD) {
        watched[fd] = (unsigned char)classify(path);
        dirty[fd] = 0;
        held[fd].len = 0;
    }
    return fd;
}

int open(const char *path, int flags, ...)
{
    REAL(int, "open", const char *, int, ...);
    va_list ap;
    va_start(ap, flags);
    mode_t mode = (flags & (O_CREAT | O_TMPFILE)) ? va_arg(ap, mode_t) : 0;
    va_end(ap);
    return opened(real_(path, flags, mode), path);
}

int open64(const char *path, int flags, ...)
{
    REAL(int, "open64", const char *, int, ...);
    va_list ap;
    va_start(ap, flags);
    mode_t mode = (flags & (O_CREAT | O_TMPFILE)) ? va_arg(ap, mode_t) : 0;
    va_end(ap);
    return opened(real_(path, flags, mode), path);
}

int openat(int dirfd, const char *path, int flags, ...)
{
    REAL(int, "openat", int, const char *, int, ...);
    va_list ap;
    va_start(ap, flags);
    mode_t mode = (flags & (O_CREAT | O_TMPFILE)) ? va_arg(ap, mode_t) : 0;
    va_end(ap);
    return opened(real_(dirfd, path, flags, mode), path);
}

int close(int fd)
{
    REAL(int, "close", int);
    if (fd >= 0 && fd < MAXFD) {
        if (dirty[fd]) {
            lost_dirty = 1;
            trace("C %d unsynced\n", fd);
        }
        watched[fd] = dirty[fd] = 0;
        held[fd].len = 0;               /* never synced: lost, as in a power cut */
    }
    return real_(fd);
}

static void wrote(int fd, ssize_t n)
{
    if (n > 0 && fd >= 0 && fd < MAXFD && watched[fd] == 1) {
        dirty[fd] = 1;
        trace("W %d %zd\n", fd, n);
    }
}

static int caching(int fd)
{
    const char *c = getenv("SYNCSHIM_CACHE");
    return c && *c == '1' && fd >= 0 && fd < MAXFD && watched[fd] == 1;
}

ssize_t write(int fd, const void *buf, size_t len)
{
    REAL(ssize_t, "write", int, const void *, size_t);
    if (caching(fd)) {
        if (held[fd].len + len > held[fd].cap) {
            size_t cap = (held[fd].len + len) * 2;
            char *nb = realloc(held[fd].buf, cap);
            if (!nb)
                return real_(fd, buf, len);
            held[fd].buf = nb;
            held[fd].cap = cap;
        }
        memcpy(held[fd].buf + held[fd].len, buf, len);
        held[fd].len += len;
        wrote(fd, (ssize_t)len);
        return (ssize_t)len;
    }
    ssize_t n = real_(fd, buf, len);
    wrote(fd, n);
    return n;
}

/* What a sync makes durable: the held writes go to the file first. */
static int flush_held(int fd)
{
    REAL(ssize_t, "write", int, const void *, size_t);
    if (fd < 0 || fd >= MAXFD)
        return 0;
    size_t off = 0;
    while (off < held[fd].len) {
        ssize_t n = real_(fd, held[fd].buf + off, held[fd].len - off);
        if (n <= 0)
            return -1;
        off += (size_t)n;
    }
    held[fd].len = 0;
    return 0;
}

ssize_t pwrite(int fd, const void *buf, size_t len, off_t off)
{
    REAL(ssize_t, "pwrite", int, const void *, size_t, off_t);
    ssize_t n = real_(fd, buf, len, off);
    wrote(fd, n);
    return n;
}

int ftruncate(int fd, off_t len)
{
    REAL(int, "ftruncate", int, off_t);
    if (fd >= 0 && fd < MAXFD)
        held[fd].len = 0;               /* a cut-back drops what was held after it */
    int rc = real_(fd, len);
    wrote(fd, rc == 0 ? 1 : 0);
    return rc;
}

static void synced(int fd, int rc)
{
    if (rc != 0 || fd < 0 || fd >= MAXFD || !watched[fd])
        return;
    if (watched[fd] == 2) {
        dir_dirty = 0;
        trace("D %d\n", fd);
    } else {
        dirty[fd] = 0;
        trace("S %d\n", fd);
    }
}

int fsync(int fd)
{
    REAL(int, "fsync", int);
    int rc = flush_held(fd) < 0 ? -1 : real_(fd);
    synced(fd, rc);
    return rc;
}

int fdatasync(int fd)
{
    REAL(int, "fdatasync", int);
    int rc = flush_held(fd) < 0 ? -1 : real_(fd);
    synced(fd, rc);
    return rc;
}

int rename(const char *from, const char *to)
{
    REAL(int, "rename", const char *, const char *);
    int rc = real_(from, to);
    if (rc == 0 && classify(to) == 1) {
        dir_dirty = 1;
        trace("R\n");
    }
    return rc;
}

int link(const char *from, const char *to)
{
    REAL(int, "link", const char *, const char *);
    int rc = real_(from, to);
    if (rc == 0 && classify(to) == 1) {
        dir_dirty = 1;
        trace("L\n");
    }
    return rc;
}

static void sent(ssize_t n)
{
    if (n >= 0)
        trace(any_dirty() ? "N! %zd\n" : "N %zd\n", n);
}

ssize_t sendmsg(int fd, const struct msghdr *msg, int flags)
{
    REAL(ssize_t, "sendmsg", int, const struct msghdr *, int);
    ssize_t n = real_(fd, msg, flags);
    sent(n);
    return n;
}

/* marie's own LCM sender hands datagrams to the kernel this way (core/bus/udpm_send.c): each one traced. */
int sendmmsg(int fd, struct mmsghdr *vec, unsigned int vlen, int flags)
{
    REAL(int, "sendmmsg", int, struct mmsghdr *, unsigned int, int);
    int n = real_(fd, vec, vlen, flags);
    for (int i = 0; i < n; i++)
        sent((ssize_t)vec[i].msg_len);
    return n;
}

ssize_t sendto(int fd, const void *buf, size_t len, int flags, const struct sockaddr *to, socklen_t tolen)
{
    REAL(ssize_t, "sendto", int, const void *, size_t, int, const struct sockaddr *, socklen_t);
    ssize_t n = real_(fd, buf, len, flags, to, tolen);
    sent(n);
    return n;
}

ssize_t send(int fd, const void *buf, size_t len, int flags)
{
    REAL(ssize_t, "send", int, const void *, size_t, int);
    ssize_t n = real_(fd, buf, len, flags);
    sent(n);
    return n;
}
