/* local_reg: the same-host fast path's registry of a channel (who publishes where, who listens
 * at which doorbell) and its doorbells, FIFOs in /dev/shm. */
#include "core/bus/local.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/bus/shm_bus.h"
#include "core/err.h"

#define REG_MAGIC 0x6c6f6361u       /* "loca" */
#define REG_VERSION 2    /* 2: a subscriber's CPU */
#define SHM_DIR "/dev/shm"
#define BELL_PREFIX "marie-bell."

/* The network namespace this process is in: registries are per namespace, as LCM's multicast
 * is (tests in namespaces of their own never meet; a robot's host has one). */
static const char *netns(void)
{
    static char id[32];
    if (!id[0]) {
        char link[64];
        ssize_t n = readlink("/proc/self/ns/net", link, sizeof link - 1);
        unsigned long v = 0;
        if (n > 0) {
            link[n] = '\0';
            sscanf(link, "net:[%lu]", &v);
        }
        snprintf(id, sizeof id, "%lu", v);
    }
    return id;
}

/* Names in a file name: letters, digits, _ and - as they are, the rest as %XX, so that two
 * channels never share a registry. */
static int escaped(char *out, size_t cap, int n, const char *name)
{
    for (const unsigned char *p = (const unsigned char *)name; *p && n > 0 && (size_t)n + 4 < cap; p++) {
        bool plain = (*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || (*p >= '0' && *p <= '9') || *p == '_' ||
                     *p == '-';
        n += plain ? snprintf(out + n, cap - (size_t)n, "%c", *p) : snprintf(out + n, cap - (size_t)n, "%%%02x", *p);
    }
    return n;
}

/* The registry of a channel in this network namespace on this host (the host as the shared
 * memory transport names it: a test plays another host with MARIE_SHM_HOST). */
void local_reg_path(char *out, size_t cap, const char *channel)
{
    char host[64];
    marie_shm_host(host, sizeof host);
    int n = snprintf(out, cap, SHM_DIR "/marie-local.%s.", netns());
    n = escaped(out, cap, n, host);
    n += n > 0 && (size_t)n + 1 < cap ? snprintf(out + n, cap - (size_t)n, ".") : 0;
    escaped(out, cap, n, channel);
}

static bool alive(int32_t pid) { return pid > 0 && (kill(pid, 0) == 0 || errno != ESRCH); }

/* Byte 0 of a registry is held shared by every process that has it open, and exclusively only
 * by one that removes it (when nobody else holds it); byte 1 exclusively while entries change.
 * Open file description locks: each open() of the file has its own. */
enum { USERS = 0, CHANGES = 1 };

static int lock(int fd, int byte, short type, bool wait)
{
    struct flock l = {.l_type = type, .l_whence = SEEK_SET, .l_start = byte, .l_len = 1};
    int rc;
    do
        rc = fcntl(fd, wait ? F_OFD_SETLKW : F_OFD_SETLK, &l);
    while (rc < 0 && errno == EINTR);
    return rc;
}

static void changing(const local_reg_t *r) { lock(r->fd, CHANGES, F_WRLCK, true); }
static void changed(const local_reg_t *r) { lock(r->fd, CHANGES, F_UNLCK, true); }

/* The file's entries made ready by the first to open it. */
static int init(local_reg_t *r)
{
    struct stat st;
    int rc = -1;
    changing(r);
    if (fstat(r->fd, &st) < 0 ||
        ((size_t)st.st_size < sizeof(local_registry_t) && ftruncate(r->fd, sizeof(local_registry_t)) < 0))
        goto out;
    r->reg = mmap(NULL, sizeof(local_registry_t), PROT_READ | PROT_WRITE, MAP_SHARED, r->fd, 0);
    if (r->reg == MAP_FAILED) {
        r->reg = NULL;
        goto out;
    }
    if (r->reg->magic == 0) {
        r->reg->magic = REG_MAGIC;
        r->reg->version = REG_VERSION;
    }
    if (r->reg->magic == REG_MAGIC && r->reg->version == REG_VERSION) {
        rc = 0;
    } else {
        munmap(r->reg, sizeof(local_registry_t));
        r->reg = NULL;
        errno = EPROTO;
    }
out:
    MARIE_KEEP_ERRNO(changed(r));
    return rc;
}

int local_reg_open(local_reg_t *r, const char *channel)
{
    *r = (local_reg_t){.fd = -1};
    local_reg_path(r->path, sizeof r->path, channel);
    /* A registry its last user removes is unlinked while that user holds it alone: one opened
     * just before is let go and opened again. */
    for (int attempt = 0; attempt < 8; attempt++) {
        struct stat st;
        if ((r->fd = open(r->path, O_RDWR | O_CREAT | O_CLOEXEC, 0600)) < 0 || lock(r->fd, USERS, F_RDLCK, true) < 0 ||
            fstat(r->fd, &st) < 0)
            goto err;
        if (st.st_nlink == 0) {
            close(r->fd);
            continue;
        }
        if (init(r) < 0)
            goto err;
        return 0;
    }
    errno = EAGAIN;
err:
    if (r->fd >= 0)
        MARIE_KEEP_ERRNO(close(r->fd));
    r->fd = -1;
    return -1;
}

void local_reg_close(local_reg_t *r)
{
    if (!r->reg)
        return;
    if (lock(r->fd, USERS, F_WRLCK, false) == 0)
        unlink(r->path);        /* nobody else has it open */
    munmap(r->reg, sizeof(local_registry_t));
    close(r->fd);               /* lets go of the locks */
    r->reg = NULL;
    r->fd = -1;
}

/* A free entry: never used, let go, or left by a process that is gone. */
static int free_entry(_Atomic int32_t *pid, size_t stride, int n)
{
    for (int i = 0; i < n; i++) {
        _Atomic int32_t *p = (_Atomic int32_t *)((char *)pid + (size_t)i * stride);
        if (!alive(atomic_load(p)))
            return i;
    }
    return -1;
}

int local_reg_add_pub(local_reg_t *r, const char *segment)
{
    changing(r);
    int i = free_entry(&r->reg->pubs[0].pid, sizeof r->reg->pubs[0], LOCAL_PUBS);
    if (i >= 0) {
        local_pub_t *e = &r->reg->pubs[i];
        atomic_store(&e->pid, 0);
        snprintf(e->segment, sizeof e->segment, "%s", segment);
        atomic_store(&e->ticket, atomic_fetch_add(&r->reg->tickets, 1) + 1);
        atomic_store(&e->pid, (int32_t)getpid());   /* last: a reader that sees it sees the rest */
    }
    changed(r);
    return i >= 0 ? i : marie_fail(ENOSPC);
}

int local_reg_add_sub(local_reg_t *r, const char *bell)
{
    changing(r);
    int i = free_entry(&r->reg->subs[0].pid, sizeof r->reg->subs[0], LOCAL_SUBS);
    if (i >= 0) {
        local_sub_t *e = &r->reg->subs[i];
        atomic_store(&e->pid, 0);
        snprintf(e->bell, sizeof e->bell, "%s", bell);
        atomic_store(&e->sleeping, 0);
        atomic_store(&e->ticket, atomic_fetch_add(&r->reg->tickets, 1) + 1);
        atomic_store(&e->pid, (int32_t)getpid());
        if (atomic_load(&r->reg->subs_used) <= (uint32_t)i)
            atomic_store(&r->reg->subs_used, (uint32_t)i + 1);
    }
    changed(r);
    return i >= 0 ? i : marie_fail(ENOSPC);
}

void local_reg_remove_pub(local_reg_t *r, int i)
{
    changing(r);
    atomic_store(&r->reg->pubs[i].pid, 0);
    atomic_fetch_add(&r->reg->tickets, 1);
    changed(r);
}

void local_reg_remove_sub(local_reg_t *r, int i)
{
    changing(r);
    atomic_store(&r->reg->subs[i].pid, 0);
    atomic_fetch_add(&r->reg->tickets, 1);
    changed(r);
}

/* ---- doorbells ---- */

/* Doorbells of processes that are gone (killed before they could remove theirs). */
static void sweep_bells(void)
{
    DIR *d = opendir(SHM_DIR);
    struct dirent *e;
    while (d && (e = readdir(d))) {
        long pid = 0;
        if (strncmp(e->d_name, BELL_PREFIX, strlen(BELL_PREFIX)) == 0 &&
            sscanf(e->d_name + strlen(BELL_PREFIX), "%ld.", &pid) == 1 && !alive((int32_t)pid)) {
            char path[512];
            snprintf(path, sizeof path, SHM_DIR "/%s", e->d_name);
            unlink(path);
        }
    }
    if (d)
        closedir(d);
}

/* Registries nobody has open (their processes were killed before they could remove them). */
static void sweep_registries(void)
{
    DIR *d = opendir(SHM_DIR);
    struct dirent *e;
    while (d && (e = readdir(d))) {
        char path[320];
        int fd;
        if (strncmp(e->d_name, "marie-local.", 12) != 0)
            continue;
        snprintf(path, sizeof path, SHM_DIR "/%s", e->d_name);
        if ((fd = open(path, O_RDWR | O_CLOEXEC)) < 0)
            continue;
        if (lock(fd, USERS, F_WRLCK, false) == 0)
            unlink(path);
        close(fd);
    }
    if (d)
        closedir(d);
}

int local_bell_open(local_bell_t *b)
{
    static _Atomic int count;
    sweep_bells();
    sweep_registries();
    snprintf(b->name, sizeof b->name, BELL_PREFIX "%d.%d", (int)getpid(), atomic_fetch_add(&count, 1));
    char path[256];
    snprintf(path, sizeof path, SHM_DIR "/%s", b->name);
    unlink(path);
    b->fd = b->self = -1;
    if (mkfifo(path, 0600) < 0)
        return -1;
    /* Open for writing too: with no writer left the reader would see end-of-file, readable
     * forever. */
    if ((b->fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC)) < 0 ||
        (b->self = open(path, O_WRONLY | O_NONBLOCK | O_CLOEXEC)) < 0) {
        MARIE_KEEP_ERRNO(local_bell_close(b));
        return -1;
    }
    return 0;
}

