/* sharedmap_log: SharedMap log records (marker, sequence number, header and body checksums)
 * and the scan that keeps every intact record after damage. */
#include "ca/sharedmap_log.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/buf.h"
#include "core/err.h"

/* Layout (all integers big-endian):
 *   file   := "MARIESM2" record*
 *   record := u32 marker, u32 body_len, u64 seq, u32 crc32(body), u32 crc32(the 20 bytes before), body
 *   body   := u8 op (1 set, 2 delete, 3 version only, key empty), i64 version, i64 set_utime,
 *             u16 key_len, key, u16 type_len, type, u32 data_len, data
 * The marker lets a reader find the next record after damage, the header checksum makes a
 * false marker in a value (or a damaged length) fail cheaply, and the sequence number counts
 * the records a damaged stretch held.
 * Version 1 ("MARIESM1"): record := u32 body_len, u32 crc32(body), body; it cannot be
 * resynchronised, so its scan stops at the first bad record. */
const char sharedmap_log_magic[SHAREDMAP_LOG_MAGIC_LEN] = { 'M', 'A', 'R', 'I', 'E', 'S', 'M', '2' };
static const char MAGIC_V1[SHAREDMAP_LOG_MAGIC_LEN] = { 'M', 'A', 'R', 'I', 'E', 'S', 'M', '1' };
static const uint8_t MARKER[4] = { 0xA7, 'S', 'M', 'R' };
#define V1_HEAD 8
#define BODY_MIN (1 + 8 + 8 + 2 + 2 + 4)
#define BODY_MAX (BODY_MIN + SHAREDMAP_MAX_KEY + SHAREDMAP_MAX_TYPE + SHAREDMAP_MAX_VALUE)

static void put_u16(uint8_t *p, uint16_t v) { p[0] = (uint8_t)(v >> 8); p[1] = (uint8_t)v; }
static void put_u32(uint8_t *p, uint32_t v) { for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (24 - 8 * i)); }
static void put_i64(uint8_t *p, int64_t v) { for (int i = 0; i < 8; i++) p[i] = (uint8_t)((uint64_t)v >> (56 - 8 * i)); }
static uint16_t get_u16(const uint8_t *p) { return (uint16_t)(p[0] << 8 | p[1]); }
static uint32_t get_u32(const uint8_t *p) { return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]; }
static int64_t get_i64(const uint8_t *p) { uint64_t v = 0; for (int i = 0; i < 8; i++) v = v << 8 | p[i]; return (int64_t)v; }

size_t sharedmap_log_record_size(size_t klen, size_t tlen, size_t dlen)
{
    return SHAREDMAP_LOG_HEAD + BODY_MIN + klen + tlen + dlen;
}

size_t sharedmap_log_encode(uint8_t *out, const sharedmap_log_rec_t *r)
{
    size_t klen = strlen(r->key), tlen = r->type ? strlen(r->type) : 0;
    uint8_t *b = out + SHAREDMAP_LOG_HEAD, *p = b;
    *p++ = (uint8_t)r->op;
    put_i64(p, r->version); p += 8;
    put_i64(p, r->set_utime); p += 8;
    put_u16(p, (uint16_t)klen); p += 2;
    memcpy(p, r->key, klen); p += klen;
    put_u16(p, (uint16_t)tlen); p += 2;
    if (tlen)
        memcpy(p, r->type, tlen);
    p += tlen;
    put_u32(p, (uint32_t)r->len); p += 4;
    if (r->len)
        memcpy(p, r->data, r->len);
    p += r->len;
    size_t body = (size_t)(p - b);
    memcpy(out, MARKER, 4);
    put_u32(out + 4, (uint32_t)body);
    put_i64(out + 8, r->seq);
    put_u32(out + 16, ca_crc32(0, b, body));
    put_u32(out + 20, ca_crc32(0, out, 20));
    return SHAREDMAP_LOG_HEAD + body;
}

