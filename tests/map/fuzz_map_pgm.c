/* fuzz_map_pgm: any bytes given as a map image are decoded or refused, never crash; a decoded
 * map holds only map_server's values and its rays stay within range. */
#include <assert.h>
#include <stdint.h>
#include <stddef.h>
#include <stdlib.h>

#include "map/occmap.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    pgm_t img;
    char err[160];
    if (pgm_parse(data, size, &img, err, sizeof(err)) < 0) {
        assert(img.pixels == NULL && err[0]);
        return 0;
    }
    assert(img.width > 0 && img.height > 0 && img.maxval > 0);
    /* The first byte picks the mode and the origin's yaw, so every path is reached. */
    occmap_meta_t meta = { .resolution = 0.05, .mode = (occmap_mode_t)(data[size - 1] % 3),
                           .origin_yaw = (data[size - 1] & 4) ? 0.3 : 0, .negate = data[size - 1] & 8,
                           .occupied_thresh = 0.65, .free_thresh = 0.196 };
    occmap_t *m = img.width * img.height <= 1 << 20 ? occmap_from_image(&img, &meta) : NULL;
    if (m) {
        for (size_t i = 0; i < (size_t)m->width * m->height; i++)
            assert(m->cells[i] >= OCCMAP_UNKNOWN && m->cells[i] <= OCCMAP_OCCUPIED);
        if (meta.mode == OCCMAP_TRINARY)
            for (size_t i = 0; i < (size_t)m->width * m->height; i++)
                assert(m->cells[i] == OCCMAP_UNKNOWN || m->cells[i] == OCCMAP_FREE || m->cells[i] == OCCMAP_OCCUPIED);
        double d = occmap_raycast(m, m->origin_x + m->width * m->resolution / 2,
                                  m->origin_y + m->height * m->resolution / 2, 0.7, 10);
        assert(d >= 0 && d <= 10);
        occmap_destroy(m);
    }
    free(img.pixels);
    return 0;
}
