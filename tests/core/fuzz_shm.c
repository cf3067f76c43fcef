/* fuzz_shm: a shared-memory segment is bytes from outside (any process may write a file under
 * /dev/shm): whatever the segment holds, a reader refuses or copies within bounds, never reads
 * outside the mapping. The input is the segment; its first 8 bytes pick the message number. */
#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/shm.h"

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
    ssize_t w = write(fd, data + 8, size - 8);
    close(fd);
    if (w != (ssize_t)(size - 8)) {
        unlink(path);
        return 0;
    }
    marie_shm_reader_t *r = marie_shm_reader_create();
    marie_shm_ref_t ref;
    snprintf(ref.segment, sizeof ref.segment, "%s", name);
    memcpy(&ref.seq, data, 8);
    ref.size = (uint32_t)(size & 0xffff);
    static uint8_t buf[1 << 16];
    int64_t n = marie_shm_read(r, &ref, buf, sizeof buf);
    if (n > (int64_t)sizeof buf)
        abort();
    /* Following the segment without a notice: its newest message, and a ref made from its slot. */
    marie_shm_ref_t at;
    if (marie_shm_newest(r, name) > 0 && marie_shm_ref_at(r, name, ref.seq, &at) == 0 &&
        marie_shm_read(r, &at, buf, sizeof buf) > (int64_t)sizeof buf)
        abort();
    const uint8_t *p = marie_shm_peek(r, &ref);
    if (p) {
        volatile uint8_t sum = 0;
        for (uint32_t i = 0; i < ref.size; i++)
            sum ^= p[i];        /* every byte of a peeked message must be mapped */
        (void)marie_shm_still_valid(r, &ref);
    }
    marie_shm_reader_destroy(r);
    unlink(path);
    return 0;
}
