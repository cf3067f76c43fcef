/* ssl_srp: SRP-PHAT localization over a direction grid (see ssl_srp.h). */
#include "adapters/ssl/ssl_srp.h"

#include <errno.h>
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"

#define SPEED_OF_SOUND 343.0
/* The grid and the band: constants, not parameters. */
#define UPSAMPLE 4              /* cross-correlation resolution: 1/UPSAMPLE sample */
#define AZ_STEP (2 * M_PI / 180)
#define EL_MIN (-10 * M_PI / 180)
#define EL_MAX (60 * M_PI / 180)
#define EL_STEP (10 * M_PI / 180)
#define F_MIN 150.0             /* Hz band used */
#define F_MAX 7000.0
/* A bin weighs 1 - OVERSUB * steady level / power (at least 0): 2 keeps a fan just trackable and
 * diffuse noise out. */
#define OVERSUB 2.0
#define MIN_SEPARATION (25 * M_PI / 180)    /* rad of azimuth between two potentials of a frame */

struct ssl_srp {
    ssl_srp_cfg_t cfg;
    int nmics, npairs, ndirs, nbins, ncorr;
    int (*pair)[2];
    double (*dirs)[3];
    float *map;
    int *lag;                   /* [dir * npairs + pair]: index into the upsampled correlation */
    float complex *cross;       /* ncorr/2 + 1 bins */
    float *corr;                /* npairs * ncorr */
    fftwf_plan plan;
    int kmin, kmax;
    float complex *phat;        /* npairs * nbins: each pair's unit cross-spectrum this frame */
    double (*mics)[3];
    float *noise;               /* per bin: noise floor of the mean microphone power */
    float *weight;              /* per bin: how much of it is above that floor, 0..1 */
    long frames;
};

void ssl_srp_cfg_default(ssl_srp_cfg_t *c)
{
    *c = (ssl_srp_cfg_t)SSL_SRP_CFG_DEFAULTS;
}

static int make_grid(ssl_srp_t *s)
{
    int naz = (int)lround(2 * M_PI / AZ_STEP);
    int nel = (int)floor((EL_MAX - EL_MIN) / EL_STEP + 1e-9) + 1;
    s->ndirs = naz * nel;
    if (!(s->dirs = malloc(sizeof(*s->dirs) * (size_t)s->ndirs)))
        return -1;
    for (int e = 0; e < nel; e++)
        for (int a = 0; a < naz; a++) {
            double el = EL_MIN + e * EL_STEP, az = a * 2 * M_PI / naz;
            double *d = s->dirs[e * naz + a];
            d[0] = cos(el) * cos(az);
            d[1] = cos(el) * sin(az);
            d[2] = sin(el);
        }
    return 0;
}

/* A plane wave from direction u reaches microphone m at -(m . u)/c relative to the centre;
 * pair (i, j) correlates best at lag tau_i - tau_j. */
static void make_lags(ssl_srp_t *s, const micarray_t *mics)
{
    double scale = (double)s->cfg.rate * UPSAMPLE / SPEED_OF_SOUND;
    for (int d = 0; d < s->ndirs; d++)
        for (int p = 0; p < s->npairs; p++) {
            const double *mi = mics->pos[s->pair[p][0]], *mj = mics->pos[s->pair[p][1]], *u = s->dirs[d];
            double diff = -((mi[0] - mj[0]) * u[0] + (mi[1] - mj[1]) * u[1] + (mi[2] - mj[2]) * u[2]);
            long l = lround(diff * scale);
            s->lag[d * s->npairs + p] = (int)((l % s->ncorr + s->ncorr) % s->ncorr);
        }
}

