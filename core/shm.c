/* shm: a ring of seqlocked slots in /dev/shm, one writer, any number of read-only readers. */
#include "core/shm.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/err.h"

#define SHM_MAGIC 0x6d73686du     /* "mshm" */
#define SHM_VERSION 1
#define SHM_PREFIX "marie-shm."
#define SHM_DIR "/dev/shm"
#define READER_MAPS 4
#define ALIGN 64

typedef struct {
    uint32_t magic, version;
    uint64_t slot_size;         /* payload bytes per slot */
    uint64_t stride;            /* bytes from one slot header to the next */
    uint32_t nslots;
    int32_t pid;                /* the writer */
    _Atomic uint64_t write_seq; /* last complete message */
} shm_hdr_t;

/* seq is 2n - 1 while message n is written into the slot, 2n once it is complete. */
typedef struct {
    _Atomic uint64_t seq;
    uint64_t size;
} slot_hdr_t;

#define DATA_OFF ((sizeof(slot_hdr_t) + ALIGN - 1) / ALIGN * ALIGN)
#define HDR_SIZE ((sizeof(shm_hdr_t) + ALIGN - 1) / ALIGN * ALIGN)

struct marie_shm_writer {
    char name[MARIE_SHM_NAME_MAX];
    uint8_t *base;
    size_t len;
    shm_hdr_t *hdr;
    uint64_t seq;
    uint64_t open;              /* the message begun and not committed, or 0 */
};

typedef struct {
    char name[MARIE_SHM_NAME_MAX];
    const uint8_t *base;
    size_t len;
    uint64_t used;              /* for eviction: the oldest use goes first */
} reader_map_t;

struct marie_shm_reader {
    reader_map_t maps[READER_MAPS];
    uint64_t uses;
};

static slot_hdr_t *slot_at(const uint8_t *base, const shm_hdr_t *h, uint64_t i)
{
    return (slot_hdr_t *)(base + HDR_SIZE + i * h->stride);
}

static int segment_name(char *out, size_t cap, const char *channel, pid_t pid)
{
    char clean[64];
    size_t n = 0;
    for (const char *p = channel; *p && n < sizeof clean - 1; p++) {
        char c = *p;
        bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '-';
        clean[n++] = ok ? c : '_';
    }
    clean[n] = '\0';
    int r = snprintf(out, cap, "%s%s.%d", SHM_PREFIX, clean, (int)pid);
    return r > 0 && (size_t)r < cap ? 0 : -1;
}

/* Remove /dev/shm/marie-shm.* segments whose writer process is gone. Returns how many. */
static int marie_shm_sweep(void)
{
    DIR *d = opendir(SHM_DIR);
    if (!d)
        return 0;
    int removed = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (strncmp(e->d_name, SHM_PREFIX, strlen(SHM_PREFIX)) != 0)
            continue;
        const char *dot = strrchr(e->d_name, '.');
        char *end;
        long pid = dot ? strtol(dot + 1, &end, 10) : 0;
        if (!dot || *end || pid <= 0)
            continue;
        if (kill((pid_t)pid, 0) < 0 && errno == ESRCH) {
            char path[512];
            snprintf(path, sizeof path, SHM_DIR "/%s", e->d_name);
            if (unlink(path) == 0)
                removed++;
        }
    }
    closedir(d);
    return removed;
}