/* Decodes a body whose checksum held; -1 with errno EBADMSG when its fields do not fit. */
static int decode_body(const uint8_t *b, size_t blen, sharedmap_log_rec_t *r,
                       char key[SHAREDMAP_MAX_KEY + 1], char type[SHAREDMAP_MAX_TYPE + 1])
{
    const uint8_t *end = b + blen, *p = b;
    if (blen < BODY_MIN)
        return marie_fail(EBADMSG);
    r->op = *p++;
    r->version = get_i64(p); p += 8;
    r->set_utime = get_i64(p); p += 8;
    size_t klen = get_u16(p); p += 2;
    if ((klen == 0) != (r->op == SHAREDMAP_LOG_VERSION) || klen > SHAREDMAP_MAX_KEY ||
        (size_t)(end - p) < klen + 2)
        return marie_fail(EBADMSG);
    memcpy(key, p, klen); key[klen] = 0; p += klen;
    size_t tlen = get_u16(p); p += 2;
    if (tlen > SHAREDMAP_MAX_TYPE || (size_t)(end - p) < tlen + 4)
        return marie_fail(EBADMSG);
    memcpy(type, p, tlen); type[tlen] = 0; p += tlen;
    size_t dlen = get_u32(p); p += 4;
    if (dlen != (size_t)(end - p) || strlen(key) != klen ||
        r->op < SHAREDMAP_LOG_SET || r->op > SHAREDMAP_LOG_VERSION)
        return marie_fail(EBADMSG);
    r->key = key;
    r->type = type;
    r->data = p;
    r->len = dlen;
    return 0;
}

/* A damaged stretch being skipped. */
typedef struct {
    int open;
    size_t off;
    int64_t max_seq;            /* highest sequence number of a whole header inside it */
} stretch_t;

/* An intact record, where it lies in the file. */
typedef struct {
    int64_t seq;
    size_t off, size;
} found_t;

typedef struct {
    found_t *v;
    size_t n, cap;
    int64_t max_seq;            /* of the intact records */
    int tail;                   /* the last stretch runs to the end of the file ... */
    int64_t tail_max_seq;       /* ... holding whole headers up to this sequence number */
} found_list_t;

static int found_add(found_list_t *f, int64_t seq, size_t off, size_t size)
{
    if (f->n == f->cap) {
        size_t cap = f->cap ? 2 * f->cap : 256;
        found_t *v = realloc(f->v, cap * sizeof *v);
        if (!v)
            return marie_fail(ENOMEM);
        f->v = v;
        f->cap = cap;
    }
    f->v[f->n++] = (found_t){ seq, off, size };
    if (seq > f->max_seq)
        f->max_seq = seq;
    return 0;
}

static void range_add(sharedmap_replay_t *rep, size_t off, size_t len)
{
    if (rep->nranges < SHAREDMAP_MAX_RANGES)
        rep->ranges[rep->nranges] = (typeof(rep->ranges[0])){ (int64_t)off, (int64_t)len, 0 };
    rep->nranges++;
    rep->bytes_skipped += (int64_t)len;
}

static void stretch_open(stretch_t *s, size_t off)
{
    if (!s->open)
        *s = (stretch_t){ .open = 1, .off = off };
}

static void stretch_close(sharedmap_replay_t *rep, stretch_t *s, size_t end)
{
    if (s->open)
        range_add(rep, s->off, end - s->off);
    s->open = 0;
}

/* Records missing between sequence numbers last and seq; a hostile file's numbers must
 * neither overflow nor make the count absurd. */
static int64_t seq_gap(int64_t last, int64_t seq)
{
    if (seq <= last)
        return 0;
    uint64_t gap = (uint64_t)seq - (uint64_t)last - 1;
    return gap > UINT32_MAX ? UINT32_MAX : (int64_t)gap;
}

