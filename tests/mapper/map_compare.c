/* map_compare: a saved map against the world it was built in (same frame): prints precision,
 * recall, coverage (tests/mapper/mapeval.h). Usage: map_compare BUILT.yaml WORLD.yaml SX SY */
#include <stdio.h>
#include <stdlib.h>

#include "tests/mapper/mapeval.h"

int main(int argc, char **argv)
{
    if (argc != 5) {
        fprintf(stderr, "usage: map_compare BUILT.yaml WORLD.yaml START_X START_Y\n");
        return 2;
    }
    marie_errors_t errs = { 0 };
    occmap_t *built = occmap_load(argv[1], &errs), *world = occmap_load(argv[2], &errs);
    if (!built || !world) {
        fprintf(stderr, "map_compare: %s\n", errs.n ? errs.msgs[0] : "cannot load");
        return 1;
    }
    mapeval_t e;
    mapeval_compare(world, built, atof(argv[3]), atof(argv[4]), &e);
    printf("precision %.3f recall %.3f coverage %.3f (built occupied %ld, visible walls %ld, reachable free %ld)\n",
           e.precision, e.recall, e.coverage, e.map_occupied, e.truth_walls, e.truth_free);
    /* Aligned: the best rigid transform within 0.5 m and 0.03 rad, as the measure asks. */
    double dx, dy, th;
    occmap_t *al = mapeval_align(world, built, 0.5, 0.03, &dx, &dy, &th);
    if (al) {
        mapeval_compare(world, al, atof(argv[3]), atof(argv[4]), &e);
        printf("aligned by (%.2f m, %.2f m, %.3f rad): aprecision %.3f arecall %.3f acoverage %.3f\n", dx, dy, th,
               e.precision, e.recall, e.coverage);
        occmap_destroy(al);
    }
    occmap_destroy(built);
    occmap_destroy(world);
    return 0;
}
