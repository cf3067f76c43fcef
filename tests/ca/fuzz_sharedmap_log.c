/* fuzz_ca_sharedmap_log: damaged or hostile SharedMap state files. Two modes, by the first
 * byte: raw bytes after the magic (never a crash; the map stays sorted and unique; the report
 * stays within the file), or a log built from the input and then damaged by it (every record
 * the damage did not touch survives, counted losses match). */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ca/ca.h"
#include "ca/sharedmap.h"
#include "ca/sharedmap_log.h"
#include "tests/ca/sharedmap_damage.h"

static uint32_t be32(const uint8_t *p) { return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]; }
static void put32(uint8_t *p, uint32_t v) { for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (24 - 8 * i)); }

/* Give every marked record whose body fits correct checksums, so mutations reach the field
 * checks and the resynchronisation behind them. */
static void fix_checksums(uint8_t *img, size_t len)
{
    for (size_t off = SHAREDMAP_LOG_MAGIC_LEN; off + SHAREDMAP_LOG_HEAD <= len; off++) {
        if (memcmp(img + off, "\xa7SMR", 4) != 0)
            continue;
        uint32_t blen = be32(img + off + 4);
        if (blen > len - off - SHAREDMAP_LOG_HEAD)
            continue;
        put32(img + off + 16, ca_crc32(0, img + off + SHAREDMAP_LOG_HEAD, blen));
        put32(img + off + 20, ca_crc32(0, img + off, 20));
    }
}

static void check_report(const sharedmap_replay_t *rep, size_t len)
{
    int64_t bytes = 0, prev_end = SHAREDMAP_LOG_MAGIC_LEN;
    if (rep->end < SHAREDMAP_LOG_MAGIC_LEN || (size_t)rep->end > len || rep->torn_bytes < 0 ||
        (size_t)(rep->end + rep->torn_bytes) > len || rep->records_skipped < 0)
        abort();
    for (size_t i = 0; i < rep->nranges && i < SHAREDMAP_MAX_RANGES; i++) {
        if (rep->ranges[i].off < prev_end || rep->ranges[i].len < 0 ||
            (size_t)(rep->ranges[i].off + rep->ranges[i].len) > len)
            abort();
        prev_end = rep->ranges[i].off + rep->ranges[i].len;
        bytes += rep->ranges[i].len;
    }
    if (rep->nranges <= SHAREDMAP_MAX_RANGES && bytes != rep->bytes_skipped)
        abort();
}

static void raw(const uint8_t *data, size_t size, int fix)
{
    uint8_t *img = malloc(size + SHAREDMAP_LOG_MAGIC_LEN);
    sharedmap_t *sm = sharedmap_open(NULL, NULL);
    if (!img || !sm)
        goto out;
    memcpy(img, sharedmap_log_magic, SHAREDMAP_LOG_MAGIC_LEN);
    memcpy(img + SHAREDMAP_LOG_MAGIC_LEN, data, size);
    if (fix)
        fix_checksums(img, size + SHAREDMAP_LOG_MAGIC_LEN);
    sharedmap_replay_t rep;
    if (sharedmap_replay(sm, img, size + SHAREDMAP_LOG_MAGIC_LEN, &rep) != 0)
        abort();
    check_report(&rep, size + SHAREDMAP_LOG_MAGIC_LEN);
    sharedmap_value_t prev = { 0 }, v;
    for (size_t i = 0; i < sharedmap_size(sm); i++) {
        if (sharedmap_entry(sm, i, &v) < 0 || (i && strcmp(prev.key, v.key) >= 0))
            abort();
        prev = v;
    }
    sharedmap_replay(sm, data, size, NULL);    /* without the magic: refused, or an old log */
out:
    sharedmap_close(sm);
    free(img);
}

/* Reads input bytes in order; zeros once it runs out. */
typedef struct {
    const uint8_t *p;
    size_t left;
} input_t;

static uint8_t next(input_t *in)
{
    if (!in->left)
        return 0;
    in->left--;
    return *in->p++;
}

static smd_log_t lg;
static uint8_t img[sizeof lg.img];

static void built_then_damaged(input_t *in)
{
    smd_init(&lg);
    int nrec = 1 + next(in) % 64;
    for (int i = 0; i < nrec; i++) {
        uint8_t b = next(in);
        char key[16];
        uint8_t data[SMD_MAXDATA];
        snprintf(key, sizeof key, "k%d", b & 7);
        size_t len = 8 + next(in) % 40;
        for (size_t k = 0; k < len; k++)
            data[k] = next(in);
        smd_add(&lg, (b & 0x38) == 0 ? SHAREDMAP_LOG_DEL : SHAREDMAP_LOG_SET, key, data, len);
    }
    memcpy(img, lg.img, lg.len);
    size_t len = lg.len;
    for (int d = 0; d < 4 && in->left >= 5 && len > SHAREDMAP_LOG_MAGIC_LEN; d++) {
        uint8_t kind = next(in);
        size_t at = next(in) << 8, n;
        at = SHAREDMAP_LOG_MAGIC_LEN + (at | next(in)) % (len - SHAREDMAP_LOG_MAGIC_LEN);
        n = 1 + (size_t)(next(in) << 8 | next(in)) % 512;
        if (kind % 3 == 0)
            img[at] ^= (uint8_t)(n % 255 + 1);
        else if (kind % 3 == 1)
            smd_zero(img, len, at, n);
        else if (len - n > SHAREDMAP_LOG_MAGIC_LEN)
            len = smd_cut(&lg, img, len, at, n);
    }
    int touched = smd_mark_touched(&lg, img, len);
    /* A value holding a whole record image (marker, header, checksums: spliced in from the
     * raw seeds) can be taken for a record once the one around it is damaged: documented,
     * and out of this property. */
    for (int i = 0; i < lg.n; i++)
        if (memmem(lg.r[i].data, lg.r[i].len, "\xa7SMR", 4))
            return;
    sharedmap_t *sm = sharedmap_open(NULL, NULL);
    if (!sm)
        return;
    sharedmap_replay_t rep;
    char why[200];
    if (sharedmap_replay(sm, img, len, &rep) != 0 || smd_check_map(sm, &lg, why, sizeof why) < 0) {
        fprintf(stderr, "fuzz_ca_sharedmap_log: an untouched record was lost or a damaged one kept: %s\n", why);
        abort();
    }
    check_report(&rep, len);
    if (touched == 0 && (rep.nranges || rep.torn_bytes))
        abort();
    if (touched && !lg.r[lg.n - 1].touched && rep.records_skipped != touched)
        abort();
    if (rep.records_skipped > touched)
        abort();
    sharedmap_close(sm);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size == 0)
        return 0;
    if (data[0] & 1) {
        input_t in = { data + 1, size - 1 };
        built_then_damaged(&in);
    } else {
        raw(data + 1, size - 1, data[0] & 2);
    }
    return 0;
}
