/* test_asr: the 20 command phrases, spoken by Festival's voice 2 m from the array with a fan
 * making the speech 5 dB over it, recognized by marie-asr's decoder on one raw microphone and
 * on marie-ssl's separated stream (accuracies printed and bounded); the VAD opens and closes
 * an utterance around speech; muting drops what is heard. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "adapters/asr/asr.h"
#include "hw/audio/wav.h"
#include "tests/audio/audio_scene_util.h"

#define DEG (M_PI / 180)
#define BLOCK 256

typedef struct {
    char text[256];
    double conf;
    int n;
} heard_t;

static void on_heard(const asr_result_t *r, void *user)
{
    heard_t *h = user;
    if (r->text[0] && !h->text[0]) {
        snprintf(h->text, sizeof(h->text), "%s", r->text);
        h->conf = r->confidence;
    }
    h->n++;
}

typedef struct {
    double bearing;
    int16_t *sep;
    size_t nsep, cap;
} grab_t;

static void on_sep(const ssl_result_t *r, void *user)
{
    grab_t *g = user;
    for (int i = 0; i < r->nstreams; i++) {
        if (fabs(ssl_wrap(r->streams[i].azimuth - g->bearing)) > 15 * DEG || g->nsep + BLOCK > g->cap)
            continue;
        for (int j = 0; j < BLOCK; j++)
            g->sep[g->nsep + j] = (int16_t)lrintf(fmaxf(-32768, fminf(32767, r->streams[i].samples[j] * 32768)));
        g->nsep += BLOCK;
        break;
    }
}

static void feed_all(asr_t *a, const int16_t *x, size_t n)
{
    for (size_t off = 0; off + BLOCK <= n; off += BLOCK)
        asr_feed(a, 1, x + off, BLOCK, (int64_t)(off * 1000000 / 16000));
    asr_flush(a, (int64_t)(n * 1000000 / 16000));
}

/* The speaker's stream out of marie-ssl's pipeline: tracked, or steered toward the known
 * bearing (as a face tracker would). */
static size_t separate(const float *x, size_t ns, int M, double bearing, bool steered, int16_t *out)
{
    grab_t g = { .bearing = bearing, .sep = out, .cap = ns };
    ssl_cfg_t scfg;
    ssl_cfg_default(&scfg);
    if (steered) {
        scfg.nfixed = 1;
        scfg.fixed[0][0] = bearing;
        scfg.fixed[0][1] = atan2(1.5 - 0.65, 2.0);
    }
    ssl_t *s = ssl_create(&scfg, on_sep, &g);
    for (size_t off = 0; off + BLOCK <= ns; off += BLOCK)
        ssl_feed_float(s, x + off * (size_t)M, M, BLOCK, (int64_t)(off * 1000000 / 16000));
    ssl_destroy(s);
    return g.nsep;
}

static void test_commands_raw_vs_separated(void **state)
{
    asr_cfg_t cfg;
    asr_cfg_default(&cfg, asr_default_commands, asr_default_ncommands, BLOCK);
    heard_t raw_h, sep_h;
    char why[256] = "";
    asr_t *raw = asr_create(&cfg, on_heard, &raw_h, why, sizeof(why));
    asr_t *sep = asr_create(&cfg, on_heard, &sep_h, why, sizeof(why));
    asr_t *steer = asr_create(&cfg, on_heard, &sep_h, why, sizeof(why));
    if (!raw || !sep)
        fprintf(stderr, "asr: %s\n", why);
    assert_non_null(raw);
    assert_non_null(sep);
    assert_non_null(steer);
    int ok_raw = 0, ok_sep = 0, ok_steer = 0, n = asr_default_ncommands;
    printf("# phrase | raw microphone | tracked and separated (stream length) | steered beam\n");
    for (int i = 0; i < n; i++) {
        double bearing = (-150 + 67 * i % 300) * DEG, fan_bearing = bearing + 100 * DEG;
        sim_audio_scene_t sc = { .n = 2, .snr_db = 30 };
        sc.src[0] = (sim_sound_t){ .kind = SIM_SOUND_SPEECH, .x = 2 * cos(bearing), .y = 2 * sin(bearing), .z = 1.5,
                                   .start = 0.8, .stop = -1, .level = 0.05 };
        snprintf(sc.src[0].file, sizeof(sc.src[0].file), "%s", audio_phrase(i + 1));
        /* The fan 2 m away: speech RMS over fan RMS at the array is 5 dB. */
        sc.src[1] = (sim_sound_t){ .kind = SIM_SOUND_FAN, .x = 2 * cos(fan_bearing), .y = 2 * sin(fan_bearing),
                                   .z = 0.65, .stop = -1, .level = 0.05 / pow(10, 5 / 20.0) * 2.0 / 2.0 };
        sim_audio_cfg_t acfg = { .rate = 16000, .block = BLOCK, .seed = 11 + (uint64_t)i };
        micarray_parse(MICARRAY_DEFAULT, &acfg.mics, NULL);
        sim_audio_t *a = sim_audio_create(&acfg, &sc, NULL, why, sizeof(why));
        assert_non_null(a);
        double dur = 0.8 + audio_phrase_frames(i + 1) / 16000.0 + 1.2;
        const double pose[3] = { 0, 0, 0 };
        size_t nv;
        float *x = audio_render(a, pose, 0, dur, BLOCK, &nv);
        int M = sim_audio_channels(a);
        size_t ns = nv / (size_t)M;
        int16_t *ch0 = malloc(sizeof(int16_t) * ns);
        for (size_t k = 0; k < ns; k++)
            ch0[k] = (int16_t)lrintf(fmaxf(-32768, fminf(32767, x[k * M] * 32768)));
        int16_t *tracked = calloc(ns, sizeof(int16_t)), *steered = calloc(ns, sizeof(int16_t));
        size_t ntracked = separate(x, ns, M, bearing, false, tracked);
        size_t nsteered = separate(x, ns, M, bearing, true, steered);
        heard_t st_h;
        memset(&raw_h, 0, sizeof(raw_h));
        memset(&sep_h, 0, sizeof(sep_h));
        feed_all(raw, ch0, ns);
        feed_all(sep, tracked, ntracked);
        st_h = sep_h;
        memset(&sep_h, 0, sizeof(sep_h));
        feed_all(steer, steered, nsteered);
        int r_ok = !strcmp(raw_h.text, asr_default_commands[i]), t_ok = !strcmp(st_h.text, asr_default_commands[i]);
        int s_ok = !strcmp(sep_h.text, asr_default_commands[i]);
        ok_raw += r_ok;
        ok_sep += t_ok;
        ok_steer += s_ok;
        printf("%-20s | %-20s %s | %-20s %s %.1f s | %-20s %s\n", asr_default_commands[i], raw_h.text, r_ok ? "ok" : "--",
               st_h.text, t_ok ? "ok" : "--", ntracked / 16000.0, sep_h.text, s_ok ? "ok" : "--");
        free(tracked);
        free(steered);
        free(ch0);
        free(x);
        sim_audio_destroy(a);
    }
    printf("# accuracy over %d commands at 5 dB SNR (fan): raw microphone %d/%d, tracked and separated %d/%d, "
           "steered beam %d/%d\n", n, ok_raw, n, ok_sep, n, ok_steer, n);
    /* Measured here: raw 2/20, tracked 18/20 (a short phrase can lose its start while its track
     * is being confirmed), steered 20/20. */
    assert_true(ok_steer >= 18);
    assert_true(ok_sep >= 16);
    assert_true(ok_sep >= ok_raw + 8);
    asr_destroy(raw);
    asr_destroy(sep);
    asr_destroy(steer);
}

