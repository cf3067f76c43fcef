/* test_ssl: marie-ssl's pipeline on scenes rendered by the simulator's array: a Festival
 * phrase at known bearings and SNRs is localized (error distribution printed and bounded),
 * two speakers 60 degrees apart are two tracks, a walking speaker is followed, the separated
 * streams gain SIR and SNR over one microphone, and a new stream starts before the words. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "hw/audio/wav.h"
#include "map/occmap.h"
#include "tests/audio/audio_scene_util.h"

#define DEG (M_PI / 180)
#define BLOCK 256

typedef struct {
    double true_az[2];          /* per source; NAN when unused */
    double t_on, t_off;         /* frames in [t_on, t_off) are scored */
    double *err;                /* per-frame error of the best potential, rad */
    int nerr, cap, frames;
    int ids_seen[32], nids;
    /* confirmed tracks in the last result */
    int ntracks;
    double track_az[SSL_TRACK_MAX];
    int track_id[SSL_TRACK_MAX];
    double min_energy;
} collect_t;

static void on_result(const ssl_result_t *r, void *user)
{
    collect_t *c = user;
    double t = r->utime / 1e6;
    if (t >= c->t_on && t < c->t_off) {
        c->frames++;
        if (r->npot > 0 && r->pot[0].energy >= c->min_energy && c->nerr < c->cap) {
            double best = 1e9;
            for (int s = 0; s < 2; s++)
                if (!isnan(c->true_az[s]))
                    best = fmin(best, fabs(ssl_wrap(r->pot[0].azimuth - c->true_az[s])));
            c->err[c->nerr++] = best;
        }
    }
    c->ntracks = 0;
    for (int i = 0; i < r->tracker->n; i++) {
        const ssl_track_t *tr = &r->tracker->t[i];
        if (!tr->confirmed)
            continue;
        c->track_az[c->ntracks] = tr->azimuth;
        c->track_id[c->ntracks++] = tr->id;
        int known = 0;
        for (int k = 0; k < c->nids; k++)
            known |= c->ids_seen[k] == tr->id;
        if (!known && c->nids < 32)
            c->ids_seen[c->nids++] = tr->id;
    }
}

static sim_audio_t *scene(const sim_audio_scene_t *sc, const occmap_t *map, const double pose[3])
{
    sim_audio_cfg_t cfg = { .rate = 16000, .block = BLOCK, .seed = 7 };
    micarray_parse(MICARRAY_DEFAULT, &cfg.mics, NULL);
    memcpy(cfg.start_pose, pose, sizeof(cfg.start_pose));
    char why[256] = "";
    sim_audio_t *a = sim_audio_create(&cfg, sc, map, why, sizeof(why));
    if (!a)
        fprintf(stderr, "scene: %s\n", why);
    return a;
}

static sim_sound_t speech_at(int phrase, double az, double dist, double start)
{
    sim_sound_t s = { .kind = SIM_SOUND_SPEECH, .x = dist * cos(az), .y = dist * sin(az), .z = 1.5,
                      .start = start, .stop = -1, .level = 0.05 };
    snprintf(s.file, sizeof(s.file), "%s", audio_phrase(phrase));
    return s;
}

