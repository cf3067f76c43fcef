/* ssl_sep: geometric beamforming and post-filter (see ssl_sep.h). */
#include "adapters/ssl/ssl_sep.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define SPEED_OF_SOUND 343.0
#define MAXK 8
#define LOADING 0.05            /* diagonal loading of A^H A, relative to the microphone count */
#define FLOOR_GAIN 0.3          /* the post-filter's lowest gain */

void ssl_sep_cfg_default(ssl_sep_cfg_t *c)
{
    *c = (ssl_sep_cfg_t)SSL_SEP_CFG_DEFAULTS;
}

/* Solves G z = b in place (G n x n, complex, Gaussian elimination with partial pivoting). */
static void solve(double complex G[MAXK][MAXK], double complex *b, int n)
{
    for (int c = 0; c < n; c++) {
        int piv = c;
        for (int r = c + 1; r < n; r++)
            if (cabs(G[r][c]) > cabs(G[piv][c]))
                piv = r;
        if (piv != c) {
            for (int j = 0; j < n; j++) {
                double complex t = G[c][j]; G[c][j] = G[piv][j]; G[piv][j] = t;
            }
            double complex t = b[c]; b[c] = b[piv]; b[piv] = t;
        }
        if (cabs(G[c][c]) < 1e-12)
            continue;
        for (int r = c + 1; r < n; r++) {
            double complex f = G[r][c] / G[c][c];
            for (int j = c; j < n; j++)
                G[r][j] -= f * G[c][j];
            b[r] -= f * b[c];
        }
    }
    for (int c = n - 1; c >= 0; c--) {
        double complex s = b[c];
        for (int j = c + 1; j < n; j++)
            s -= G[c][j] * b[j];
        b[c] = cabs(G[c][c]) < 1e-12 ? 0 : s / G[c][c];
    }
}

void ssl_sep_beam(const ssl_sep_cfg_t *cfg, const micarray_t *mics, int rate, int nfft,
                  const float complex *const *X, const double (*dirs)[3], int n, int k, float complex *Y)
{
    int M = mics->n, nb = nfft / 2 + 1;
    if (n > MAXK)
        n = MAXK;
    if (!cfg->nulls) {
        dirs += k;
        n = 1;
        k = 0;
    }
    double tau[MAXK][MICARRAY_MAX];   /* arrival time at each microphone relative to the centre, s */
    for (int s = 0; s < n; s++)
        for (int m = 0; m < M; m++) {
            double proj = 0;
            for (int j = 0; j < 3; j++)
                proj += dirs[s][j] * (mics->pos[m][j] - mics->center[j]);
            tau[s][m] = -proj / SPEED_OF_SOUND;
        }
    for (int b = 0; b < nb; b++) {
        double w = 2 * M_PI * b * rate / nfft;
        double complex A[MICARRAY_MAX][MAXK], G[MAXK][MAXK], z[MAXK];
        for (int m = 0; m < M; m++)
            for (int s = 0; s < n; s++)
                A[m][s] = cexp(-I * w * tau[s][m]);
        /* w_k = A (A^H A + dI)^-1 e_k: unit response toward k, (near) nulls toward the others. */
        for (int i = 0; i < n; i++) {
            for (int j = 0; j < n; j++) {
                double complex g = 0;
                for (int m = 0; m < M; m++)
                    g += conj(A[m][i]) * A[m][j];
                G[i][j] = g + (i == j ? LOADING * M : 0);
            }
            z[i] = i == k ? 1 : 0;
        }
        solve(G, z, n);
        double complex y = 0;
        for (int m = 0; m < M; m++) {
            double complex wm = 0;
            for (int s = 0; s < n; s++)
                wm += A[m][s] * z[s];
            y += conj(wm) * X[m][b];
        }
        /* The loading shrinks the gain toward the source by M / (M + dM): give it back. */
        Y[b] = (float complex)(y * (n == 1 ? (1 + LOADING) : 1));
    }
}

int ssl_postfilter_init(ssl_postfilter_t *p, int nbins)
{
    memset(p, 0, sizeof(*p));
    p->nbins = nbins;
    p->noise = calloc((size_t)nbins, sizeof(float));
    p->prev_snr = calloc((size_t)nbins, sizeof(float));
    if (!p->noise || !p->prev_snr) {
        ssl_postfilter_free(p);
        return -1;
    }
    return 0;
}

void ssl_postfilter_free(ssl_postfilter_t *p)
{
    free(p->noise);
    free(p->prev_snr);
    p->noise = p->prev_snr = NULL;
}

/* The noise level per bin is a running mean of the power that leaves out bursts over 3 times
 * it (speech), as in ssl_srp.c; the gain is decision-directed Wiener with a floor, so the
 * recognizer downstream gets speech with its noise lowered rather than carved out. */
void ssl_postfilter_apply(ssl_postfilter_t *p, const ssl_sep_cfg_t *cfg, float complex *Y)
{
    p->frames++;
    for (int b = 0; b < p->nbins; b++) {
        float pw = crealf(Y[b]) * crealf(Y[b]) + cimagf(Y[b]) * cimagf(Y[b]);
        float *nz = &p->noise[b];
        if (p->frames <= 10)
            *nz = p->frames == 1 ? pw : *nz + (pw - *nz) / (float)p->frames;
        else if (pw < 3 * *nz)
            *nz += 0.05f * (pw - *nz);
        else
            *nz *= 1.01f;
        float post = *nz > 0 ? pw / *nz : 1000;
        float prio = 0.9f * p->prev_snr[b] + 0.1f * fmaxf(post - 1, 0);
        float g = prio / (1 + prio);
        if (g < FLOOR_GAIN)
            g = FLOOR_GAIN;
        Y[b] *= g;
        p->prev_snr[b] = g * g * post;
    }
}
