/* fuzz_lms200: the LMS200 stream parser and reply decoders on arbitrary bytes, split into
 * chunks at arbitrary places; every count must stay consistent with what was fed. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "hw/lms200/lms200.h"

static size_t delivered_bytes;

static void on_telegram(void *user, const lms200_telegram_t *t)
{
    static lms200_scan_t scan;
    uint8_t res;
    lms200_variant_t v;
    delivered_bytes += t->raw_len;
    if (t->raw_len < 6 || t->raw_len > LMS200_MAX_TELEGRAM || t->data + t->data_len > t->raw + t->raw_len)
        abort();
    (void)lms200_decode_mode_reply(t, &res);
    (void)lms200_decode_variant_reply(t, &v);
    if (lms200_decode_scan(t, &scan) == 0) {
        for (int i = 0; i < scan.n; i++)
            (void)lms200_value_m(scan.values[i], scan.unit);
    }
    /* Re-encoding a decoded telegram gives the same bytes back. */
    uint8_t out[LMS200_MAX_TELEGRAM];
    size_t n = lms200_encode(out, sizeof out, t->addr, t->cmd, t->data, t->data_len,
                             t->has_status ? t->status : -1);
    if (n != t->raw_len || memcmp(out, t->raw, n) != 0)
        abort();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size == 0)
        return 0;
    lms200_parser_t *p = lms200_parser_create(on_telegram, NULL, NULL);
    if (!p)
        return 0;
    delivered_bytes = 0;
    /* The first byte picks the chunk size, so splits inside headers and CRCs are covered. */
    size_t chunk = 1 + data[0] % 97;
    data++;
    size--;
    for (size_t off = 0; off < size; off += chunk) {
        size_t n = size - off < chunk ? size - off : chunk;
        lms200_parser_feed(p, data + off, n);
    }
    if (delivered_bytes + lms200_parser_pending(p) > size)
        abort();
    lms200_parser_reset(p);
    if (lms200_parser_pending(p) != 0)
        abort();
    lms200_parser_destroy(p);
    return 0;
}