/* One phrase at each of 12 bearings, 2 m away, at one SNR; returns the per-frame errors. */
static int localize_sweep(double snr, const occmap_t *map, const double pose[3], double reflect,
                          double *err, int cap, int *tracked_ok, double *track_err, int *frames)
{
    int n = 0;
    *frames = 0;
    *tracked_ok = 0;
    double plen = audio_phrase_frames(2) / 16000.0;
    for (int k = 0; k < 12; k++) {
        double az = k * 30 * DEG;
        sim_audio_scene_t sc = { .n = 1, .snr_db = snr, .reflect = reflect };
        sc.src[0] = speech_at(2, az + pose[2], 2.0, 0.2);
        sc.src[0].x += pose[0];
        sc.src[0].y += pose[1];
        sim_audio_t *a = scene(&sc, map, pose);
        assert_non_null(a);
        ssl_cfg_t cfg;
        ssl_cfg_default(&cfg);
        collect_t c = { .true_az = { az, NAN }, .t_on = 0.2, .t_off = 0.2 + plen, .err = err + n,
                        .cap = cap - n, .min_energy = cfg.track.min_energy };
        ssl_t *s = ssl_create(&cfg, on_result, &c);
        assert_non_null(s);
        audio_run(a, s, pose, 0, 0.3 + plen, BLOCK);
        n += c.nerr;
        *frames += c.frames;
        if (c.ntracks == 1) {
            track_err[k] = fabs(ssl_wrap(c.track_az[0] - az));
            *tracked_ok += track_err[k] < 10 * DEG;
        } else {
            track_err[k] = M_PI;
        }
        ssl_destroy(s);
        sim_audio_destroy(a);
    }
    return n;
}

static void test_localization_over_bearings_and_snr(void **state)
{
    static const double snrs[] = { 20, 10, 5, 0 };
    double *err = malloc(sizeof(double) * 20000), terr[12];
    const double pose[3] = { 0, 0, 0 };
    printf("# SRP-PHAT per-frame error of the strongest direction, phrase at 2 m, 12 bearings, anechoic\n");
    printf("# snr_db frames_with_a_peak/frames_of_the_phrase median_deg p90_deg tracked_within_10deg track_median_deg\n");
    for (int i = 0; i < 4; i++) {
        int ok, frames, n = localize_sweep(snrs[i], NULL, pose, 0, err, 20000, &ok, terr, &frames);
        double med = audio_median(err, n) / DEG, p90 = audio_quantile(err, n, 0.9) / DEG;
        double tmed = audio_median(terr, 12) / DEG;
        printf("%g %d/%d %.2f %.2f %d/12 %.2f\n", snrs[i], n, frames, med, p90, ok, tmed);
        /* Every bearing gives peaks, and tracks, down to 0 dB. */
        assert_true(n >= 12 * 4);
        assert_true(ok >= 10);
        if (snrs[i] >= 10) {
            /* The goal at 10 dB: median under 5 degrees, p90 under 10. */
            assert_true(med < 5);
            assert_true(p90 < 10);
            assert_int_equal(ok, 12);
        }
    }
    free(err);
}

static void test_localization_in_a_room_with_reflections(void **state)
{
    marie_errors_t errs = { 0 };
    occmap_t *map = occmap_load("sim/worlds/test.yaml", &errs);
    marie_errors_clear(&errs);
    assert_non_null(map);
    double *err = malloc(sizeof(double) * 20000), terr[12];
    const double pose[3] = { 3.5, 2.5, 0.3 };
    int ok, frames, n = localize_sweep(10, map, pose, 0.6, err, 20000, &ok, terr, &frames);
    double med = audio_median(err, n) / DEG, p90 = audio_quantile(err, n, 0.9) / DEG;
    printf("# room (sim/worlds/test, walls reflect 0.6), 10 dB: frames with a peak %d/%d, median %.2f p90 %.2f deg, "
           "tracked %d/12\n", n, frames, med, p90, ok);
    assert_true(med < 10);
    assert_true(ok >= 10);
    free(err);
    occmap_destroy(map);
}

