/* fuzz_lcmlog: any bytes, fed whole and in odd-sized pieces, must give the same records and
 * never crash the LCM log reader. */
#include <assert.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/lcmlog.h"

typedef struct {
    int64_t events;
    uint64_t sum;
} tally_t;

static void on_event(void *user, const lcmlog_event_t *ev)
{
    tally_t *t = user;
    t->events++;
    t->sum += ev->offset + ev->data_len + ev->channel_len;
    if (ev->data_len)
        t->sum += ev->data[ev->data_len - 1];
}

static void on_corrupt(void *user, uint64_t offset, const char *reason)
{
    (void)user; (void)offset;
    assert(reason && *reason);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    tally_t whole = {0}, pieces = {0};
    lcmlog_parser_t *p = lcmlog_parser_create(on_event, on_corrupt, &whole);
    if (!p)
        return 0;
    lcmlog_parser_feed(p, data, size);
    lcmlog_parser_finish(p);
    lcmlog_parser_destroy(p);

    p = lcmlog_parser_create(on_event, on_corrupt, &pieces);
    if (!p)
        return 0;
    size_t step = size ? 1 + data[0] % 61 : 1;
    for (size_t off = 0; off < size; off += step)
        lcmlog_parser_feed(p, data + off, size - off < step ? size - off : step);
    lcmlog_parser_finish(p);
    lcmlog_parser_destroy(p);
    /* Records are found the same way however the bytes arrive. */
    assert(whole.events == pieces.events && whole.sum == pieces.sum);
    return 0;
}