static int header_ok(const uint8_t *h)
{
    return memcmp(h, MARKER, 4) == 0 && ca_crc32(0, h, 20) == get_u32(h + 20);
}

/* Whether the record at off (whole header, body inside the image) is intact. */
static int record_ok(const uint8_t *buf, size_t off, size_t blen, int64_t seq)
{
    char key[SHAREDMAP_MAX_KEY + 1], type[SHAREDMAP_MAX_TYPE + 1];
    sharedmap_log_rec_t r;
    const uint8_t *b = buf + off + SHAREDMAP_LOG_HEAD;
    return seq > 0 && ca_crc32(0, b, blen) == get_u32(buf + off + 16) && decode_body(b, blen, &r, key, type) == 0;
}

/* Pass 1, in file order: every intact record wherever it lies (after a duplicate, inserted
 * bytes or a swap as after a damaged one), the damaged stretches between them, and a torn
 * tail: a header cut short, or a whole header, newer than every intact record, whose body runs
 * past the end (the write a crash cut short). */
static int find_records(const uint8_t *buf, size_t len, found_list_t *f, sharedmap_replay_t *rep)
{
    size_t off = SHAREDMAP_LOG_MAGIC_LEN;
    stretch_t s = { 0 };
    rep->end = (int64_t)off;
    while (off < len) {
        size_t left = len - off;
        if (left < SHAREDMAP_LOG_HEAD || !header_ok(buf + off)) {
            if (left < SHAREDMAP_LOG_HEAD && !s.open && memcmp(buf + off, MARKER, left < 4 ? left : 4) == 0) {
                rep->torn_bytes = (int64_t)left;
                return 0;
            }
            stretch_open(&s, off);
            const uint8_t *m = memmem(buf + off + 1, left - 1, MARKER, sizeof MARKER);
            off = m ? (size_t)(m - buf) : len;
            continue;
        }
        size_t blen = get_u32(buf + off + 4);
        int64_t seq = get_i64(buf + off + 8);
        if (blen > left - SHAREDMAP_LOG_HEAD && blen <= BODY_MAX && seq > f->max_seq && seq > s.max_seq) {
            stretch_close(rep, &s, off);
            rep->torn_bytes = (int64_t)left;
            return 0;
        }
        if (blen > left - SHAREDMAP_LOG_HEAD || !record_ok(buf, off, blen, seq)) {
            stretch_open(&s, off);
            if (seq > s.max_seq)
                s.max_seq = seq;        /* a whole header: its record is among the lost */
            off++;
            continue;
        }
        stretch_close(rep, &s, off);
        if (found_add(f, seq, off, SHAREDMAP_LOG_HEAD + blen) < 0)
            return marie_fail(ENOMEM);
        off += SHAREDMAP_LOG_HEAD + blen;
        rep->end = (int64_t)off;
    }
    if (s.open) {
        f->tail = 1;
        f->tail_max_seq = s.max_seq;
        stretch_close(rep, &s, len);
    }
    return 0;
}

static int by_seq(const void *a, const void *b)
{
    const found_t *x = a, *y = b;
    return x->seq != y->seq ? (x->seq < y->seq ? -1 : 1) : (x->off < y->off ? -1 : x->off > y->off);
}

/* The records numbered between prev and next are lost: to the listed stretch where they were
 * in the file (it starts where prev ends, or lies before next), or a stretch of no bytes
 * there (whole records cut out, or a number missing from records out of order). */
static void lost_between(sharedmap_replay_t *rep, size_t prev_end, const found_t *next, int64_t n)
{
    rep->records_skipped += n;
    size_t listed = rep->nranges < SHAREDMAP_MAX_RANGES ? rep->nranges : SHAREDMAP_MAX_RANGES;
    for (size_t i = 0; i < listed; i++) {
        size_t off = (size_t)rep->ranges[i].off;
        if (off == prev_end || (off > prev_end && (!next || (next->off > prev_end && off <= next->off)))) {
            rep->ranges[i].records += n;
            return;
        }
    }
    range_add(rep, prev_end, 0);
    if (rep->nranges <= SHAREDMAP_MAX_RANGES)
        rep->ranges[rep->nranges - 1].records = n;
}

