/* ssl_sep: separation of tracked sources: a geometric (LCMV) beamformer per frequency with
 * unit gain toward its source and nulls toward the other tracked sources, then a Wiener
 * post-filter against stationary noise. */
#ifndef MARIE_SSL_SEP_H
#define MARIE_SSL_SEP_H
#include <complex.h>
#include <stdbool.h>

#include "adapters/ssl/ssl_sep_params.h"
#include "hw/audio/micarray.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ssl_sep_cfg_t (ssl_sep.params.yaml): separate (the pipeline beams the tracked sources at all),
 * nulls (false: plain delay-and-sum toward each source), postfilter. */

void ssl_sep_cfg_default(ssl_sep_cfg_t *c);

/* Beam of source k of the n directions dirs[] (unit vectors, robot frame) from spectra
 * X[m][bin] (nbins = nfft/2 + 1) into Y[bin]. */
void ssl_sep_beam(const ssl_sep_cfg_t *cfg, const micarray_t *mics, int rate, int nfft,
                  const float complex *const *X, const double (*dirs)[3], int n, int k, float complex *Y);

/* Per-stream post-filter state. */
typedef struct {
    int nbins;
    float *noise;               /* noise power per bin */
    float *prev_snr;
    int frames;
} ssl_postfilter_t;

int ssl_postfilter_init(ssl_postfilter_t *p, int nbins);        /* 0 or -1 (ENOMEM) */
void ssl_postfilter_free(ssl_postfilter_t *p);
void ssl_postfilter_apply(ssl_postfilter_t *p, const ssl_sep_cfg_t *cfg, float complex *Y);

#ifdef __cplusplus
}
#endif
#endif
