/* fuzz_ca_sharedmap_log: replaying a damaged or hostile SharedMap state file never crashes,
 * and what it loads stays consistent (sorted, unique keys). */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "ca/ca.h"
#include "ca/sharedmap.h"

/* Give every whole record a correct CRC, so mutations reach the field checks behind it. */
static void fix_crcs(uint8_t *img, size_t len)
{
    size_t off = 8;
    while (len - off >= 8) {
        uint32_t blen = (uint32_t)img[off] << 24 | (uint32_t)img[off + 1] << 16 | (uint32_t)img[off + 2] << 8 | img[off + 3];
        if (blen > len - off - 8)
            break;
        uint32_t crc = ca_crc32(0, img + off + 8, blen);
        for (int i = 0; i < 4; i++)
            img[off + 4 + i] = (uint8_t)(crc >> (24 - 8 * i));
        off += 8 + blen;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sharedmap_t *sm = sharedmap_open(NULL, NULL);
    if (!sm)
        return 0;
    /* the magic is fixed; fuzz what follows it too */
    uint8_t *img = malloc(size + 8);
    if (!img) {
        sharedmap_close(sm);
        return 0;
    }
    memcpy(img, "MARIESM1", 8);
    memcpy(img + 8, data, size);
    if (size % 4 != 0)
        fix_crcs(img, size + 8);
    ssize_t good = sharedmap_replay(sm, img, size + 8);
    if (good < 8 || (size_t)good > size + 8)
        abort();
    sharedmap_value_t prev = {0}, v;
    for (size_t i = 0; i < sharedmap_size(sm); i++) {
        if (sharedmap_entry(sm, i, &v) < 0 || (i && strcmp(prev.key, v.key) >= 0))
            abort();
        prev = v;
    }
    sharedmap_replay(sm, data, size);    /* without the magic: refused or replayed */
    free(img);
    sharedmap_close(sm);
    return 0;
}
