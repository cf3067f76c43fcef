/* fuzz_occmap_pgm: any bytes given as a map image are decoded or refused, never crash. */
#include <stdint.h>
#include <stddef.h>
#include <stdlib.h>

#include "adapters/common/occmap.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    occmap_meta_t meta = { 0.05, 0, 0, false, 0.65, 0.196 };
    char err[160];
    occmap_t *m = occmap_from_pgm(data, size, &meta, err, sizeof(err));
    if (m) {
        /* A decoded map is usable: a ray across it ends within its range. */
        double r = occmap_raycast(m, m->width * m->resolution / 2, m->height * m->resolution / 2, 0.7, 10);
        if (m->width <= 0 || m->height <= 0 || !(r >= 0 && r <= 10))
            abort();
        occmap_destroy(m);
    }
    return 0;
}
