/* ssl_srp: SRP-PHAT localization: GCC-PHAT of every microphone pair (FFTW, interpolated by
 * zero padding) summed over a grid of directions; the best directions are the potential
 * sources of a frame. */
#ifndef MARIE_SSL_SRP_H
#define MARIE_SSL_SRP_H
#include <complex.h>

#include "adapters/ssl/ssl_srp_params.h"
#include "hw/audio/micarray.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double azimuth, elevation;  /* rad, robot frame */
    double dir[3];
    double energy;              /* mean PHAT coherence over pairs, about 0 (noise) to 1 */
} ssl_potential_t;

/* ssl_srp_cfg_t (ssl_srp.params.yaml): rate and nfft (the spectra handed to ssl_srp_frame have
 * nfft/2 + 1 bins), and how many potentials the pipeline takes from each frame. */
void ssl_srp_cfg_default(ssl_srp_cfg_t *c);

typedef struct ssl_srp ssl_srp_t;

ssl_srp_t *ssl_srp_create(const ssl_srp_cfg_t *cfg, const micarray_t *mics);   /* NULL + errno */
void ssl_srp_destroy(ssl_srp_t *s);

/* spectra[m][k]: microphone m, bin k (nfft/2 + 1 bins). Writes up to max potentials, best
 * first, and returns how many. */
int ssl_srp_frame(ssl_srp_t *s, const float complex *const *spectra, ssl_potential_t *out, int max);

int ssl_srp_directions(const ssl_srp_t *s);

#ifdef __cplusplus
}
#endif
#endif