ssl_srp_t *ssl_srp_create(const ssl_srp_cfg_t *cfg, const micarray_t *mics)
{
    if (cfg->nfft < 64 || cfg->nfft > 8192 || (cfg->nfft & (cfg->nfft - 1)) || mics->n < 2 || cfg->rate < 4000)
        return marie_fail_null(EINVAL);
    ssl_srp_t *s = calloc(1, sizeof(*s));
    if (!s)
        return NULL;
    s->cfg = *cfg;
    s->nmics = mics->n;
    s->npairs = mics->n * (mics->n - 1) / 2;
    s->nbins = (int)cfg->nfft / 2 + 1;
    s->ncorr = (int)cfg->nfft * UPSAMPLE;
    s->kmin = (int)fmax(1, floor(F_MIN * cfg->nfft / cfg->rate));
    s->kmax = (int)fmin(s->nbins - 1, ceil(F_MAX * cfg->nfft / cfg->rate));
    s->pair = malloc(sizeof(*s->pair) * (size_t)s->npairs);
    if (!s->pair || make_grid(s))
        goto fail;
    for (int i = 0, p = 0; i < mics->n; i++)
        for (int j = i + 1; j < mics->n; j++, p++) {
            s->pair[p][0] = i;
            s->pair[p][1] = j;
        }
    s->noise = calloc((size_t)s->nbins, sizeof(float));
    s->phat = malloc(sizeof(float complex) * (size_t)s->npairs * (size_t)s->nbins);
    s->mics = malloc(sizeof(double) * 3 * (size_t)mics->n);
    if (s->mics)
        memcpy(s->mics, mics->pos, sizeof(double) * 3 * (size_t)mics->n);
    s->weight = calloc((size_t)s->nbins, sizeof(float));
    s->map = malloc(sizeof(float) * (size_t)s->ndirs);
    s->lag = malloc(sizeof(int) * (size_t)s->ndirs * (size_t)s->npairs);
    s->cross = fftwf_alloc_complex((size_t)s->ncorr / 2 + 1);
    s->corr = fftwf_alloc_real((size_t)s->ncorr * (size_t)s->npairs);
    if (!s->map || !s->lag || !s->cross || !s->corr || !s->noise || !s->weight || !s->phat || !s->mics)
        goto fail;
    s->plan = fftwf_plan_dft_c2r_1d(s->ncorr, s->cross, s->corr, FFTW_ESTIMATE);
    if (!s->plan)
        goto fail;
    make_lags(s, mics);
    return s;
fail:
    ssl_srp_destroy(s);
    return marie_fail_null(ENOMEM);
}

void ssl_srp_destroy(ssl_srp_t *s)
{
    if (!s)
        return;
    if (s->plan)
        fftwf_destroy_plan(s->plan);
    fftwf_free(s->cross);
    fftwf_free(s->corr);
    free(s->pair);
    free(s->dirs);
    free(s->map);
    free(s->lag);
    free(s->noise);
    free(s->weight);
    free(s->phat);
    free(s->mics);
    free(s);
}

/* Bins where the array hears little more than its steady noise carry no direction, yet PHAT
 * would weigh them as much as the loudest: each bin is weighed by how far its power stands
 * over the steady level (spectral subtraction with an over-subtraction, OVERSUB), so diffuse noise
 * and stationary sources such as fans fade out of the map and speech stands out. The level is
 * a running mean of the power that leaves out bursts over 3 times it (speech), and creeps up
 * under a lasting rise (a fan turned on). */
static void update_weights(ssl_srp_t *s, const float complex *const *X)
{
    s->frames++;
    for (int k = s->kmin; k <= s->kmax; k++) {
        float p = 0;
        for (int m = 0; m < s->nmics; m++)
            p += crealf(X[m][k]) * crealf(X[m][k]) + cimagf(X[m][k]) * cimagf(X[m][k]);
        p /= (float)s->nmics;
        float *n = &s->noise[k];
        if (s->frames <= 8)
            *n = s->frames == 1 ? p : *n + (p - *n) / (float)s->frames;
        else if (p < 3 * *n)
            *n += 0.05f * (p - *n);
        else
            *n *= 1.01f;
        float w = p > 0 ? 1 - (float)OVERSUB * *n / p : 0;
        s->weight[k] = w > 0 ? w : 0;
    }
}

/* Each pair's unit cross-spectrum (PHAT) of this frame, kept for the later potentials. */
static void cross_spectra(ssl_srp_t *s, const float complex *const *X)
{
    update_weights(s, X);
    for (int p = 0; p < s->npairs; p++) {
        const float complex *xi = X[s->pair[p][0]], *xj = X[s->pair[p][1]];
        float complex *ph = s->phat + (size_t)p * s->nbins;
        for (int k = s->kmin; k <= s->kmax; k++) {
            float complex c = xi[k] * conjf(xj[k]);
            float mag = cabsf(c);
            ph[k] = mag > 1e-20f ? c / mag : 0;
        }
    }
}

