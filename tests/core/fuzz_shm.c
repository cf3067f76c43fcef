/* fuzz_shm: a shared-memory segment is bytes from outside (any process of the user may write a
 * file under /dev/shm, and every reader writes the hold table): whatever the segment holds, a
 * reader refuses or reads within bounds, never reads outside the mapping, and a writer whose
 * hold table is garbage still writes without a wait and keeps its newest message readable.
 * The input: 8 bytes naming the message, then the segment in short: its header (64 bytes),
 * its index (8 bytes a message kept, as many as the header's nslots says, at most 1024), the
 * hold table (64 bytes), the slots; laid out as the ring lays them (docs/transport.md). */
#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "core/shm.h"

#define HDR 64
#define HOLD_ALIGN 65536
#define HOLDS_LEN 64
#define ROUND(x, a) (((x) + (a) - 1) / (a) * (a))

static uint64_t hold_off(uint64_t nslots) { return ROUND(HDR + 8 * nslots, HOLD_ALIGN); }

/* Lay the short form out as a segment file: 0, or -1 when the input is too short. */
static int lay_out(int fd, const uint8_t *in, size_t len)
{
    if (len < HDR)
        return -1;
    uint32_t nslots;
    memcpy(&nslots, in + 24, 4);            /* shm_hdr_t: magic, version, slot_size, stride, nslots */
    nslots = nslots > 1024 ? 1024 : nslots;
    size_t idx = len - HDR < 8 * (size_t)nslots ? len - HDR : 8 * (size_t)nslots;
    size_t rest = len - HDR - idx, holds = rest < HOLDS_LEN ? rest : HOLDS_LEN;
    uint64_t h = hold_off(nslots);
    if (pwrite(fd, in, HDR, 0) != HDR || pwrite(fd, in + HDR, idx, HDR) != (ssize_t)idx ||
        pwrite(fd, in + HDR + idx, holds, (off_t)h) != (ssize_t)holds)
        return -1;
    rest -= holds;
    if (ftruncate(fd, (off_t)(h + HOLD_ALIGN + rest)) < 0)
        return -1;
    return pwrite(fd, in + HDR + idx + holds, rest, (off_t)(h + HOLD_ALIGN)) == (ssize_t)rest ? 0 : -1;
}

static void read_all(const char *name, marie_shm_ref_t *ref)
{
    marie_shm_reader_t *r = marie_shm_reader_create();
    static uint8_t buf[1 << 16];
    int64_t n = marie_shm_read(r, ref, buf, sizeof buf);
    if (n > (int64_t)sizeof buf)
        abort();
    /* Following the segment without a notice: its newest message, and a ref made from its slot. */
    marie_shm_ref_t at;
    if (marie_shm_newest(r, name) > 0 && marie_shm_ref_at(r, name, ref->seq, &at) == 0 &&
        marie_shm_read(r, &at, buf, sizeof buf) > (int64_t)sizeof buf)
        abort();
    for (int held = 0; held < 2; held++) {
        const uint8_t *p = held ? marie_shm_hold(r, ref) : marie_shm_peek(r, ref);
        if (!p)
            continue;
        volatile uint8_t sum = 0;
        for (uint32_t i = 0; i < ref->size; i++)
            sum ^= p[i];        /* every byte of a peeked or held message must be mapped */
        (void)marie_shm_still_valid(r, ref);
        if (held)
            marie_shm_release(r, ref);
    }
    marie_shm_reader_destroy(r);
}

/* A live writer whose hold table readers filled with the input's bytes. */
static void write_past_garbage_holds(const uint8_t *holds, size_t len)
{
    static marie_shm_writer_t *w;
    static uint8_t *table;
    if (!w && !(w = marie_shm_writer_create("fuzzw", 64, 4)))
        return;
    if (!table) {
        char path[256];
        snprintf(path, sizeof path, "/dev/shm/%s", marie_shm_writer_segment(w));
        int fd = open(path, O_RDWR | O_CLOEXEC);
        void *t = fd < 0 ? MAP_FAILED : mmap(NULL, HOLD_ALIGN, PROT_READ | PROT_WRITE, MAP_SHARED, fd, (off_t)hold_off(4));
        if (fd >= 0)
            close(fd);
        if (t == MAP_FAILED)
            return;
        table = t;
    }
    memset(table, 0, HOLDS_LEN);
    memcpy(table, holds, len < HOLDS_LEN ? len : HOLDS_LEN);
    marie_shm_reader_t *r = marie_shm_reader_create();
    uint8_t msg[64], out[64];
    marie_shm_ref_t ref;
    for (int i = 0; i < 16; i++) {
        memset(msg, i, sizeof msg);
        if (marie_shm_write(w, msg, sizeof msg, &ref) < 0)
            abort();
    }
    if (marie_shm_read(r, &ref, out, sizeof out) != sizeof out || memcmp(out, msg, sizeof out) != 0)
        abort();
    marie_shm_reader_destroy(r);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 8)
        return 0;
    char name[64], path[128];
    snprintf(name, sizeof name, "marie-shm.fuzz.%d", (int)getpid());
    snprintf(path, sizeof path, "/dev/shm/%s", name);
    int fd = open(path, O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
    if (fd < 0)
        return 0;
    int laid = lay_out(fd, data + 8, size - 8);
    close(fd);
    if (laid == 0) {
        marie_shm_ref_t ref;
        snprintf(ref.segment, sizeof ref.segment, "%s", name);
        memcpy(&ref.seq, data, 8);
        ref.size = (uint32_t)(size & 0xffff);
        read_all(name, &ref);
    }
    unlink(path);
    if (size > 8 + HDR)
        write_past_garbage_holds(data + 8 + HDR, size - 8 - HDR);
    return 0;
}
