/* walls: the cells of a map that are not known free merged into rectangles, one physics box each:
 * the simulator makes no free space the map never saw (the unknown inside a warehouse's racks is
 * solid, as the racks are). */
#include "sim/walls.h"

#include <errno.h>
#include <stdlib.h>

#include "core/err.h"

long sim_walls_rects(const occmap_t *m, sim_rect_t **out)
{
    size_t cap = 256, n = 0;
    sim_rect_t *r = malloc(cap * sizeof(*r));
    /* open[k]: index in r of the rectangle still growing upward whose run starts at column k */
    long *open = malloc((size_t)m->width * sizeof(*open));
    long *next = malloc((size_t)m->width * sizeof(*next));
    if (!r || !open || !next)
        goto nomem;
    for (int i = 0; i < m->width; i++)
        open[i] = -1;
    for (int j = 0; j < m->height; j++) {
        for (int i = 0; i < m->width; i++)
            next[i] = -1;
        int i = 0;
        while (i < m->width) {
            if (occmap_get(m, i, j) == OCCMAP_FREE) {
                i++;
                continue;
            }
            int i0 = i;
            while (i < m->width && occmap_get(m, i, j) != OCCMAP_FREE)
                i++;
            long k = open[i0];
            if (k >= 0 && r[k].w == i - i0 && r[k].j + r[k].h == j) {
                r[k].h++;               /* the same run as the row below: stack it */
            } else {
                if (n == cap) {
                    sim_rect_t *g = realloc(r, 2 * cap * sizeof(*r));
                    if (!g)
                        goto nomem;
                    r = g;
                    cap *= 2;
                }
                r[n] = (sim_rect_t){ i0, j, i - i0, 1 };
                k = (long)n++;
            }
            next[i0] = k;
        }
        long *t = open;
        open = next;
        next = t;
    }
    free(open);
    free(next);
    *out = r;
    return (long)n;
nomem:
    free(r);
    free(open);
    free(next);
    return marie_fail(ENOMEM);
}