static void test_two_speakers_60_degrees_apart_are_two_tracks(void **state)
{
    const double pose[3] = { 0, 0, 0 };
    sim_audio_scene_t sc = { .n = 2, .snr_db = 20 };
    sc.src[0] = speech_at(2, 30 * DEG, 2.0, 0.1);
    sc.src[1] = speech_at(13, 90 * DEG, 2.0, 0.3);
    sc.src[0].every = sc.src[1].every = 2.0;
    sim_audio_t *a = scene(&sc, NULL, pose);
    assert_non_null(a);
    ssl_cfg_t cfg;
    ssl_cfg_default(&cfg);
    double err[4096];
    collect_t c = { .true_az = { 30 * DEG, 90 * DEG }, .t_on = 0.3, .t_off = 4, .err = err, .cap = 4096,
                    .min_energy = cfg.track.min_energy };
    ssl_t *s = ssl_create(&cfg, on_result, &c);
    audio_run(a, s, pose, 0, 4.0, BLOCK);
    printf("# two speakers at 30 and 90 deg: %d confirmed tracks at the end, %d ids over the run\n", c.ntracks, c.nids);
    for (int i = 0; i < c.ntracks; i++)
        printf("#   track %d at %.1f deg\n", c.track_id[i], c.track_az[i] / DEG);
    assert_int_equal(c.ntracks, 2);
    double e0 = fmin(fabs(ssl_wrap(c.track_az[0] - 30 * DEG)), fabs(ssl_wrap(c.track_az[0] - 90 * DEG)));
    double e1 = fmin(fabs(ssl_wrap(c.track_az[1] - 30 * DEG)), fabs(ssl_wrap(c.track_az[1] - 90 * DEG)));
    assert_true(e0 < 8 * DEG && e1 < 8 * DEG);
    assert_true(fabs(ssl_wrap(c.track_az[0] - c.track_az[1])) > 40 * DEG);
    assert_true(c.nids <= 3);
    ssl_destroy(s);
    sim_audio_destroy(a);
}

typedef struct {
    sim_audio_t *a;
    double t_last;
    double worst_late, sum_err;
    int scored, last_id, id_changes, with_track;
} follow_t;

static void on_follow(const ssl_result_t *r, void *user)
{
    follow_t *f = user;
    double t = r->utime / 1e6, truth[3];
    sim_audio_source_at(f->a, 0, t, truth);
    double az = atan2(truth[1], truth[0]);
    for (int i = 0; i < r->tracker->n; i++) {
        const ssl_track_t *tr = &r->tracker->t[i];
        if (!tr->confirmed)
            continue;
        if (f->last_id && tr->id != f->last_id)
            f->id_changes++;
        f->last_id = tr->id;
        f->with_track++;
        if (t > 1.0) {
            double e = fabs(ssl_wrap(tr->azimuth - az));
            f->worst_late = fmax(f->worst_late, e);
            f->sum_err += e;
            f->scored++;
        }
        break;
    }
}

static void test_walking_speaker_is_followed(void **state)
{
    const double pose[3] = { 0, 0, 0 };
    /* From straight ahead at 2 m to 90 degrees left, walking 0.6 m/s on a 2 m circle's chord. */
    sim_audio_scene_t sc = { .n = 1, .snr_db = 15 };
    sc.src[0] = speech_at(14, 0, 2.0, 0.1);
    sc.src[0].vx = -0.42;
    sc.src[0].vy = 0.42;
    sc.src[0].every = audio_phrase_frames(14) / 16000.0 + 0.1;
    sc.src[0].stop = 4.8;
    sim_audio_t *a = scene(&sc, NULL, pose);
    assert_non_null(a);
    ssl_cfg_t cfg;
    ssl_cfg_default(&cfg);
    follow_t f = { .a = a };
    ssl_t *s = ssl_create(&cfg, on_follow, &f);
    audio_run(a, s, pose, 0, 4.8, BLOCK);
    double end[3];
    sim_audio_source_at(a, 0, 4.7, end);
    printf("# walking speaker 0 -> %.0f deg: mean error %.2f deg, worst %.2f deg after 1 s, %d id changes\n",
           atan2(end[1], end[0]) / DEG, f.sum_err / fmax(1, f.scored) / DEG, f.worst_late / DEG, f.id_changes);
    assert_true(atan2(end[1], end[0]) > 80 * DEG);
    assert_true(f.scored > 100);
    assert_true(f.sum_err / f.scored < 5 * DEG);
    assert_true(f.worst_late < 15 * DEG);
    assert_int_equal(f.id_changes, 0);
    ssl_destroy(s);
    sim_audio_destroy(a);
}

