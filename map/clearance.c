/* clearance: exact Euclidean distance transform of a map's blocked cells (Felzenszwalb and
 * Huttenlocher's lower envelope of parabolas, one pass along rows then one along columns). */
#include "map/clearance.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>

/* Squared distance along one line: f holds 0 at blocked samples and FAR elsewhere; d gets the
 * squared distance to the nearest blocked sample (about FAR when there is none). v, z: scratch
 * of n and n + 1. */
#define FAR 1e20
static void edt_line(const double *f, int n, double *d, int *v, double *z)
{
    int k = 0;
    v[0] = 0;
    z[0] = -INFINITY;
    z[1] = INFINITY;
    for (int q = 1; q < n; q++) {
        double s = ((f[q] + (double)q * q) - (f[v[k]] + (double)v[k] * v[k])) / (2.0 * (q - v[k]));
        while (s <= z[k]) {
            k--;
            s = ((f[q] + (double)q * q) - (f[v[k]] + (double)v[k] * v[k])) / (2.0 * (q - v[k]));
        }
        k++;
        v[k] = q;
        z[k] = s;
        z[k + 1] = INFINITY;
    }
    k = 0;
    for (int q = 0; q < n; q++) {
        while (z[k + 1] < q)
            k++;
        double dq = q - v[k];
        d[q] = dq * dq + f[v[k]];
    }
}

static bool blocked(int8_t v, bool unknown_is_free)
{
    return v == OCCMAP_OCCUPIED || (v != OCCMAP_FREE && !unknown_is_free);
}

float *occmap_clearance(const occmap_t *m, bool unknown_is_free)
{
    int w = m->width, h = m->height, n = w > h ? w : h;
    size_t nc = (size_t)w * h;
    float *out = malloc(sizeof(float) * nc);
    double *sq = malloc(sizeof(double) * nc), *f = malloc(sizeof(double) * n), *d = malloc(sizeof(double) * n);
    double *z = malloc(sizeof(double) * (n + 1));
    int *v = malloc(sizeof(int) * n);
    bool any = false;
    if (!out || !sq || !f || !d || !z || !v)
        goto err_nomem;
    for (int y = 0; y < h; y++) {
        for (int x = 0; x < w; x++) {
            bool b = blocked(m->cells[(size_t)y * w + x], unknown_is_free);
            f[x] = b ? 0 : FAR;
            any |= b;
        }
        edt_line(f, w, d, v, z);
        for (int x = 0; x < w; x++)
            sq[(size_t)y * w + x] = d[x];
    }
    for (int x = 0; any && x < w; x++) {
        for (int y = 0; y < h; y++)
            f[y] = sq[(size_t)y * w + x];
        edt_line(f, h, d, v, z);
        for (int y = 0; y < h; y++)
            sq[(size_t)y * w + x] = d[y];
    }
    for (size_t i = 0; i < nc; i++)
        out[i] = (float)(any ? (sqrt(sq[i]) - 0.5) * m->resolution : (double)(w + h) * m->resolution);
    free(sq); free(f); free(d); free(z); free(v);
    return out;
err_nomem:
    free(out); free(sq); free(f); free(d); free(z); free(v);
    errno = ENOMEM;
    return NULL;
}

uint8_t *occmap_passable(const occmap_t *m, double radius, bool unknown_is_free)
{
    float *cl = occmap_clearance(m, unknown_is_free);
    uint8_t *pass = cl ? malloc((size_t)m->width * m->height) : NULL;
    if (!pass) {
        free(cl);
        errno = ENOMEM;
        return NULL;
    }
    for (size_t i = 0; i < (size_t)m->width * m->height; i++)
        pass[i] = cl[i] > radius;
    free(cl);
    return pass;
}
