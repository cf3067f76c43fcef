/* gridpath: A* with an octile heuristic over a passability mask (jump point search), and
 * line-of-sight shortcuts. */
#include "map/gridpath.h"

#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdlib.h>

#include "core/buf.h"

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
    if (MARIE_GROW(h->v, h->cap, h->n + 1) < 0)
        return -1;
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

/* Jump point search (Harabor and Grastien, 2011), in its form for a grid where a diagonal step
 * needs both side cells: A* over the cells where an optimal path may turn, each reached by a
 * straight or diagonal run, instead of over every cell. Same paths' length as plain A*.
 * Straight runs scan 64 cells a step (Harabor and Grastien, 2014): each row of the grid, and
 * each column (a transposed copy), is a bit set with a blocked row above and below. */
typedef struct {
    int nw;             /* 64-bit words a line */
    uint64_t *bits;     /* lines -1 .. n, line l at (l + 1) * nw; bit set: passable */
} lines_t;

typedef struct {
    int w, h, goal;
    const uint8_t *pass;
    lines_t rows, cols;
} grid_t;

static inline bool open_at(const grid_t *g, int x, int y)
{
    return x >= 0 && y >= 0 && x < g->w && y < g->h && g->pass[(size_t)y * g->w + x];
}

static int lines_make(lines_t *l, int n, int len)
{
    l->nw = (len + 63) / 64;
    l->bits = calloc((size_t)(n + 2) * l->nw, sizeof *l->bits);
    return l->bits ? 0 : -1;
}

static inline void lines_set(lines_t *l, int line, int at)
{
    l->bits[(size_t)(line + 1) * l->nw + at / 64] |= 1ull << (at % 64);
}

static inline uint64_t word_at(const uint64_t *line, int nw, int k) { return k >= 0 && k < nw ? line[k] : 0; }

/* Along a line from `at` (exclusive) towards dir (+1 or -1): where the run stops in word k: a
 * blocked cell, or a cell whose neighbour line opens up beside one that was closed. */
static inline uint64_t stops(const lines_t *l, int line, int k, int dir)
{
    const uint64_t *p = l->bits + (size_t)(line + 1) * l->nw, *a = p + l->nw, *b = p - l->nw;
    uint64_t A = a[k], B = b[k], A_before, B_before;
    if (dir > 0) {
        A_before = A << 1 | word_at(a, l->nw, k - 1) >> 63;
        B_before = B << 1 | word_at(b, l->nw, k - 1) >> 63;
    } else {
        A_before = A >> 1 | word_at(a, l->nw, k + 1) << 63;
        B_before = B >> 1 | word_at(b, l->nw, k + 1) << 63;
    }
    return ~p[k] | (A & ~A_before) | (B & ~B_before);
}

/* The first stop after `at` towards dir: its position, passable or not (*open). Positions past
 * the line's end are blocked bits, so there always is one within the line's words, or -1. */
static int scan(const lines_t *l, int line, int at, int dir, bool *open)
{
    int pos = -1;
    if (dir > 0) {
        int from = at + 1;
        for (int k = from / 64; k < l->nw && pos < 0; k++) {
            uint64_t m = stops(l, line, k, dir);
            if (k == from / 64)
                m &= ~0ull << (from % 64);
            if (m)
                pos = k * 64 + __builtin_ctzll(m);
        }
    } else {
        int from = at - 1;
        for (int k = from < 0 ? -1 : from / 64; k >= 0 && pos < 0; k--) {
            uint64_t m = stops(l, line, k, dir);
            if (k == from / 64 && from % 64 != 63)
                m &= (1ull << (from % 64 + 1)) - 1;
            if (m)
                pos = k * 64 + 63 - __builtin_clzll(m);
        }
    }
    *open = pos >= 0 && (l->bits[(size_t)(line + 1) * l->nw + pos / 64] >> (pos % 64) & 1);
    return pos;
}

/* Runs from (x, y) along (dx, 0) or (0, dy): the first cell where a side opens up behind a wall
 * (a neighbour only reachable through it) or the goal; -1 at a wall. */
static int jump_straight(const grid_t *g, int x, int y, int dx, int dy)
{
    const lines_t *l = dx ? &g->rows : &g->cols;
    int line = dx ? y : x, at = dx ? x : y, dir = dx ? dx : dy;
    int goal_line = dx ? g->goal / g->w : g->goal % g->w, goal_at = dx ? g->goal % g->w : g->goal / g->w;
    bool open;
    int pos = scan(l, line, at, dir, &open);
    if (goal_line == line && (goal_at - at) * dir > 0 && (pos < 0 || (pos - goal_at) * dir >= 0))
        return g->goal;
    if (pos < 0 || !open)
        return -1;
    return dx ? y * g->w + pos : pos * g->w + x;
}

/* Runs diagonally: the first cell from which a straight run finds a jump point, or the goal. */
static int jump_diagonal(const grid_t *g, int x, int y, int dx, int dy)
{
    for (;;) {
        if (!open_at(g, x + dx, y) || !open_at(g, x, y + dy) || !open_at(g, x + dx, y + dy))
            return -1;
        x += dx;
        y += dy;
        int c = y * g->w + x;
        if (c == g->goal || jump_straight(g, x, y, dx, 0) >= 0 || jump_straight(g, x, y, 0, dy) >= 0)
            return c;
    }
}

