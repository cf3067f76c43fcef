/* audio_scene_util: what the audio tests and benchmarks share: phrase files made by the build,
 * and running a rendered scene through the ssl pipeline block by block. */
#ifndef MARIE_TESTS_AUDIO_SCENE_UTIL_H
#define MARIE_TESTS_AUDIO_SCENE_UTIL_H
#include "adapters/ssl/ssl.h"
#include "sim/audio.h"

/* Path of build/share/sounds/phrase_NN.wav (1-based, the line of sim/sounds/phrases.txt). */
const char *audio_phrase(int n);
size_t audio_phrase_frames(int n);     /* its length in samples at 16 kHz */

/* Renders [t0, t0 + dur) in blocks of `block` for a robot standing at pose and feeds s. */
void audio_run(sim_audio_t *a, ssl_t *s, const double pose[3], double t0, double dur, int block);

/* Renders [t0, t0 + dur) into a malloc'd interleaved buffer (M channels). */
float *audio_render(sim_audio_t *a, const double pose[3], double t0, double dur, int block, size_t *nsamples);

double audio_median(double *v, int n);
double audio_quantile(double *v, int n, double q);
#endif