static int by_offset(const void *a, const void *b)
{
    const typeof(((sharedmap_replay_t *)0)->ranges[0]) *x = a, *y = b;
    return x->off != y->off ? (x->off < y->off ? -1 : 1) : (x->len > y->len) - (x->len < y->len);
}

/* Records lost after the last intact one: damage up to the end holds at least one, more if
 * its headers say so; and every acknowledged record the log no longer holds (rep->acked_lost,
 * from the writer's note) is lost, a torn tail included: it then counts as damage. */
static void lost_at_end(sharedmap_replay_t *rep, const found_list_t *f, size_t prev_end)
{
    int64_t n = f->tail ? seq_gap(rep->last_seq, f->tail_max_seq) + 1 : 0;
    if (rep->acked_lost > n)
        n = rep->acked_lost;
    if (rep->acked_lost && rep->torn_bytes) {
        range_add(rep, prev_end, (size_t)rep->torn_bytes);
        rep->torn_bytes = 0;
    }
    if (n)
        lost_between(rep, prev_end, NULL, n);
}

/* Pass 2: the intact records in sequence order, each number once; the numbers missing are
 * the records lost. */
static int replay_found(const uint8_t *buf, found_list_t *f, sharedmap_log_fn fn, void *user,
                        sharedmap_replay_t *rep)
{
    char key[SHAREDMAP_MAX_KEY + 1], type[SHAREDMAP_MAX_TYPE + 1];
    if (f->n)
        qsort(f->v, f->n, sizeof *f->v, by_seq);
    int64_t prev = 0;
    size_t prev_end = SHAREDMAP_LOG_MAGIC_LEN, prev_off = 0;
    for (size_t i = 0; i < f->n; i++) {
        const found_t *x = &f->v[i];
        if (x->seq == prev) {
            rep->duplicates++;
            continue;
        }
        if (seq_gap(prev, x->seq))
            lost_between(rep, prev_end, x, seq_gap(prev, x->seq));
        if (x->off < prev_off)
            rep->reordered++;
        sharedmap_log_rec_t r = { .seq = x->seq };
        decode_body(buf + x->off + SHAREDMAP_LOG_HEAD, x->size - SHAREDMAP_LOG_HEAD, &r, key, type);
        int rc = fn(user, &r);
        if (rc < 0)
            return rc;
        rep->records++;
        prev = x->seq;
        prev_off = x->off;
        prev_end = x->off + x->size;
    }
    rep->last_seq = prev;
    lost_at_end(rep, f, prev_end);
    size_t listed = rep->nranges < SHAREDMAP_MAX_RANGES ? rep->nranges : SHAREDMAP_MAX_RANGES;
    qsort(rep->ranges, listed, sizeof rep->ranges[0], by_offset);
    return 0;
}

static int scan_v2(const uint8_t *buf, size_t len, int64_t acked, sharedmap_log_fn fn, void *user,
                   sharedmap_replay_t *rep)
{
    found_list_t f = { 0 };
    int rc = find_records(buf, len, &f, rep);
    rep->acked_lost = seq_gap(f.max_seq, acked + 1);
    if (rc == 0)
        rc = replay_found(buf, &f, fn, user, rep);
    free(f.v);
    return rc;
}