void local_bell_close(local_bell_t *b)
{
    char path[256];
    snprintf(path, sizeof path, SHM_DIR "/%s", b->name);
    unlink(path);
    if (b->fd >= 0)
        close(b->fd);
    if (b->self >= 0)
        close(b->self);
    b->fd = b->self = -1;
}

void local_bell_drain(const local_bell_t *b)
{
    char buf[256];
    while (read(b->fd, buf, sizeof buf) == (ssize_t)sizeof buf)
        ;
}

int local_bell_ring(const char *name, int *fd)
{
    if (*fd < 0) {
        char path[256];
        if (strncmp(name, BELL_PREFIX, strlen(BELL_PREFIX)) != 0 || strchr(name, '/'))
            return marie_fail(EINVAL);
        snprintf(path, sizeof path, SHM_DIR "/%s", name);
        if ((*fd = open(path, O_WRONLY | O_NONBLOCK | O_CLOEXEC)) < 0)
            return -1;      /* ENXIO: nobody reads it any more */
    }
    /* A full FIFO has been rung already. EPIPE (its reader is gone) needs SIGPIPE ignored, which
     * the fast path's publishers do. */
    if (write(*fd, "", 1) < 0 && errno != EAGAIN) {
        MARIE_KEEP_ERRNO(close(*fd));
        *fd = -1;
        return -1;
    }
    return 0;
}
