/* shm: a ring of seqlocked slots in /dev/shm, one writer, any number of read-only readers, and a
 * table where a few of them hold the slot they read in place (the writer skips held slots). */
#include "core/shm.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#endif

#include "core/err.h"

#define SHM_MAGIC 0x6d73686du     /* "mshm" */
#define SHM_VERSION 3
#define SHM_PREFIX "marie-shm."
#define SHM_DIR "/dev/shm"
#define READER_MAPS 4
#define ALIGN 64
#define HOLDS 4                 /* readers that may hold a slot at once; as many spare slots */
#define HOLD_ALIGN 65536        /* the hold table's offset: a page on every MMU */
#define SLOT_BITS 16            /* a hold and an index entry: seq << SLOT_BITS | slot */

typedef struct {
    uint32_t magic, version;
    uint64_t slot_size;         /* payload bytes per slot */
    uint64_t stride;            /* bytes from one slot header to the next */
    uint32_t nslots;            /* messages kept: the index's length */
    int32_t pid;                /* the writer */
    _Atomic uint64_t write_seq; /* last complete message */
    uint32_t nholds;            /* hold entries, and spare slots: nslots + nholds slots */
} shm_hdr_t;

/* A reader's hold: the slot it reads in place (seq << SLOT_BITS | slot), 0 when none. The only
 * bytes of a segment readers write: the table has a page of its own, mapped writable apart. */
typedef struct {
    _Atomic int32_t pid;        /* the entry's reader, 0: free */
    int32_t pad;
    _Atomic uint64_t held;
} hold_t;

/* seq is 2n - 1 while message n is written into the slot, 2n once it is complete; cpu is the
 * CPU its writer committed it on (-1: unknown). */
typedef struct {
    _Atomic uint64_t seq;
    uint64_t size;
    _Atomic int32_t cpu;
} slot_hdr_t;

#define DATA_OFF ((sizeof(slot_hdr_t) + ALIGN - 1) / ALIGN * ALIGN)
#define HDR_SIZE ((sizeof(shm_hdr_t) + ALIGN - 1) / ALIGN * ALIGN)
#define ROUND(x, a) (((x) + (a) - 1) / (a) * (a))

/* Where things lie, from nslots alone (so nothing of it is read from a segment): the header,
 * the index (message n is in slot idx[n % nslots]), the hold table, the slots. */
static uint64_t hold_off(uint64_t nslots) { return ROUND(HDR_SIZE + 8 * nslots, HOLD_ALIGN); }
static uint64_t slots_off(uint64_t nslots) { return hold_off(nslots) + HOLD_ALIGN; }

/* Where a segment's slots lie: read from its header once, checked (layout_ok) and kept by each
 * side. The header is the writer's to rewrite and shares its line with write_seq, which changes
 * at every message: a reader that read these from it at each message would take that line from
 * the writer's CPU each time, and would follow a header rewritten after the check out of its
 * mapping. */
typedef struct {
    uint64_t slot_size, stride;
    uint32_t nslots, nholds;
} geom_t;

struct marie_shm_writer {
    char name[MARIE_SHM_NAME_MAX];
    uint8_t *base;
    size_t len;
    shm_hdr_t *hdr;
    geom_t g;
    uint64_t seq;
    uint64_t open;              /* the message begun and not committed, or 0 */
    uint32_t slot;              /* its slot */
    uint32_t spare;             /* the spare to swap in next when a place's slot is held */
    uint32_t *slots;            /* each place's slot (message n's place: n % nslots), then the
                                 * spare ones (nholds) */
    int64_t skipped;            /* slots passed over because a reader held them */
};

typedef struct {
    char name[MARIE_SHM_NAME_MAX];
    const uint8_t *base;
    size_t len;
    geom_t g;
    uint64_t used;              /* for eviction: the oldest use goes first */
    hold_t *holds;              /* the hold table mapped writable, or NULL: this reader copies */
    int entry;                  /* its entry there, -1 until its first hold */
} reader_map_t;

