/* sharedmap_log: the SharedMap's on-disk record format, and the scan that replays every intact
 * record of a log, damaged or not (private to libca; the fuzz target and tests use it too). */
#ifndef MARIE_CA_SHAREDMAP_LOG_H
#define MARIE_CA_SHAREDMAP_LOG_H

#include <stddef.h>
#include <stdint.h>

#include "ca/sharedmap.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The magic of a log written today ("MARIESM2"); "MARIESM1" logs are still read. */
#define SHAREDMAP_LOG_MAGIC_LEN 8
extern const char sharedmap_log_magic[SHAREDMAP_LOG_MAGIC_LEN];

#define SHAREDMAP_LOG_SET 1
#define SHAREDMAP_LOG_DEL 2
#define SHAREDMAP_LOG_VERSION 3     /* no key: the map's version (a compacted log whose last change was a delete) */
#define SHAREDMAP_LOG_HEAD 24       /* bytes before a record's body */

/* One record. key and type are NUL-terminated; data is len bytes. */
typedef struct {
    int op;
    int64_t seq;                    /* 1, 2, ... within one file: gaps count lost records */
    int64_t version, set_utime;
    const char *key, *type;
    const void *data;
    size_t len;
} sharedmap_log_rec_t;

/* Bytes that record takes on disk. */
size_t sharedmap_log_record_size(size_t klen, size_t tlen, size_t dlen);
/* Encodes r at out (sharedmap_log_record_size() bytes); returns the size. */
size_t sharedmap_log_encode(uint8_t *out, const sharedmap_log_rec_t *r);

/* Called for each intact record, in file order; a negative return stops the scan with it. */
typedef int (*sharedmap_log_fn)(void *user, const sharedmap_log_rec_t *r);

/* Scans a log image (magic included), calling fn for every intact record, in sequence order,
 * each sequence number once, and filling rep (zeroed first). Damaged stretches are skipped: the
 * scan resynchronises on the next record marker whose header and body hold, whatever its
 * sequence number. 0, or -1 with errno EINVAL when no known magic starts the image, ENOMEM, or fn's
 * negative return. */
int sharedmap_log_scan(const void *image, size_t len, sharedmap_log_fn fn, void *user,
                       sharedmap_replay_t *rep);

/* The same, for a log whose writer noted that it acknowledged the records up to sequence
 * number `acked` (0: unknown): those the log does not hold at its end are lost (acked_lost),
 * a torn tail among them, and count as damage. */
int sharedmap_log_scan_acked(const void *image, size_t len, int64_t acked, sharedmap_log_fn fn, void *user,
                             sharedmap_replay_t *rep);

/* Whether the scan found damage (a damaged stretch, records lost, a duplicate, records out of
 * sequence): the log is then kept aside and rewritten. */
int sharedmap_log_damaged(const sharedmap_replay_t *rep);
/* "N records (B bytes) at offsets O1+L1, O2+L2, ... lost; D duplicate records ignored; R
 * records out of sequence, replayed in order" (the parts that apply), into buf. */
void sharedmap_log_describe(const sharedmap_replay_t *rep, char *buf, size_t cap);

#ifdef __cplusplus
}
#endif
#endif