/* ---- a new stream's onset -------------------------------------------------------------- */

typedef struct {
    int id;                     /* the first stream's source, 0 before it */
    double first_sample, birth; /* s */
} onset_t;

static void on_onset(const ssl_result_t *r, void *user)
{
    onset_t *o = user;
    if (o->id || r->nstreams == 0)
        return;
    o->id = r->streams[0].id;
    o->birth = r->stream_utime / 1e6;
    o->first_sample = o->birth - (double)r->streams[0].nhistory * BLOCK / 16000;
}

static double power(const float *x, size_t n, size_t skip);

/* When the words start, in the phrase file: the first 10 ms with 1% of the loudest 10 ms's power. */
static double phrase_onset(int phrase)
{
    size_t n = 0;
    int rate;
    float *x = wav_load_mono(audio_phrase(phrase), &n, &rate);
    assert_non_null(x);
    double peak = 0, onset = 0;
    for (int pass = 0; pass < 2; pass++)
        for (size_t i = 0; i + 160 <= n; i += 160) {
            double e = power(x + i, 160, 0);
            peak = pass == 0 ? fmax(peak, e) : peak;
            if (pass == 1 && e > 0.01 * peak) {
                onset = (double)i / rate;
                break;
            }
        }
    free(x);
    return onset;
}

/* A track is born a few frames into the words; its stream must still start before them (the
 * recognizer needs the first syllable, and the quiet before it to measure its floor). */
static void test_new_stream_starts_before_the_words(void **state)
{
    const double pose[3] = { 0, 0, 0 };
    sim_audio_scene_t sc = { .n = 1, .snr_db = 10 };
    sc.src[0] = speech_at(2, 60 * DEG, 2.0, 1.0);
    sim_audio_t *a = scene(&sc, NULL, pose);
    assert_non_null(a);
    ssl_cfg_t cfg;
    ssl_cfg_default(&cfg);
    onset_t o = { 0 };
    ssl_t *s = ssl_create(&cfg, on_onset, &o);
    assert_non_null(s);
    audio_run(a, s, pose, 0, 1.0 + audio_phrase_frames(2) / 16000.0, BLOCK);
    double words = 1.0 + phrase_onset(2) + 2.0 / 343;
    printf("# words start at %.3f s, the track is born at %.3f s, its stream starts at %.3f s\n", words, o.birth,
           o.first_sample);
    assert_true(o.id > 0);
    assert_true(o.first_sample <= words - 0.1);
    ssl_destroy(s);
    sim_audio_destroy(a);
}

/* ---- separation ------------------------------------------------------------------------ */

typedef struct {
    float *out[2];
    size_t n, cap;
} sep_t;

static void on_sep(const ssl_result_t *r, void *user)
{
    sep_t *s = user;
    if (s->n + BLOCK > s->cap)
        return;
    for (int i = 0; i < r->nstreams; i++)
        memcpy(s->out[r->streams[i].id - 1] + s->n, r->streams[i].samples, sizeof(float) * BLOCK);
    s->n += BLOCK;
}

/* Beams toward dirs (fixed) over one rendered part of the scene; stream k's output. */
static void beam_part(sim_audio_t *a, const double pose[3], const double dirs[2][2], bool nulls, bool pf,
                      float **out, size_t *n, double dur)
{
    ssl_cfg_t cfg;
    ssl_cfg_default(&cfg);
    cfg.nfixed = 2;
    memcpy(cfg.fixed, dirs, sizeof(double) * 4);
    cfg.sep.nulls = nulls;
    cfg.sep.postfilter = pf;
    size_t cap = (size_t)(dur * 16000) + BLOCK;
    sep_t s = { .out = { calloc(cap, sizeof(float)), calloc(cap, sizeof(float)) }, .cap = cap };
    ssl_t *p = ssl_create(&cfg, on_sep, &s);
    audio_run(a, p, pose, 0, dur, BLOCK);
    ssl_destroy(p);
    out[0] = s.out[0];
    out[1] = s.out[1];
    *n = s.n;
}