struct marie_shm_reader {
    reader_map_t maps[READER_MAPS];
    uint64_t uses;
    int last_cpu;               /* the writer's CPU for the last marie_shm_ref_at() that found one */
};

static slot_hdr_t *slot_at(const uint8_t *base, const geom_t *g, uint64_t i)
{
    return (slot_hdr_t *)(base + slots_off(g->nslots) + i * g->stride);
}

static _Atomic uint64_t *index_at(const uint8_t *base, const geom_t *g, uint64_t seq)
{
    return (_Atomic uint64_t *)(base + HDR_SIZE) + seq % g->nslots;
}

static uint32_t nphys(const geom_t *g) { return g->nslots + g->nholds; }

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
    if (!(w->slots = calloc((size_t)nslots + HOLDS, sizeof *w->slots)))
        goto err_free;
    if (segment_name(w->name, sizeof w->name, channel, getpid()) < 0) {
        errno = EINVAL;
        goto err_free;
    }
    uint64_t stride = (DATA_OFF + slot_size + ALIGN - 1) / ALIGN * ALIGN;
    w->len = slots_off((uint64_t)nslots) + stride * (uint64_t)(nslots + HOLDS);
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
    w->g = (geom_t){slot_size, stride, (uint32_t)nslots, HOLDS};
    w->hdr->slot_size = slot_size;
    w->hdr->stride = stride;
    w->hdr->nslots = (uint32_t)nslots;
    w->hdr->nholds = HOLDS;
    for (uint32_t i = 0; i < nphys(&w->g); i++)
        w->slots[i] = i;
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
    MARIE_KEEP_ERRNO(free(w->slots); free(w));
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
    free(w->slots);
    free(w);
}

const char *marie_shm_writer_segment(const marie_shm_writer_t *w) { return w->name; }

/* Does a reader hold slot k? Holds are loaded after the slot was marked odd (both seq_cst):
 * a reader that stored its hold before sees the slot odd afterwards, or the writer sees it. */
static bool held(const marie_shm_writer_t *w, uint32_t k)
{
    const hold_t *t = (const hold_t *)(w->base + hold_off(w->g.nslots));
    for (uint32_t i = 0; i < w->g.nholds; i++) {
        uint64_t v = atomic_load(&t[i].held);
        if (v && (v & ((1u << SLOT_BITS) - 1)) == k)
            return true;
    }
    return false;
}

/* The slot of the ring's next place, marked odd (being written); when a reader holds it, a
 * spare takes its place and it becomes a spare. The place's slot and the nholds spares are
 * nholds + 1 slots, and a reader holds one at most: one is free. A slot written over has had
 * at least nslots - 1 messages after it, as without holds, and while nobody holds, the spares
 * are never touched (the memory the ring goes round stays nslots slots, as a cache sees it). */
static uint32_t claim_slot(marie_shm_writer_t *w)
{
    uint32_t *at = &w->slots[w->open % w->g.nslots];
    for (;;) {
        uint32_t k = *at;
        slot_hdr_t *s = slot_at(w->base, &w->g, k);
        uint64_t was = atomic_load_explicit(&s->seq, memory_order_relaxed);
        atomic_store(&s->seq, 2 * w->open - 1);
        if (!held(w, k))
            return k;
        atomic_store(&s->seq, was);         /* held: its bytes are untouched, as its reader saw them */
        w->skipped++;
        uint32_t *spare = &w->slots[w->g.nslots + w->spare++ % w->g.nholds];
        *at = *spare;
        *spare = k;
    }
}

/* A line taken for writing ahead of the write: PREFETCHW where the CPU has it (CPUID
 * 0x80000001 ECX bit 8: AMD's and Intel's x86-64 CPUs of the last ten years), else a plain
 * prefetch. */
#if defined(__x86_64__) || defined(__i386__)
static bool has_prefetchw(void)
{
    static int known = -1;
    unsigned a, b, c = 0, d;
    if (known < 0)
        known = __get_cpuid(0x80000001, &a, &b, &c, &d) && (c & (1u << 8));
    return known;
}

