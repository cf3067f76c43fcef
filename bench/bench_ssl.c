/* bench_ssl: cost of marie-ssl's pipeline at 16 kHz x 8 channels on a two-speaker scene
 * rendered by the simulator's array: SRP-PHAT per frame, the whole pipeline (localization,
 * tracking, separation) as a share of one core against real time, and the simulator's cost
 * to render the array. Prints "bench metric value unit baseline ratio" rows. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench/bench.h"
#include "tests/audio/audio_scene_util.h"

#define DUR 10.0
#define BLOCK 256

static double cpu_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec + ts.tv_nsec / 1e9;
}

static long frames;
static void count(const ssl_result_t *r, void *u)
{
    frames++;
}

static double run_pipeline(const float *x, size_t n, int M, bool separate)
{
    ssl_cfg_t cfg;
    ssl_cfg_default(&cfg);
    cfg.sep.separate = separate;
    ssl_t *s = ssl_create(&cfg, count, NULL);
    frames = 0;
    double t = cpu_s();
    for (size_t off = 0; off + BLOCK <= n; off += BLOCK)
        ssl_feed_float(s, x + off * (size_t)M, M, BLOCK, (int64_t)(off * 1000000 / 16000));
    t = cpu_s() - t;
    ssl_destroy(s);
    return t;
}

int main(void)
{
    sim_audio_scene_t sc = { .n = 3, .snr_db = 10, .reflect = 0.5 };
    for (int i = 0; i < 2; i++) {
        double az = (30 + 60 * i) * M_PI / 180;
        sc.src[i] = (sim_sound_t){ .kind = SIM_SOUND_SPEECH, .x = 2 * cos(az), .y = 2 * sin(az), .z = 1.5,
                                   .start = 0.1 * i, .stop = -1, .every = 2.0, .level = 0.05 };
        snprintf(sc.src[i].file, sizeof(sc.src[i].file), "%s", audio_phrase(2 + 11 * i));
    }
    sc.src[2] = (sim_sound_t){ .kind = SIM_SOUND_FAN, .x = -2, .y = -1, .z = 0.5, .stop = -1, .level = 0.02 };
    sim_audio_cfg_t acfg = { .rate = 16000, .block = BLOCK, .seed = 3 };
    micarray_parse(MICARRAY_DEFAULT, &acfg.mics, NULL);
    char why[256] = "";
    sim_audio_t *a = sim_audio_create(&acfg, &sc, NULL, why, sizeof(why));
    if (!a) {
        fprintf(stderr, "bench_ssl: %s\n", why);
        return 1;
    }
    const double pose[3] = { 0, 0, 0 };
    size_t nv;
    double t = cpu_s();
    float *x = audio_render(a, pose, 0, DUR, BLOCK, &nv);
    double render = cpu_s() - t;
    int M = sim_audio_channels(a);
    size_t n = nv / (size_t)M;
    printf("bench\tmetric\tvalue\tunit\tbaseline\tratio\n");
    printf("# baselines: real time (one core for 1 s of audio), or the frame period (16 ms)\n");
    bench_row("bench_ssl", "sim_array_render_cpu", 100 * render / DUR, "% of one core", 100);

    /* SRP-PHAT alone: repeated calls on fixed spectra. */
    ssl_srp_cfg_t scfg;
    ssl_srp_cfg_default(&scfg);
    ssl_srp_t *srp = ssl_srp_create(&scfg, &acfg.mics);
    float complex *spec[MICARRAY_MAX];
    for (int m = 0; m < M; m++) {
        spec[m] = malloc(sizeof(float complex) * 257);
        for (int k = 0; k < 257; k++)
            spec[m][k] = (float)sin(k * 0.3 + m) + I * (float)cos(k * 0.7 - m);
    }
    ssl_potential_t pot[4];
    int reps = 500;
    t = cpu_s();
    for (int i = 0; i < reps; i++)
        ssl_srp_frame(srp, (const float complex *const *)spec, pot, 3);
    double srp_us = (cpu_s() - t) / reps * 1e6;
    char unit[64];
    snprintf(unit, sizeof unit, "us (28 pairs, %d directions)", ssl_srp_directions(srp));
    bench_row("bench_ssl", "srp_phat_per_frame", srp_us, unit, 16000);

    double loc = run_pipeline(x, n, M, false);
    double full = run_pipeline(x, n, M, true);
    bench_row("bench_ssl", "localize_track_cpu", 100 * loc / DUR, "% of one core at 16 kHz x 8", 100);
    bench_row("bench_ssl", "localize_track_separate_cpu", 100 * full / DUR, "% of one core at 16 kHz x 8", 100);
    bench_row("bench_ssl", "pipeline_per_frame", full / frames * 1e6, "us", 16000);
    for (int m = 0; m < M; m++)
        free(spec[m]);
    ssl_srp_destroy(srp);
    free(x);
    sim_audio_destroy(a);
    return 0;
}
