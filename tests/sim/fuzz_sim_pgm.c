/* fuzz_sim_pgm: the simulator's PGM parser and the map built from it, on arbitrary bytes. */
#include <stdint.h>
#include <stdlib.h>

#include "sim/map.h"
#include "sim/pgm.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sim_pgm_t g;
    char err[160];
    if (sim_pgm_parse(data, size, &g, err, sizeof(err)) == 0) {
        if ((size_t)g.width * g.height <= 1u << 20) {
            sim_map_info_t info = { .resolution = 0.05, .occupied_thresh = 0.65, .free_thresh = 0.196 };
            sim_map_t *m = sim_map_from_pgm(&g, &info);
            sim_rect_t *r = NULL;
            if (m && sim_map_rects(m, &r) >= 0)
                free(r);
            sim_map_destroy(m);
        }
        free(g.pixels);
    }
    return 0;
}