/* GCC-PHAT of every pair with the current bin weights into s->corr, then the map: a
 * perfectly coherent pair in bins far above the noise peaks at 1. */
static void srp_map(ssl_srp_t *s)
{
    int nb = s->ncorr / 2 + 1, used = s->kmax - s->kmin + 1;
    float scale = 0.5f / (float)used;
    for (int p = 0; p < s->npairs; p++) {
        const float complex *ph = s->phat + (size_t)p * s->nbins;
        memset(s->cross, 0, sizeof(float complex) * (size_t)nb);
        for (int k = s->kmin; k <= s->kmax; k++)
            s->cross[k] = ph[k] * (s->weight[k] * scale);
        fftwf_execute_dft_c2r(s->plan, s->cross, s->corr + (size_t)p * s->ncorr);
    }
    for (int d = 0; d < s->ndirs; d++) {
        const int *lag = s->lag + (size_t)d * s->npairs;
        float e = 0;
        for (int p = 0; p < s->npairs; p++)
            e += s->corr[(size_t)p * s->ncorr + lag[p]];
        s->map[d] = e / s->npairs;
    }
}

/* Bins that the found direction explains (their pairs' phases agree with it) are taken out
 * before the next search: what remains is another source, not this one's sidelobes. */
static void mask_explained(ssl_srp_t *s, const double *u)
{
    double tau[MICARRAY_MAX * (MICARRAY_MAX - 1) / 2];
    for (int p = 0; p < s->npairs; p++) {
        const double *mi = s->mics[s->pair[p][0]], *mj = s->mics[s->pair[p][1]];
        tau[p] = -((mi[0] - mj[0]) * u[0] + (mi[1] - mj[1]) * u[1] + (mi[2] - mj[2]) * u[2]) / SPEED_OF_SOUND;
    }
    for (int k = s->kmin; k <= s->kmax; k++) {
        if (s->weight[k] <= 0)
            continue;
        double w = 2 * M_PI * k * s->cfg.rate / s->cfg.nfft, coh = 0;
        for (int p = 0; p < s->npairs; p++) {
            float complex ph = s->phat[(size_t)p * s->nbins + k];
            coh += crealf(ph) * cos(w * tau[p]) - cimagf(ph) * sin(w * tau[p]);     /* Re(ph e^{jw tau}) */
        }
        if (coh / s->npairs > 0.3)
            s->weight[k] = 0;
    }
}

static int best_direction(const ssl_srp_t *s, const ssl_potential_t *found, int n)
{
    int best = -1;
    for (int d = 0; d < s->ndirs; d++) {
        if (best >= 0 && s->map[d] <= s->map[best])
            continue;
        int near = 0;
        for (int k = 0; k < n && !near; k++)
            near = fabs(remainder(atan2(s->dirs[d][1], s->dirs[d][0]) - found[k].azimuth, 2 * M_PI)) < MIN_SEPARATION;
        if (!near)
            best = d;
    }
    return best;
}

int ssl_srp_frame(ssl_srp_t *s, const float complex *const *spectra, ssl_potential_t *out, int max)
{
    cross_spectra(s, spectra);
    float saved[s->kmax + 1];
    memcpy(saved, s->weight, sizeof(float) * (size_t)(s->kmax + 1));
    int n = 0;
    while (n < max) {
        srp_map(s);
        int best = best_direction(s, out, n);
        if (best < 0)
            break;
        ssl_potential_t *o = &out[n++];
        memcpy(o->dir, s->dirs[best], sizeof(o->dir));
        o->azimuth = atan2(o->dir[1], o->dir[0]);
        o->elevation = asin(fmax(-1, fmin(1, o->dir[2])));
        o->energy = s->map[best];
        if (n < max)
            mask_explained(s, o->dir);
    }
    /* The weights stay this frame's. */
    memcpy(s->weight, saved, sizeof(float) * (size_t)(s->kmax + 1));
    return n;
}

int ssl_srp_directions(const ssl_srp_t *s)
{
    return s->ndirs;
}