static inline void prefetch_for_write(const void *p, bool w)
{
    if (w)
        __asm__ volatile("prefetchw %0" : : "m"(*(const char *)p));
    else
        __builtin_prefetch(p, 1);
}
#else
static bool has_prefetchw(void) { return false; }
static inline void prefetch_for_write(const void *p, bool w) { __builtin_prefetch(p, 1); }
#endif

/* The next place's slot, taken for writing while the writer waits for other things (an answer,
 * its next message): a reader read it last, and without this the next message's first writes
 * would each wait for the reader's copies of their lines to be dropped. As many bytes as the
 * slot's last message had, PREFETCH_MAX at most. */
#define PREFETCH_MAX 16384
static void prefetch_next(const marie_shm_writer_t *w, uint64_t n)
{
    const uint8_t *s = (const uint8_t *)slot_at(w->base, &w->g, w->slots[(n + 1) % w->g.nslots]);
    uint64_t len = ((const slot_hdr_t *)s)->size;
    len = DATA_OFF + (len < PREFETCH_MAX ? len : PREFETCH_MAX);
    bool w_ok = has_prefetchw();
    for (uint64_t off = 0; off < len; off += ALIGN)
        prefetch_for_write(s + off, w_ok);
}

void *marie_shm_begin(marie_shm_writer_t *w)
{
    if (!w->open) {             /* else a write begun and not committed: its slot again */
        w->open = ++w->seq;
        w->slot = claim_slot(w);
        atomic_thread_fence(memory_order_release);      /* odd before any byte of the new data */
    }
    return marie_shm_begun(w);
}

void *marie_shm_begun(const marie_shm_writer_t *w)
{
    return w->open ? (uint8_t *)slot_at(w->base, &w->g, w->slot) + DATA_OFF : NULL;
}

int marie_shm_commit(marie_shm_writer_t *w, size_t len, marie_shm_ref_t *ref)
{
    if (!w->open)
        return marie_fail(EINVAL);
    uint64_t n = w->open;
    w->open = 0;
    slot_hdr_t *s = slot_at(w->base, &w->g, w->slot);
    bool fits = len <= w->g.slot_size;
    s->size = fits ? len : 0;
    atomic_store_explicit(&s->cpu, sched_getcpu(), memory_order_relaxed);    /* a load from rseq's area */
    atomic_store_explicit(&s->seq, 2 * n, memory_order_release);
    atomic_store_explicit(index_at(w->base, &w->g, n), n << SLOT_BITS | w->slot, memory_order_release);
    atomic_store_explicit(&w->hdr->write_seq, n, memory_order_release);
    prefetch_next(w, n);
    if (!fits)
        return marie_fail(EMSGSIZE);
    if (!ref)
        return 0;
    memcpy(ref->segment, w->name, sizeof ref->segment);     /* both NUL-terminated, of one size */
    ref->seq = (int64_t)n;
    ref->size = (uint32_t)len;
    return 0;
}

int64_t marie_shm_writer_skipped(const marie_shm_writer_t *w) { return w->skipped; }

size_t marie_shm_slot_size(const marie_shm_writer_t *w) { return w->g.slot_size; }

int marie_shm_write_with(marie_shm_writer_t *w, size_t len, marie_shm_fill_t fill, void *user, marie_shm_ref_t *ref)
{
    if (len > w->g.slot_size)
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
    marie_shm_reader_t *r = calloc(1, sizeof(marie_shm_reader_t));
    if (r)
        r->last_cpu = -1;
    return r;
}

int marie_shm_reader_last_cpu(const marie_shm_reader_t *r) { return r->last_cpu; }

static void map_drop(reader_map_t *m)
{
    if (m->holds && m->entry >= 0) {
        atomic_store(&m->holds[m->entry].held, 0);
        atomic_store(&m->holds[m->entry].pid, 0);
    }
    if (m->holds)
        munmap(m->holds, HOLD_ALIGN);
    munmap((void *)m->base, m->len);
    *m = (reader_map_t){.entry = -1};
}

