/* audio_scene_util: phrase files and scene runs shared by the audio tests and benchmarks. */
#include "tests/audio/audio_scene_util.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "hw/audio/wav.h"

const char *audio_phrase(int n)
{
    static char path[8][512];
    static int k;
    const char *b = getenv("B") ? getenv("B") : "build";
    char *p = path[k++ % 8];
    snprintf(p, 512, "%s/share/sounds/phrase_%02d.wav", b, n);
    return p;
}

size_t audio_phrase_frames(int n)
{
    size_t frames = 0;
    int rate;
    float *x = wav_load_mono(audio_phrase(n), &frames, &rate);
    free(x);
    return frames;
}

void audio_run(sim_audio_t *a, ssl_t *s, const double pose[3], double t0, double dur, int block)
{
    size_t n = 0;
    float *buf = audio_render(a, pose, t0, dur, block, &n);
    if (!buf)
        return;
    int M = sim_audio_channels(a), rate = ssl_rate(s);
    size_t total = n / (size_t)M;
    for (size_t off = 0; off + (size_t)block <= total; off += (size_t)block)
        ssl_feed_float(s, buf + off * (size_t)M, M, block,
                       (int64_t)llround(t0 * 1e6) + (int64_t)(off * 1000000 / (size_t)rate));
    free(buf);
}

float *audio_render(sim_audio_t *a, const double pose[3], double t0, double dur, int block, size_t *nvalues)
{
    int rate = 16000;
    size_t nb = (size_t)lround(dur * rate / block);
    size_t M = (size_t)sim_audio_channels(a);
    float *out = malloc(sizeof(float) * nb * (size_t)block * M);
    if (!out)
        return NULL;
    for (size_t k = 0; k < nb; k++) {
        int64_t t = (int64_t)llround(t0 * 1e6) + (int64_t)(k * (size_t)block * 1000000 / (size_t)rate);
        sim_audio_render_float(a, t, pose, out + k * (size_t)block * M);
    }
    *nvalues = nb * (size_t)block * M;
    return out;
}

static int cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

double audio_quantile(double *v, int n, double q)
{
    if (n <= 0)
        return NAN;
    qsort(v, (size_t)n, sizeof(double), cmp);
    int i = (int)floor(q * (n - 1) + 0.5);
    return v[i];
}

double audio_median(double *v, int n)
{
    return audio_quantile(v, n, 0.5);
}