marie_shm_writer_t *marie_shm_writer_create(const char *channel, size_t slot_size, int nslots)
{
    if (!channel || !*channel || slot_size == 0 || slot_size > ((size_t)1 << 30) || nslots < 2 || nslots > 1024)
        return marie_fail_null(EINVAL);
    marie_shm_sweep();
    marie_shm_writer_t *w = calloc(1, sizeof *w);
    if (!w)
        return NULL;
    if (segment_name(w->name, sizeof w->name, channel, getpid()) < 0) {
        errno = EINVAL;
        goto err_free;
    }
    uint64_t stride = (DATA_OFF + slot_size + ALIGN - 1) / ALIGN * ALIGN;
    w->len = HDR_SIZE + stride * (uint64_t)nslots;
    char path[256];
    snprintf(path, sizeof path, SHM_DIR "/%s", w->name);
    unlink(path);               /* ours by pid: a leftover of a process that had our pid */
    int fd = open(path, O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0)
        goto err_free;
    if (ftruncate(fd, (off_t)w->len) < 0)
        goto err_unlink;
    w->base = mmap(NULL, w->len, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    if (w->base == MAP_FAILED)
        goto err_unlink;
    close(fd);
    w->hdr = (shm_hdr_t *)w->base;
    w->hdr->slot_size = slot_size;
    w->hdr->stride = stride;
    w->hdr->nslots = (uint32_t)nslots;
    w->hdr->pid = (int32_t)getpid();
    w->hdr->version = SHM_VERSION;
    atomic_store_explicit(&w->hdr->write_seq, 0, memory_order_relaxed);
    /* The magic last: a reader that sees it sees a complete header. */
    atomic_thread_fence(memory_order_release);
    w->hdr->magic = SHM_MAGIC;
    return w;
err_unlink:
    MARIE_KEEP_ERRNO(close(fd); unlink(path));
err_free:
    MARIE_KEEP_ERRNO(free(w));
    return NULL;
}

void marie_shm_writer_destroy(marie_shm_writer_t *w)
{
    if (!w)
        return;
    char path[256];
    snprintf(path, sizeof path, SHM_DIR "/%s", w->name);
    unlink(path);               /* readers keep their mappings until they let go */
    munmap(w->base, w->len);
    free(w);
}

const char *marie_shm_writer_segment(const marie_shm_writer_t *w) { return w->name; }

void *marie_shm_begin(marie_shm_writer_t *w)
{
    if (!w->open) {             /* else a write begun and not committed: its slot again */
        w->open = ++w->seq;
        slot_hdr_t *s = slot_at(w->base, w->hdr, w->open % w->hdr->nslots);
        atomic_store_explicit(&s->seq, 2 * w->open - 1, memory_order_relaxed);
        atomic_thread_fence(memory_order_release);      /* odd before any byte of the new data */
    }
    return marie_shm_begun(w);
}

void *marie_shm_begun(const marie_shm_writer_t *w)
{
    return w->open ? (uint8_t *)slot_at(w->base, w->hdr, w->open % w->hdr->nslots) + DATA_OFF : NULL;
}

int marie_shm_commit(marie_shm_writer_t *w, size_t len, marie_shm_ref_t *ref)
{
    if (!w->open)
        return marie_fail(EINVAL);
    uint64_t n = w->open;
    w->open = 0;
    slot_hdr_t *s = slot_at(w->base, w->hdr, n % w->hdr->nslots);
    bool fits = len <= w->hdr->slot_size;
    s->size = fits ? len : 0;
    atomic_store_explicit(&s->seq, 2 * n, memory_order_release);
    atomic_store_explicit(&w->hdr->write_seq, n, memory_order_release);
    if (!fits)
        return marie_fail(EMSGSIZE);
    if (!ref)
        return 0;
    memcpy(ref->segment, w->name, sizeof ref->segment);     /* both NUL-terminated, of one size */
    ref->seq = (int64_t)n;
    ref->size = (uint32_t)len;
    return 0;
}

size_t marie_shm_slot_size(const marie_shm_writer_t *w) { return w->hdr->slot_size; }

int marie_shm_write_with(marie_shm_writer_t *w, size_t len, marie_shm_fill_t fill, void *user, marie_shm_ref_t *ref)
{
    if (len > w->hdr->slot_size)
        return marie_fail(EMSGSIZE);
    if (fill(marie_shm_begin(w), len, user) < 0) {
        marie_shm_commit(w, 0, NULL);
        return marie_fail(EINVAL);     /* no ref: nobody is told of the empty slot */
    }
    return marie_shm_commit(w, len, ref);
}

int marie_shm_fill_copy(void *dst, size_t len, void *src)
{
    memcpy(dst, src, len);
    return 0;
}

int marie_shm_write(marie_shm_writer_t *w, const void *data, size_t len, marie_shm_ref_t *ref)
{
    return marie_shm_write_with(w, len, marie_shm_fill_copy, (void *)data, ref);
}

marie_shm_reader_t *marie_shm_reader_create(void)
{
    return calloc(1, sizeof(marie_shm_reader_t));
}

void marie_shm_reader_destroy(marie_shm_reader_t *r)
{
    if (!r)
        return;
    for (int i = 0; i < READER_MAPS; i++)
        if (r->maps[i].base)
            munmap((void *)r->maps[i].base, r->maps[i].len);
    free(r);
}

static bool valid_name(const char *s)
{
    if (strncmp(s, SHM_PREFIX, strlen(SHM_PREFIX)) != 0 || strlen(s) >= MARIE_SHM_NAME_MAX)
        return false;
    for (; *s; s++)
        if (*s == '/')
            return false;
    return true;
}

/* The mapping of a segment, opened and checked the first time it is named. */
static const reader_map_t *map_of(marie_shm_reader_t *r, const char *name)
{
    reader_map_t *free_slot = NULL, *oldest = &r->maps[0];
    for (int i = 0; i < READER_MAPS; i++) {
        reader_map_t *m = &r->maps[i];
        if (m->base && strcmp(m->name, name) == 0) {
            m->used = ++r->uses;
            return m;
        }
        if (!m->base && !free_slot)
            free_slot = m;
        if (m->used < oldest->used)
            oldest = m;
    }
    if (!valid_name(name)) {
        return marie_fail_null(EBADMSG);
    }
    char path[256];
    snprintf(path, sizeof path, SHM_DIR "/%s", name);
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return NULL;
    struct stat st;
    void *base = MAP_FAILED;
    if (fstat(fd, &st) == 0 && (size_t)st.st_size >= HDR_SIZE)
        base = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_SHARED, fd, 0);
    close(fd);
    if (base == MAP_FAILED)
        return marie_fail_null(EBADMSG);
    const shm_hdr_t *h = base;
    /* Nothing in the header is trusted: a slot must lie inside the file, aligned as the writer
     * lays them out (its seq is read atomically). */
    if (h->magic != SHM_MAGIC || h->version != SHM_VERSION || h->nslots < 2 || h->slot_size == 0 ||
        h->stride < DATA_OFF + h->slot_size || h->stride % ALIGN != 0 ||
        h->stride > ((uint64_t)st.st_size - HDR_SIZE) / h->nslots) {
        munmap(base, (size_t)st.st_size);
        return marie_fail_null(EBADMSG);
    }
    reader_map_t *m = free_slot ? free_slot : oldest;
    if (m->base)
        munmap((void *)m->base, m->len);
    snprintf(m->name, sizeof m->name, "%s", name);
    m->base = base;
    m->len = (size_t)st.st_size;
    m->used = ++r->uses;
    return m;
}

