/* sharedmap: a durable key-value store of typed LCM payloads, served over LCM requests. */
#ifndef MARIE_CA_SHAREDMAP_H
#define MARIE_CA_SHAREDMAP_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

#include "ca/ca.h"
#include "lcmtypes/marie_sharedmap_request_t.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct sharedmap sharedmap_t;

/* Limits on what a request may store. */
#define SHAREDMAP_MAX_KEY   256
#define SHAREDMAP_MAX_TYPE  128
#define SHAREDMAP_MAX_VALUE (1 << 20)

typedef struct {
    const char *key;
    const char *type;           /* LCM type name given by the writer */
    const void *data;           /* the payload, fingerprint first */
    size_t len;
    int64_t version;            /* map version when the key last changed */
    int64_t set_utime;
} sharedmap_value_t;

typedef struct {
    int64_t requests, bad_requests, sets, gets, deletes, lists;
    int64_t fsyncs, compactions, io_errors;
    int64_t records_loaded, tail_bytes_dropped;   /* at open */
    int64_t records_skipped, bytes_skipped;       /* at open: lost to damage */
    int64_t snapshots;
} sharedmap_stats_t;

/* What replaying a log found. A torn tail (the write being made when the process died,
 * never acknowledged) is the only damage a crash causes; anything else is corruption. The
 * log is damaged when sharedmap_log_damaged() says so. */
#define SHAREDMAP_MAX_RANGES 16
typedef struct {
    int format;                 /* 1 ("MARIESM1", read and rewritten) or 2 */
    int64_t records;            /* intact records replayed */
    int64_t records_skipped;    /* records lost to damage: exact between intact records; for
                                 * damage that runs to the end of the file, a lower bound */
    int64_t bytes_skipped;      /* in damaged stretches */
    int64_t duplicates;         /* intact records whose sequence number came before: ignored */
    int64_t reordered;          /* intact records found after a later one: replayed in order */
    int64_t torn_bytes;         /* a torn tail: the write a crash cut short, or (see
                                 * acked_lost) an acknowledged record cut off */
    int64_t acked_lost;         /* acknowledged records missing at the end of the log (known
                                 * from the SharedMap's note of its last acknowledgement) */
    int64_t end;                /* offset after the last intact record in the file */
    int64_t last_seq;           /* the highest sequence number replayed */
    size_t nranges;             /* damaged stretches; the first SHAREDMAP_MAX_RANGES listed */
    struct { int64_t off, len, records; } ranges[SHAREDMAP_MAX_RANGES];
} sharedmap_replay_t;

/* Open the store persisted in the append-only log `path` (NULL: memory only), replaying it.
 * PATH.lock is held locked while open: a second SharedMap on the same log gets EBUSY.
 * A torn last record is cut off. A damaged log (a record that fails its checksum, anything
 * but a torn tail) keeps every intact record: the file is kept as PATH.corrupt-TIMESTAMP,
 * a fresh log of the intact records replaces it, and the damage is reported (sink event
 * sharedmap_log_damaged, counter log_records_skipped, sharedmap_load_report()). With
 * SHAREDMAP_STRICT a damaged log is left untouched and open fails with EBADMSG.
 * Replies go to sink->publish/lcm, counters to sink->note. NULL with errno (EINVAL: not
 * a SharedMap log, EBUSY, EBADMSG, or the system call's). */
#define SHAREDMAP_STRICT 1u
sharedmap_t *sharedmap_open(const char *path, const ca_sink_t *sink);
sharedmap_t *sharedmap_open_flags(const char *path, unsigned flags, const ca_sink_t *sink);
void sharedmap_close(sharedmap_t *sm);          /* NULL is a no-op */
/* What the scan at open found, and where a damaged log was kept (NULL: nowhere). */
const sharedmap_replay_t *sharedmap_load_report(const sharedmap_t *sm);
const char *sharedmap_kept_aside(const sharedmap_t *sm);

/* Replay a log image (the bytes of a state file) into the map, as sharedmap_open() does,
 * describing what it found in *rep (may be NULL). 0, or -1 with errno EINVAL when the magic is
 * missing.
 * Used by open and by the fuzz target; a map opened from a path keeps logging to its own
 * file. */
int sharedmap_replay(sharedmap_t *sm, const void *image, size_t len, sharedmap_replay_t *rep);

/* Store operations. set/delete return only once the change is on disk (fdatasync).
 * 0, or -1 with errno: set: EINVAL (empty/oversized key, short payload), EBADMSG (payload is
 * not `type`, when `type` is a registered marie type), EFBIG, EIO; delete: ENOENT, EIO. */
int sharedmap_set(sharedmap_t *sm, const char *key, const char *type, const void *data,
                  size_t len, int64_t now);
int sharedmap_delete(sharedmap_t *sm, const char *key);
/* The value of `key`; pointers stay valid until the next change. 0, or -1 with errno ENOENT. */
int sharedmap_get(const sharedmap_t *sm, const char *key, sharedmap_value_t *out);
size_t sharedmap_size(const sharedmap_t *sm);
/* The i-th entry in key order. */
int sharedmap_entry(const sharedmap_t *sm, size_t i, sharedmap_value_t *out);
int64_t sharedmap_version(const sharedmap_t *sm);

/* Rewrite the log holding only live entries (temporary file, fsync, rename, fsync of the
 * directory). Done automatically when the log holds more than 2 x keys + min_records
 * records (min_records defaults to SHAREDMAP_COMPACT_MIN). */
int sharedmap_compact(sharedmap_t *sm);
#define SHAREDMAP_COMPACT_MIN 1024
void sharedmap_set_compaction(sharedmap_t *sm, int64_t min_records);

/* Request protocol: decode, apply, and answer on the request's reply channel. Undecodable
 * bytes are counted and dropped (errno EBADMSG); invalid requests are answered BAD_REQUEST or
 * BAD_TYPE. A change marks the snapshot due. */
int sharedmap_handle_request(sharedmap_t *sm, const marie_sharedmap_request_t *req, int64_t now);
int sharedmap_handle_request_raw(sharedmap_t *sm, const void *buf, size_t len, int64_t now);

/* Snapshots: published on `channel` (NULL: none) after a change, at most once every
 * min_interval_us; sharedmap_tick() sends one that was held back. */
void sharedmap_set_snapshot(sharedmap_t *sm, const char *channel, const char *source,
                            int64_t min_interval_us);
int sharedmap_publish_snapshot(sharedmap_t *sm, int64_t now);
void sharedmap_tick(sharedmap_t *sm, int64_t now);

const sharedmap_stats_t *sharedmap_stats(const sharedmap_t *sm);

/* Serve requests arriving on `request_channel` over `lcm`. 0, or -1 with errno. */
int sharedmap_attach(sharedmap_t *sm, lcm_t *lcm, const char *request_channel);
void sharedmap_detach(sharedmap_t *sm);

#ifdef __cplusplus
}
#endif
#endif