static double power(const float *x, size_t n, size_t skip)
{
    double e = 0;
    for (size_t i = skip; i < n; i++)
        e += (double)x[i] * x[i];
    return e / (double)(n - skip);
}

static double channel_power(const float *x, size_t nvalues, int M, int ch)
{
    double e = 0;
    size_t n = nvalues / (size_t)M;
    for (size_t i = 0; i < n; i++)
        e += (double)x[i * M + ch] * x[i * M + ch];
    return e / (double)n;
}

static void test_separation_gains_sir_and_snr(void **state)
{
    const double pose[3] = { 0, 0, 0 };
    const double dirs[2][2] = { { 30 * DEG, atan2(1.5 - 0.65, 2.0) }, { 90 * DEG, atan2(1.5 - 0.65, 2.0) } };
    sim_audio_scene_t sc = { .n = 2, .snr_db = 10 };
    sc.src[0] = speech_at(2, 30 * DEG, 2.0, 0.0);
    sc.src[1] = speech_at(13, 90 * DEG, 2.0, 0.0);
    sc.src[0].every = sc.src[1].every = 1.5;
    sim_audio_t *a = scene(&sc, NULL, pose);
    assert_non_null(a);
    const double dur = 3.0;
    int M = sim_audio_channels(a);
    /* Each part alone through the same (fixed, linear) beams: the output's share of each. */
    double in_p[3], out_p[2][3][2];     /* [nulls?][part: A, B, noise][beam] */
    for (int part = 0; part < 3; part++) {
        sim_audio_set_mask(a, part < 2 ? 1u << part : 0, part == 2);
        size_t nv;
        float *raw = audio_render(a, pose, 0, dur, BLOCK, &nv);
        in_p[part] = 0;
        for (int m = 0; m < M; m++)
            in_p[part] += channel_power(raw, nv, M, m) / M;
        free(raw);
        for (int nulls = 0; nulls < 2; nulls++) {
            float *out[2];
            size_t n;
            beam_part(a, pose, dirs, nulls, false, out, &n, dur);
            for (int b = 0; b < 2; b++) {
                out_p[nulls][part][b] = power(out[b], n, 512);
                free(out[b]);
            }
        }
    }
    double sir_in = 10 * log10(in_p[0] / in_p[1]);
    printf("# separation, speakers at 30 and 90 deg, 2 m, diffuse noise 10 dB: input SIR (A over B) %.2f dB, "
           "SNR %.2f dB per microphone\n", sir_in, 10 * log10(in_p[0] / in_p[2]));
    for (int nulls = 0; nulls < 2; nulls++) {
        double sir_a = 10 * log10(out_p[nulls][0][0] / out_p[nulls][1][0]) - sir_in;
        double sir_b = 10 * log10(out_p[nulls][1][1] / out_p[nulls][0][1]) + sir_in;
        double snr_a = 10 * log10(out_p[nulls][0][0] / out_p[nulls][2][0]) - 10 * log10(in_p[0] / in_p[2]);
        printf("#   %s: SIR gain %.2f dB (beam A), %.2f dB (beam B); SNR gain %.2f dB (beam A)\n",
               nulls ? "geometric beams (nulls)" : "delay-and-sum", sir_a, sir_b, snr_a);
        if (nulls) {
            assert_true(sir_a > 10 && sir_b > 10);
            assert_true(snr_a > 0);
        } else {
            assert_true(sir_a > 2 && sir_b > 2);
            assert_true(snr_a > 3);
        }
    }
    sim_audio_destroy(a);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_localization_over_bearings_and_snr),
        cmocka_unit_test(test_localization_in_a_room_with_reflections),
        cmocka_unit_test(test_two_speakers_60_degrees_apart_are_two_tracks),
        cmocka_unit_test(test_walking_speaker_is_followed),
        cmocka_unit_test(test_separation_gains_sir_and_snr),
        cmocka_unit_test(test_new_stream_starts_before_the_words),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
