/* shm: same-host shared-memory rings for large messages; a small notice on LCM names each one. */
#ifndef MARIE_SHM_H
#define MARIE_SHM_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* One writer per channel owns a segment /dev/shm/marie-shm.<channel>.<pid>: a ring of
 * `nslots` messages of `slot_size` bytes, each slot guarded by a sequence number (a seqlock).
 * Readers map it read-only, so a reader that crashes or stalls can neither block nor corrupt the
 * writer or the other readers: a slot overwritten while a reader copies it is detected and
 * counted, never delivered torn. A few readers at once (4) may also hold the slot they read in
 * place: their page of the segment, a table of holds, is the only one they map writable; the
 * writer skips held slots (it has as many spare ones) and never waits. The memory is fixed at creation; the writer unlinks its segment when it
 * is destroyed, and a writer's creation removes segments left by dead processes. See
 * docs/transport.md. */

#define MARIE_SHM_NAME_MAX 128

typedef struct marie_shm_writer marie_shm_writer_t;
typedef struct marie_shm_reader marie_shm_reader_t;

/* Where one message is: what the notice on LCM carries. */
typedef struct {
    char segment[MARIE_SHM_NAME_MAX];   /* file name under /dev/shm */
    int64_t seq;                        /* 1, 2, ... per segment */
    uint32_t size;                      /* bytes */
} marie_shm_ref_t;

/* NULL with errno (EINVAL: bad sizes or channel; what shm_open/ftruncate/mmap say). */
marie_shm_writer_t *marie_shm_writer_create(const char *channel, size_t slot_size, int nslots);
void marie_shm_writer_destroy(marie_shm_writer_t *w);      /* NULL is a no-op; unlinks */
/* Copy one message into the next slot. 0, or -1 with errno EMSGSIZE when it does not fit a slot. */
int marie_shm_write(marie_shm_writer_t *w, const void *data, size_t len, marie_shm_ref_t *ref);
/* Without the copy: `fill(dst, len, user)` writes the len bytes of the message straight into the
 * slot (an encoder) and returns 0, or -1 to abandon it (the slot is left empty, no ref made, and
 * this fails with EINVAL). dst is only valid during the call. 0, or -1 with errno EMSGSIZE or EINVAL. */
typedef int (*marie_shm_fill_t)(void *dst, size_t len, void *user);
int marie_shm_write_with(marie_shm_writer_t *w, size_t len, marie_shm_fill_t fill, void *user, marie_shm_ref_t *ref);
int marie_shm_fill_copy(void *dst, size_t len, void *src);     /* the fill of marie_shm_write: a memcpy */
/* In two steps, for a producer that makes the message in place (a loan): begin gives the next
 * slot's bytes (slot_size of them), marked as being written, so a reader of what the slot held
 * sees it gone; commit publishes its first len bytes. A begin not committed is taken up by the
 * next begin or write. Commit: 0, or -1 with errno EMSGSIZE (len past the slot: the slot is left
 * empty, no ref) or EINVAL (nothing begun). */
void *marie_shm_begin(marie_shm_writer_t *w);
void *marie_shm_begun(const marie_shm_writer_t *w);     /* what begin gave, or NULL: nothing begun */
int marie_shm_commit(marie_shm_writer_t *w, size_t len, marie_shm_ref_t *ref);
size_t marie_shm_slot_size(const marie_shm_writer_t *w);
int64_t marie_shm_writer_skipped(const marie_shm_writer_t *w);   /* slots passed over: held */
const char *marie_shm_writer_segment(const marie_shm_writer_t *w);

marie_shm_reader_t *marie_shm_reader_create(void);
void marie_shm_reader_destroy(marie_shm_reader_t *r);      /* NULL is a no-op */
/* Copy the message `ref` names into buf (cap bytes). Its size, or -1 with errno ENOENT (no such
 * segment: another host's writer, or gone), ESTALE (already overwritten: the reader was too
 * slow), EAGAIN (overwritten while copying), EMSGSIZE (cap too small), EBADMSG (a ref or segment
 * that makes no sense). Opens and maps the segment the first time it is named. */
int64_t marie_shm_read(marie_shm_reader_t *r, const marie_shm_ref_t *ref, void *buf, size_t cap);

/* In place, without the copy: the message's bytes inside the mapping (valid until the reader
 * is destroyed), or NULL with errno as marie_shm_read() says. They may be overwritten at any
 * moment: use them (decode them) first, then ask marie_shm_still_valid(), and drop whatever
 * was made of them when it says no. */
const void *marie_shm_peek(marie_shm_reader_t *r, const marie_shm_ref_t *ref);
bool marie_shm_still_valid(marie_shm_reader_t *r, const marie_shm_ref_t *ref);

/* In place and held: the message's bytes inside the mapping, which the writer does not write
 * over until marie_shm_release() (it skips the slot meanwhile: a reader stopped while it holds
 * costs the writer one slot, and one killed gives it back when another reader needs its entry).
 * One message held at a time per reader and segment. NULL with errno as marie_shm_peek(), or
 * EBUSY: this reader holds one already, every entry is a live reader's, or it may not write the
 * segment; then peek or copy. */
const void *marie_shm_hold(marie_shm_reader_t *r, const marie_shm_ref_t *ref);
/* The providers hold messages this large; a smaller one costs less to copy than the hold's
 * stores on a line the writer reads. */
#define MARIE_SHM_HOLD_MIN (4 * 1024)
void marie_shm_release(marie_shm_reader_t *r, const marie_shm_ref_t *ref);

/* Following a writer without notices (the same-host fast path): the newest complete message of
 * a segment (0: none yet), or -1 with errno as marie_shm_read() says; and the ref of message
 * seq, its size read from its slot: 0, or -1 with errno ESTALE (overwritten), EAGAIN (not
 * complete, or being rewritten), or what opening the segment said. */
int64_t marie_shm_newest(marie_shm_reader_t *r, const char *segment);
int marie_shm_ref_at(marie_shm_reader_t *r, const char *segment, int64_t seq, marie_shm_ref_t *ref);
/* The CPU the writer committed the message of the last marie_shm_ref_at() that found one on, or
 * -1 (none yet). A reader that is on that CPU shares it with its writer (marie_bus_waking()). */
int marie_shm_reader_last_cpu(const marie_shm_reader_t *r);
/* Whether message seq is complete (or overwritten already). It looks first at the slot the
 * message goes to when no hold moved it, which is the line its reader reads next anyway, and
 * only then at the header's newest: a reader waiting for the next message takes one line from
 * the writer's CPU per message instead of two. */
bool marie_shm_ready(marie_shm_reader_t *r, const char *segment, int64_t seq);


#ifdef __cplusplus
}
#endif
#endif