void marie_shm_reader_destroy(marie_shm_reader_t *r)
{
    if (!r)
        return;
    for (int i = 0; i < READER_MAPS; i++)
        if (r->maps[i].base)
            map_drop(&r->maps[i]);
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

/* Nothing in the header is trusted: the index, the hold table and every slot must lie inside
 * the file, the slots aligned as the writer lays them out (their seq is read atomically). The
 * fields are read once, into *g, and the copy is what is checked and used from then on. */
static bool layout_ok(const volatile shm_hdr_t *h, uint64_t size, geom_t *g)
{
    *g = (geom_t){h->slot_size, h->stride, h->nslots, h->nholds};
    if (h->magic != SHM_MAGIC || h->version != SHM_VERSION || g->nslots < 2 || g->nslots > 1024 ||
        g->nholds > HOLD_ALIGN / sizeof(hold_t) || g->slot_size == 0 || g->stride < DATA_OFF + g->slot_size ||
        g->stride % ALIGN != 0 || size < slots_off(g->nslots))
        return false;
    return g->stride <= (size - slots_off(g->nslots)) / nphys(g);
}

/* The segment's hold table, mapped writable (the rest stays read-only), or NULL: this reader
 * cannot hold (the file is not writable for it) and copies. */
static hold_t *map_holds(int fd, const geom_t *g)
{
    if (g->nholds == 0)
        return NULL;
    void *t = mmap(NULL, HOLD_ALIGN, PROT_READ | PROT_WRITE, MAP_SHARED, fd, (off_t)hold_off(g->nslots));
    return t == MAP_FAILED ? NULL : t;
}

/* The mapping of a segment, opened and checked the first time it is named. */
static reader_map_t *map_of(marie_shm_reader_t *r, const char *name)
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
    int fd = open(path, O_RDWR | O_CLOEXEC);
    if (fd < 0 && (errno == EACCES || errno == EROFS))
        fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return NULL;
    struct stat st;
    void *base = MAP_FAILED;
    if (fstat(fd, &st) == 0 && (size_t)st.st_size >= HDR_SIZE)
        base = mmap(NULL, (size_t)st.st_size, PROT_READ, MAP_SHARED, fd, 0);
    geom_t g;
    if (base != MAP_FAILED && !layout_ok(base, (uint64_t)st.st_size, &g)) {
        munmap(base, (size_t)st.st_size);
        base = MAP_FAILED;
    }
    hold_t *holds = base != MAP_FAILED ? map_holds(fd, &g) : NULL;
    close(fd);
    if (base == MAP_FAILED)
        return marie_fail_null(EBADMSG);
    reader_map_t *m = free_slot ? free_slot : oldest;
    if (m->base)
        map_drop(m);
    snprintf(m->name, sizeof m->name, "%s", name);
    m->base = base;
    m->len = (size_t)st.st_size;
    m->g = g;
    m->used = ++r->uses;
    m->holds = holds;
    m->entry = -1;
    return m;
}

/* The slot holding message seq: its place's own slot, as long as no hold moved it (a slot whose
 * sequence number says seq holds it, whatever the index says, so the index's line is read only
 * when a spare took the place), else by the index while it still names seq. NULL with errno
 * ESTALE (the index moved past it), `early` (not written yet) or EBADMSG (a slot past the ring). */
static slot_hdr_t *indexed(const reader_map_t *m, uint64_t seq, int early)
{
    const geom_t *g = &m->g;
    slot_hdr_t *own = slot_at(m->base, g, seq % g->nslots);
    if (atomic_load_explicit(&own->seq, memory_order_acquire) == 2 * seq)
        return own;
    uint64_t e = atomic_load_explicit(index_at(m->base, g, seq), memory_order_acquire);
    if (e >> SLOT_BITS != seq)
        return marie_fail_null(e >> SLOT_BITS > seq ? ESTALE : early);
    uint64_t k = e & ((1u << SLOT_BITS) - 1);
    if (k >= nphys(g))
        return marie_fail_null(EBADMSG);
    return slot_at(m->base, g, k);
}