static int sign(int v) { return (v > 0) - (v < 0); }

/* The directions worth following from a cell reached from `parent` (-1: the start, all eight). */
static int directions(const grid_t *g, int cell, int parent, int dir[8][2])
{
    int x = cell % g->w, y = cell / g->w, n = 0;
    if (parent < 0) {
        static const int all[8][2] = { { 1, 0 }, { -1, 0 }, { 0, 1 }, { 0, -1 },
                                       { 1, 1 }, { 1, -1 }, { -1, 1 }, { -1, -1 } };
        for (int k = 0; k < 8; k++) {
            dir[n][0] = all[k][0];
            dir[n++][1] = all[k][1];
        }
        return n;
    }
    int dx = sign(x - parent % g->w), dy = sign(y - parent / g->w);
#define ADD(a, b) (dir[n][0] = (a), dir[n][1] = (b), n++)
    if (dx && dy) {
        bool side_y = open_at(g, x, y + dy), side_x = open_at(g, x + dx, y);
        if (side_y)
            ADD(0, dy);
        if (side_x)
            ADD(dx, 0);
        if (side_x && side_y)
            ADD(dx, dy);
    } else if (dx) {
        bool up = open_at(g, x, y + 1), down = open_at(g, x, y - 1);
        if (open_at(g, x + dx, y)) {
            ADD(dx, 0);
            if (up)
                ADD(dx, 1);
            if (down)
                ADD(dx, -1);
        }
        if (up)
            ADD(0, 1);
        if (down)
            ADD(0, -1);
    } else {
        bool right = open_at(g, x + 1, y), left = open_at(g, x - 1, y);
        if (open_at(g, x, y + dy)) {
            ADD(0, dy);
            if (right)
                ADD(1, dy);
            if (left)
                ADD(-1, dy);
        }
        if (right)
            ADD(1, 0);
        if (left)
            ADD(-1, 0);
    }
#undef ADD
    return n;
}

/* The cells from start to goal, each jump's run walked cell by cell: malloc'd, *n of them. */
static int *walk_back(int w, const int *from, int start, int goal, int *n)
{
    int len = 1;
    for (int c = goal; c != start; c = from[c] - 1) {
        int p = from[c] - 1;
        len += abs(c % w - p % w) > abs(c / w - p / w) ? abs(c % w - p % w) : abs(c / w - p / w);
    }
    int *v = malloc((size_t)len * sizeof *v);
    if (!v)
        return NULL;
    int i = len;
    v[--i] = goal;
    for (int c = goal; c != start; c = from[c] - 1) {
        int p = from[c] - 1, sx = sign(p % w - c % w), sy = sign(p / w - c / w);
        for (int x = c % w, y = c / w; x != p % w || y != p / w;) {
            x += sx * (x != p % w);
            y += sy * (y != p / w);
            v[--i] = y * w + x;
        }
    }
    *n = len;
    return v;
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
    /* from[c]: 0 where the search has not been, else the cell it came from + 1 (the start its
     * own); g[c] is valid only there. calloc's zero pages cost nothing until touched, and the
     * search touches few cells. */
    int *from = calloc(nc, sizeof *from);
    double *g = malloc(nc * sizeof *g);
    heap_t hp = { 0 };
    double result = -1;
    grid_t grid = { w, h, goal, pass, { 0 }, { 0 } };
    if (!g || !from || lines_make(&grid.rows, h, w) < 0 || lines_make(&grid.cols, w, h) < 0)
        goto nomem;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            if (pass[(size_t)y * w + x]) {
                lines_set(&grid.rows, y, x);
                lines_set(&grid.cols, x, y);
            }
    g[start] = 0;
    from[start] = start + 1;
    if (heap_push(&hp, (node_t){ octile(w, start, goal), start }) < 0)
        goto nomem;
    while (hp.n) {
        node_t cur = heap_pop(&hp);
        if (cur.f > g[cur.cell] + octile(w, cur.cell, goal) + 1e-9)
            continue;                       /* a stale entry */
        if (cur.cell == goal) {
            result = g[goal];
            break;
        }
        int dir[8][2];
        int nd = directions(&grid, cur.cell, cur.cell == start ? -1 : from[cur.cell] - 1, dir);
        int cx = cur.cell % w, cy = cur.cell / w;
        for (int k = 0; k < nd; k++) {
            int dx = dir[k][0], dy = dir[k][1];
            int nb = dx && dy ? jump_diagonal(&grid, cx, cy, dx, dy) : jump_straight(&grid, cx, cy, dx, dy);
            if (nb < 0)
                continue;
            double ng = g[cur.cell] + octile(w, cur.cell, nb);
            if (!from[nb] || ng < g[nb] - 1e-12) {
                g[nb] = ng;
                from[nb] = cur.cell + 1;
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
        if (!(*cells = walk_back(w, from, start, goal, &len)))
            goto nomem;
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
    free(grid.rows.bits);
    free(grid.cols.bits);
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
