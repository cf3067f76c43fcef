/* gridpath: A* with an octile heuristic over a passability mask, and line-of-sight shortcuts. */
#include "map/gridpath.h"

#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdlib.h>

typedef struct {
    double f;
    int cell;
} node_t;

/* A binary min-heap on f. */
typedef struct {
    node_t *v;
    size_t n, cap;
} heap_t;

static int heap_push(heap_t *h, node_t x)
{
    if (h->n == h->cap) {
        size_t cap = h->cap ? 2 * h->cap : 1024;
        node_t *v = realloc(h->v, cap * sizeof *v);
        if (!v)
            return -1;
        h->v = v;
        h->cap = cap;
    }
    size_t i = h->n++;
    while (i && h->v[(i - 1) / 2].f > x.f) {
        h->v[i] = h->v[(i - 1) / 2];
        i = (i - 1) / 2;
    }
    h->v[i] = x;
    return 0;
}

static node_t heap_pop(heap_t *h)
{
    node_t top = h->v[0], last = h->v[--h->n];
    size_t i = 0;
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= h->n)
            break;
        if (c + 1 < h->n && h->v[c + 1].f < h->v[c].f)
            c++;
        if (h->v[c].f >= last.f)
            break;
        h->v[i] = h->v[c];
        i = c;
    }
    if (h->n)
        h->v[i] = last;
    return top;
}

static double octile(int w, int a, int b)
{
    double dx = abs(a % w - b % w), dy = abs(a / w - b / w);
    return dx > dy ? dx + (M_SQRT2 - 1) * dy : dy + (M_SQRT2 - 1) * dx;
}

double gridpath_find(int w, int h, const uint8_t *pass, int start, int goal, int **cells, int *n)
{
    if (cells)
        *cells = NULL;
    if (n)
        *n = 0;
    size_t nc = (size_t)w * h;
    if (w <= 0 || h <= 0 || start < 0 || goal < 0 || (size_t)start >= nc || (size_t)goal >= nc || !pass[start] ||
        !pass[goal]) {
        errno = EINVAL;
        return -1;
    }
    double *g = malloc(nc * sizeof *g);
    int *from = malloc(nc * sizeof *from);
    heap_t hp = { 0 };
    double result = -1;
    if (!g || !from)
        goto nomem;
    for (size_t i = 0; i < nc; i++)
        g[i] = INFINITY;
    g[start] = 0;
    from[start] = -1;
    if (heap_push(&hp, (node_t){ octile(w, start, goal), start }) < 0)
        goto nomem;
    static const int dx[8] = { 1, -1, 0, 0, 1, 1, -1, -1 }, dy[8] = { 0, 0, 1, -1, 1, -1, 1, -1 };
    while (hp.n) {
        node_t cur = heap_pop(&hp);
        if (cur.f > g[cur.cell] + octile(w, cur.cell, goal) + 1e-9)
            continue;                       /* a stale entry */
        if (cur.cell == goal) {
            result = g[goal];
            break;
        }
        int cx = cur.cell % w, cy = cur.cell / w;
        for (int k = 0; k < 8; k++) {
            int x = cx + dx[k], y = cy + dy[k];
            if (x < 0 || y < 0 || x >= w || y >= h || !pass[(size_t)y * w + x])
                continue;
            if (k >= 4 && (!pass[(size_t)cy * w + x] || !pass[(size_t)y * w + cx]))
                continue;
            int nb = y * w + x;
            double ng = g[cur.cell] + (k >= 4 ? M_SQRT2 : 1.0);
            if (ng < g[nb]) {
                g[nb] = ng;
                from[nb] = cur.cell;
                if (heap_push(&hp, (node_t){ ng + octile(w, nb, goal), nb }) < 0)
                    goto nomem;
            }
        }
    }
    if (result < 0) {
        errno = ENOENT;
        goto out;
    }
    if (cells) {
        int len = 0;
        for (int c = goal; c >= 0; c = from[c])
            len++;
        int *v = malloc((size_t)len * sizeof *v);
        if (!v)
            goto nomem;
        int i = len;
        for (int c = goal; c >= 0; c = from[c])
            v[--i] = c;
        *cells = v;
        if (n)
            *n = len;
    }
    goto out;
nomem:
    errno = ENOMEM;
    result = -1;
out:
    free(g);
    free(from);
    free(hp.v);
    return result;
}

/* Every cell the segment between two cell centres touches is passable (a supercover walk). */
static bool line_clear(int w, const uint8_t *pass, int a, int b)
{
    int x0 = a % w, y0 = a / w, x1 = b % w, y1 = b / w;
    int nx = abs(x1 - x0), ny = abs(y1 - y0), sx = x1 > x0 ? 1 : -1, sy = y1 > y0 ? 1 : -1;
    int x = x0, y = y0;
    for (int ix = 0, iy = 0; ix < nx || iy < ny;) {
        double d = (0.5 + ix) * ny - (0.5 + iy) * nx;
        if (d == 0) {                       /* through a corner: both neighbours must be open */
            if (!pass[(size_t)y * w + x + sx] || !pass[(size_t)(y + sy) * w + x])
                return false;
            x += sx;
            y += sy;
            ix++;
            iy++;
        } else if (d < 0) {
            x += sx;
            ix++;
        } else {
            y += sy;
            iy++;
        }
        if (!pass[(size_t)y * w + x])
            return false;
    }
    return true;
}

int gridpath_shortcut(int w, int h, const uint8_t *pass, int *cells, int n)
{
    (void)h;
    if (n <= 2)
        return n;
    int out = 1, anchor = 0;
    while (anchor < n - 1) {
        /* Walk on while the straight line still holds: linear in the path, not quadratic. */
        int far = anchor + 1;
        while (far + 1 < n && line_clear(w, pass, cells[anchor], cells[far + 1]))
            far++;
        cells[out++] = cells[far];
        anchor = far;
    }
    return out;
}