/* The slot of ref, when it still holds that message (s1 = its sequence number). */
static slot_hdr_t *slot_of(marie_shm_reader_t *r, const marie_shm_ref_t *ref, uint64_t *s1)
{
    if (ref->seq <= 0)
        return marie_fail_null(EBADMSG);
    const reader_map_t *m = map_of(r, ref->segment);
    if (!m)
        return NULL;
    const shm_hdr_t *h = (const shm_hdr_t *)m->base;
    slot_hdr_t *s = slot_at(m->base, h, (uint64_t)ref->seq % h->nslots);
    uint64_t want = 2 * (uint64_t)ref->seq;
    *s1 = atomic_load_explicit(&s->seq, memory_order_acquire);
    if (*s1 != want)
        return marie_fail_null(*s1 > want ? ESTALE : EBADMSG);
    if (s->size > h->slot_size || s->size != ref->size)
        return marie_fail_null(EAGAIN);     /* a size being rewritten: the slot moved on */
    return s;
}

const void *marie_shm_peek(marie_shm_reader_t *r, const marie_shm_ref_t *ref)
{
    uint64_t s1;
    slot_hdr_t *s = slot_of(r, ref, &s1);
    return s ? (const uint8_t *)s + DATA_OFF : NULL;
}

bool marie_shm_still_valid(marie_shm_reader_t *r, const marie_shm_ref_t *ref)
{
    atomic_thread_fence(memory_order_acquire);      /* every use of the bytes before this look */
    uint64_t s1;
    return slot_of(r, ref, &s1) != NULL;
}

int64_t marie_shm_newest(marie_shm_reader_t *r, const char *segment)
{
    const reader_map_t *m = map_of(r, segment);
    if (!m)
        return -1;
    return (int64_t)atomic_load_explicit(&((const shm_hdr_t *)m->base)->write_seq, memory_order_acquire);
}

int marie_shm_ref_at(marie_shm_reader_t *r, const char *segment, int64_t seq, marie_shm_ref_t *ref)
{
    if (seq <= 0)
        return marie_fail(EBADMSG);
    const reader_map_t *m = map_of(r, segment);
    if (!m)
        return -1;
    const shm_hdr_t *h = (const shm_hdr_t *)m->base;
    slot_hdr_t *s = slot_at(m->base, h, (uint64_t)seq % h->nslots);
    uint64_t want = 2 * (uint64_t)seq, s1 = atomic_load_explicit(&s->seq, memory_order_acquire);
    if (s1 != want)
        return marie_fail(s1 > want ? ESTALE : EAGAIN);
    uint64_t size = s->size;
    if (size > h->slot_size)
        return marie_fail(EAGAIN);
    memcpy(ref->segment, m->name, sizeof ref->segment);     /* segment's own name, NUL-terminated */
    ref->seq = seq;
    ref->size = (uint32_t)size;
    return 0;
}

int64_t marie_shm_read(marie_shm_reader_t *r, const marie_shm_ref_t *ref, void *buf, size_t cap)
{
    if (ref->seq <= 0)
        return marie_fail(EBADMSG);
    const reader_map_t *m = map_of(r, ref->segment);
    if (!m)
        return -1;
    const shm_hdr_t *h = (const shm_hdr_t *)m->base;
    slot_hdr_t *s = slot_at(m->base, h, (uint64_t)ref->seq % h->nslots);
    uint64_t want = 2 * (uint64_t)ref->seq;
    uint64_t s1 = atomic_load_explicit(&s->seq, memory_order_acquire);
    if (s1 != want)
        return marie_fail(s1 > want ? ESTALE : EBADMSG);
    uint64_t size = s->size;
    if (size > h->slot_size)
        return marie_fail(EAGAIN);         /* a size being rewritten: the slot moved on */
    if (size > cap)
        return marie_fail(EMSGSIZE);
    memcpy(buf, (const uint8_t *)s + DATA_OFF, size);
    atomic_thread_fence(memory_order_acquire);      /* the copy before the second look */
    if (atomic_load_explicit(&s->seq, memory_order_relaxed) != s1)
        return marie_fail(EAGAIN);
    return (int64_t)size;
}