static void test_vad_opens_and_closes_an_utterance(void **state)
{
    asr_vad_cfg_t c;
    asr_vad_cfg_default(&c, BLOCK / 16000.0);
    asr_vad_t v;
    asr_vad_init(&v, &c);
    int16_t quiet[BLOCK], loud[BLOCK];
    for (int i = 0; i < BLOCK; i++) {
        quiet[i] = (int16_t)((i * 7919) % 41 - 20);
        loud[i] = (int16_t)(3000 * sin(i * 0.3));
    }
    for (int i = 0; i < 50; i++)
        assert_int_equal(asr_vad_block(&v, quiet, BLOCK), ASR_VAD_SILENCE);
    assert_int_equal(asr_vad_block(&v, loud, BLOCK), ASR_VAD_SILENCE);
    assert_int_equal(asr_vad_block(&v, loud, BLOCK), ASR_VAD_SILENCE);
    assert_int_equal(asr_vad_block(&v, loud, BLOCK), ASR_VAD_START);
    for (int i = 0; i < 20; i++)
        assert_int_equal(asr_vad_block(&v, loud, BLOCK), ASR_VAD_SPEECH);
    int ends = 0, k = 0;
    while (k++ < 100 && asr_vad_block(&v, quiet, BLOCK) != ASR_VAD_END)
        ;
    ends = k;
    /* closes after the hangover (0.45 s = 28 blocks of 16 ms), not before */
    assert_true(ends >= 27 && ends <= 30);
    /* A stream that never stops is cut at the length limit. */
    asr_vad_init(&v, &c);
    int starts = 0, closes = 0;
    for (int i = 0; i < 1000; i++) {
        asr_vad_event_t e = asr_vad_block(&v, i < 10 ? quiet : loud, BLOCK);
        starts += e == ASR_VAD_START;
        closes += e == ASR_VAD_END;
    }
    assert_true(closes >= 1);
}

static void test_muted_hears_nothing(void **state)
{
    asr_cfg_t cfg;
    asr_cfg_default(&cfg, asr_default_commands, asr_default_ncommands, BLOCK);
    heard_t h = { 0 };
    char why[256];
    asr_t *a = asr_create(&cfg, on_heard, &h, why, sizeof(why));
    assert_non_null(a);
    size_t frames = 0;
    int rate;
    float *x = wav_load_mono(audio_phrase(5), &frames, &rate);
    assert_non_null(x);
    size_t n = frames + 16000;
    int16_t *pcm = calloc(n + 8000, sizeof(int16_t));
    for (size_t i = 0; i < n + 8000; i++)
        pcm[i] = (int16_t)((i * 7919) % 21 - 10);
    for (size_t i = 0; i < frames; i++)
        pcm[8000 + i] += (int16_t)(x[i] * 32767);
    asr_mute(a, true);
    feed_all(a, pcm, n + 8000);
    assert_int_equal(h.n, 0);
    asr_mute(a, false);
    feed_all(a, pcm, n + 8000);
    printf("# unmuted, clean: \"%s\" (confidence %.2f)\n", h.text, h.conf);
    assert_string_equal(h.text, "stop");
    free(pcm);
    free(x);
    asr_destroy(a);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_vad_opens_and_closes_an_utterance),
        cmocka_unit_test(test_muted_hears_nothing),
        cmocka_unit_test(test_commands_raw_vs_separated),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