/* The slot of ref, when it still holds that message (s1 = its sequence number). */
static slot_hdr_t *slot_in(reader_map_t *m, const marie_shm_ref_t *ref, uint64_t *s1)
{
    slot_hdr_t *s = indexed(m, (uint64_t)ref->seq, EBADMSG);
    if (!s)
        return NULL;
    uint64_t want = 2 * (uint64_t)ref->seq;
    *s1 = atomic_load_explicit(&s->seq, memory_order_acquire);
    if (*s1 != want)
        return marie_fail_null(*s1 > want ? ESTALE : EBADMSG);
    if (s->size > m->g.slot_size || s->size != ref->size)
        return marie_fail_null(EAGAIN);     /* a size being rewritten: the slot moved on */
    return s;
}

static slot_hdr_t *slot_of(marie_shm_reader_t *r, const marie_shm_ref_t *ref, uint64_t *s1)
{
    if (ref->seq <= 0)
        return marie_fail_null(EBADMSG);
    reader_map_t *m = map_of(r, ref->segment);
    return m ? slot_in(m, ref, s1) : NULL;
}

const void *marie_shm_peek(marie_shm_reader_t *r, const marie_shm_ref_t *ref)
{
    uint64_t s1;
    slot_hdr_t *s = slot_of(r, ref, &s1);
    return s ? (const uint8_t *)s + DATA_OFF : NULL;
}

/* The slot this reader holds ref in, or NULL: the index moves on while a slot is held. */
static const slot_hdr_t *held_slot(marie_shm_reader_t *r, const marie_shm_ref_t *ref)
{
    for (int i = 0; i < READER_MAPS; i++) {
        reader_map_t *m = &r->maps[i];
        if (!m->base || !m->holds || m->entry < 0 || strcmp(m->name, ref->segment) != 0)
            continue;
        uint64_t v = atomic_load(&m->holds[m->entry].held);
        if (v && v >> SLOT_BITS == (uint64_t)ref->seq && (v & ((1u << SLOT_BITS) - 1)) < nphys(&m->g))
            return slot_at(m->base, &m->g, v & ((1u << SLOT_BITS) - 1));
    }
    return NULL;
}

bool marie_shm_still_valid(marie_shm_reader_t *r, const marie_shm_ref_t *ref)
{
    atomic_thread_fence(memory_order_acquire);      /* every use of the bytes before this look */
    const slot_hdr_t *held = held_slot(r, ref);
    if (held)
        return atomic_load_explicit(&held->seq, memory_order_relaxed) == 2 * (uint64_t)ref->seq;
    uint64_t s1;
    return slot_of(r, ref, &s1) != NULL;
}

/* An entry of the hold table for this reader: a free one, or one whose reader is gone (SIGKILL:
 * its hold is let go with it). -1 with errno EBUSY when every entry is a live reader's. */
static int claim_entry(reader_map_t *m)
{
    int32_t me = (int32_t)getpid();
    for (int pass = 0; pass < 2; pass++)
        for (uint32_t i = 0; i < m->g.nholds; i++) {
            int32_t pid = atomic_load(&m->holds[i].pid);
            if (pass == 1 && pid > 0 && pid != me && kill(pid, 0) < 0 && errno == ESRCH &&
                atomic_compare_exchange_strong(&m->holds[i].pid, &pid, me)) {
                atomic_store(&m->holds[i].held, 0);
                return (int)i;
            }
            int32_t none = 0;
            if (pass == 0 && atomic_compare_exchange_strong(&m->holds[i].pid, &none, me))
                return (int)i;
        }
    return marie_fail(EBUSY);
}