/* Version 1 has no markers: the scan stops at the first bad record. */
static int scan_v1(const uint8_t *buf, size_t len, sharedmap_log_fn fn, void *user,
                   sharedmap_replay_t *rep)
{
    char key[SHAREDMAP_MAX_KEY + 1], type[SHAREDMAP_MAX_TYPE + 1];
    size_t off = SHAREDMAP_LOG_MAGIC_LEN;
    int64_t seq = 0;
    while (off < len) {
        size_t left = len - off;
        uint32_t blen = left >= V1_HEAD ? get_u32(buf + off) : 0;
        if (left < V1_HEAD || (blen > left - V1_HEAD && blen <= BODY_MAX)) {
            rep->torn_bytes = (int64_t)left;
            break;
        }
        sharedmap_log_rec_t r = { .seq = ++seq };
        const uint8_t *b = buf + off + V1_HEAD;
        if (blen > left - V1_HEAD || ca_crc32(0, b, blen) != get_u32(buf + off + 4) ||
            decode_body(b, blen, &r, key, type) < 0) {
            range_add(rep, off, len - off);
            rep->ranges[0].records = 1;
            rep->records_skipped = 1;
            break;
        }
        int rc = fn(user, &r);
        if (rc < 0)
            return rc;
        rep->records++;
        off += V1_HEAD + blen;
    }
    rep->end = (int64_t)off;
    return 0;
}

int sharedmap_log_scan(const void *image, size_t len, sharedmap_log_fn fn, void *user,
                       sharedmap_replay_t *rep)
{
    return sharedmap_log_scan_acked(image, len, 0, fn, user, rep);
}

int sharedmap_log_scan_acked(const void *image, size_t len, int64_t acked, sharedmap_log_fn fn, void *user,
                             sharedmap_replay_t *rep)
{
    memset(rep, 0, sizeof *rep);
    if (len < SHAREDMAP_LOG_MAGIC_LEN)
        return marie_fail(EINVAL);
    if (memcmp(image, sharedmap_log_magic, SHAREDMAP_LOG_MAGIC_LEN) == 0) {
        rep->format = 2;
        return scan_v2(image, len, acked, fn, user, rep);
    }
    if (memcmp(image, MAGIC_V1, SHAREDMAP_LOG_MAGIC_LEN) == 0) {
        rep->format = 1;
        return scan_v1(image, len, fn, user, rep);
    }
    return marie_fail(EINVAL);
}

int sharedmap_log_damaged(const sharedmap_replay_t *rep)
{
    return rep->nranges > 0 || rep->records_skipped > 0 || rep->duplicates > 0 || rep->reordered > 0;
}

void sharedmap_log_describe(const sharedmap_replay_t *rep, char *buf, size_t cap)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    if (rep->nranges || rep->records_skipped) {
        marie_buf_printf(&b, "%lld record%s (%lld bytes) at offset%s", (long long)rep->records_skipped,
                         rep->records_skipped == 1 ? "" : "s", (long long)rep->bytes_skipped,
                         rep->nranges == 1 ? "" : "s");
        for (size_t i = 0; i < rep->nranges && i < SHAREDMAP_MAX_RANGES; i++)
            marie_buf_printf(&b, "%s %lld+%lld", i ? "," : "", (long long)rep->ranges[i].off,
                             (long long)rep->ranges[i].len);
        if (rep->nranges > SHAREDMAP_MAX_RANGES)
            marie_buf_printf(&b, " and %zu more stretches", rep->nranges - SHAREDMAP_MAX_RANGES);
        marie_buf_printf(&b, " lost");
        if (rep->acked_lost)
            marie_buf_printf(&b, " (%lld acknowledged, cut off the end)", (long long)rep->acked_lost);
    }
    if (rep->duplicates)
        marie_buf_printf(&b, "%s%lld duplicate record%s ignored", b.len ? "; " : "", (long long)rep->duplicates,
                         rep->duplicates == 1 ? "" : "s");
    if (rep->reordered)
        marie_buf_printf(&b, "%s%lld record%s out of sequence, replayed in order", b.len ? "; " : "",
                         (long long)rep->reordered, rep->reordered == 1 ? "" : "s");
    snprintf(buf, cap, "%s", b.len ? b.data : "nothing lost");
    marie_buf_free(&b);
}