const void *marie_shm_hold(marie_shm_reader_t *r, const marie_shm_ref_t *ref)
{
    if (ref->seq <= 0 || (uint64_t)ref->seq >= (UINT64_C(1) << (64 - SLOT_BITS)))
        return marie_fail_null(EBADMSG);
    reader_map_t *m = map_of(r, ref->segment);
    if (!m)
        return NULL;
    if (!m->holds || (m->entry >= 0 && atomic_load(&m->holds[m->entry].held)))
        return marie_fail_null(EBUSY);      /* copies, or holds another message already */
    if (m->entry < 0 && (m->entry = claim_entry(m)) < 0)
        return NULL;
    uint64_t s1;
    slot_hdr_t *s = slot_in(m, ref, &s1);
    if (!s)
        return NULL;
    uint64_t k = (uint64_t)((const uint8_t *)s - (m->base + slots_off(m->g.nslots))) / m->g.stride;
    /* The hold first, then the slot looked at again (both seq_cst): the writer marks a slot odd
     * before it looks at the holds, so one of the two sees the other. */
    atomic_store(&m->holds[m->entry].held, (uint64_t)ref->seq << SLOT_BITS | k);
    if (atomic_load(&s->seq) != s1) {
        atomic_store(&m->holds[m->entry].held, 0);
        return marie_fail_null(ESTALE);
    }
    return (const uint8_t *)s + DATA_OFF;
}

void marie_shm_release(marie_shm_reader_t *r, const marie_shm_ref_t *ref)
{
    for (int i = 0; i < READER_MAPS; i++) {
        reader_map_t *m = &r->maps[i];
        if (m->base && m->holds && m->entry >= 0 && strcmp(m->name, ref->segment) == 0)
            atomic_store_explicit(&m->holds[m->entry].held, 0, memory_order_release);
    }
}

int64_t marie_shm_newest(marie_shm_reader_t *r, const char *segment)
{
    const reader_map_t *m = map_of(r, segment);
    if (!m)
        return -1;
    return (int64_t)atomic_load_explicit(&((const shm_hdr_t *)m->base)->write_seq, memory_order_acquire);
}

bool marie_shm_ready(marie_shm_reader_t *r, const char *segment, int64_t seq)
{
    const reader_map_t *m = seq > 0 ? map_of(r, segment) : NULL;
    if (!m)
        return false;
    const slot_hdr_t *own = slot_at(m->base, &m->g, (uint64_t)seq % m->g.nslots);
    return atomic_load_explicit(&own->seq, memory_order_acquire) == 2 * (uint64_t)seq ||
           atomic_load_explicit(&((const shm_hdr_t *)m->base)->write_seq, memory_order_acquire) >= (uint64_t)seq;
}

int marie_shm_ref_at(marie_shm_reader_t *r, const char *segment, int64_t seq, marie_shm_ref_t *ref)
{
    if (seq <= 0)
        return marie_fail(EBADMSG);
    const reader_map_t *m = map_of(r, segment);
    if (!m)
        return -1;
    slot_hdr_t *s = indexed(m, (uint64_t)seq, EAGAIN);
    if (!s)
        return -1;
    uint64_t want = 2 * (uint64_t)seq, s1 = atomic_load_explicit(&s->seq, memory_order_acquire);
    if (s1 != want)
        return marie_fail(s1 > want ? ESTALE : EAGAIN);
    uint64_t size = s->size;
    if (size > m->g.slot_size)
        return marie_fail(EAGAIN);
    r->last_cpu = atomic_load_explicit(&s->cpu, memory_order_relaxed);
    memcpy(ref->segment, m->name, sizeof ref->segment);     /* segment's own name, NUL-terminated */
    ref->seq = seq;
    ref->size = (uint32_t)size;
    return 0;
}

int64_t marie_shm_read(marie_shm_reader_t *r, const marie_shm_ref_t *ref, void *buf, size_t cap)
{
    uint64_t s1;
    slot_hdr_t *s = slot_of(r, ref, &s1);
    if (!s)
        return -1;
    uint64_t size = ref->size;      /* the slot's, as slot_of found it: read there again, it could have grown */
    if (size > cap)
        return marie_fail(EMSGSIZE);
    memcpy(buf, (const uint8_t *)s + DATA_OFF, size);
    atomic_thread_fence(memory_order_acquire);      /* the copy before the second look */
    if (atomic_load_explicit(&s->seq, memory_order_relaxed) != s1)
        return marie_fail(EAGAIN);
    return (int64_t)size;
}
