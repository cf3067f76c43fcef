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
    char text[256], last[256];  /* the first and the last thing heard */
    double conf;
    int n, source, last_source;
} heard_t;

static void on_heard(const asr_result_t *r, void *user)
{
    heard_t *h = user;
    if (r->text[0] && !h->text[0]) {
        snprintf(h->text, sizeof(h->text), "%s", r->text);
        h->conf = r->confidence;
        h->source = r->source_id;
    }
    if (r->text[0]) {
        snprintf(h->last, sizeof(h->last), "%s", r->text);
        h->last_source = r->source_id;
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
        const ssl_stream_t *st = &r->streams[i];
        if (fabs(ssl_wrap(st->azimuth - g->bearing)) > 15 * DEG || g->nsep + (size_t)(st->nhistory + 1) * BLOCK > g->cap)
            continue;
        for (int h = 0; h <= st->nhistory; h++) {   /* a new stream's onset first */
            const float *x = h < st->nhistory ? st->history + h * BLOCK : st->samples;
            for (int j = 0; j < BLOCK; j++)
                g->sep[g->nsep + j] = (int16_t)lrintf(fmaxf(-32768, fminf(32767, x[j] * 32768)));
            g->nsep += BLOCK;
        }
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
    assert_true(ok_sep >= 18);     /* measured 20/20; 17/20 while a new stream lost the words' onset */
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

/* A phrase file at 16 kHz as int16, with `pad` samples of quiet noise before and after. */
static int16_t *phrase_pcm(const char *path, size_t pad, double gain, size_t *n)
{
    size_t frames = 0;
    int rate;
    float *x = wav_load_mono(path, &frames, &rate);
    assert_non_null(x);
    *n = (frames + 2 * pad) / BLOCK * BLOCK;
    int16_t *pcm = calloc(*n + BLOCK, sizeof(int16_t));
    for (size_t i = 0; i < *n; i++)
        pcm[i] = (int16_t)((i * 7919) % 21 - 10);
    for (size_t i = 0; i < frames && pad + i < *n; i++)
        pcm[pad + i] += (int16_t)(x[i] * 32767 * gain);
    free(x);
    return pcm;
}

static asr_t *recognizer(heard_t *h)
{
    asr_cfg_t cfg;
    asr_cfg_default(&cfg, asr_default_commands, asr_default_ncommands, BLOCK);
    char why[256] = "";
    asr_t *a = asr_create(&cfg, on_heard, h, why, sizeof(why));
    if (!a)
        fprintf(stderr, "asr: %s\n", why);
    assert_non_null(a);
    return a;
}

/* A track that dies mid-phrase (its stream just stops) must not hold the decoder: the next
 * speaker, on another stream, is heard. */
static void test_stream_that_ends_mid_utterance_frees_the_decoder(void **state)
{
    heard_t h = { 0 };
    asr_t *a = recognizer(&h);
    size_t n1, n2;
    int16_t *first = phrase_pcm(audio_phrase(2), 8000, 1, &n1), *second = phrase_pcm(audio_phrase(5), 8000, 1, &n2);
    int64_t t = 0;
    for (size_t off = 0; off + BLOCK <= 8000 + (n1 - 16000) * 4 / 5; off += BLOCK, t += 16000)   /* stops mid-phrase */
        asr_feed(a, 7, first + off, BLOCK, t);
    for (size_t off = 0; off + BLOCK <= n2; off += BLOCK, t += 16000)
        asr_feed(a, 8, second + off, BLOCK, t);
    printf("# after a stream ended mid-phrase: \"%s\" from source %d (%d results)\n", h.last, h.last_source, h.n);
    assert_string_equal(h.last, "stop");
    assert_int_equal(h.last_source, 8);
    free(first);
    free(second);
    asr_destroy(a);
}

/* marie-asr's input=array feeds source id -1. */
static void test_source_minus_one_is_heard(void **state)
{
    heard_t h = { 0 };
    asr_t *a = recognizer(&h);
    size_t n;
    int16_t *pcm = phrase_pcm(audio_phrase(5), 8000, 1, &n);
    for (size_t off = 0; off + BLOCK <= n; off += BLOCK)
        asr_feed(a, -1, pcm + off, BLOCK, (int64_t)(off * 1000000 / 16000));
    assert_string_equal(h.text, "stop");
    free(pcm);
    asr_destroy(a);
}

/* At the speaker's onset the fan's stream (the fan plus what leaks of the voice) opens its
 * detector first, as the fan's track was just born: the speaker's stream must win. */
static void test_speech_stream_wins_over_the_fan(void **state)
{
    heard_t h = { 0 };
    asr_t *a = recognizer(&h);
    size_t n;
    int16_t *voice = phrase_pcm(audio_phrase(2), 8000, 1, &n);
    int16_t *fan = calloc(n, sizeof(int16_t)), *speaker = calloc(n, sizeof(int16_t));
    uint32_t rng = 1;
    double lp = 0;
    for (size_t i = 0; i < n; i++) {
        rng = rng * 1664525u + 1013904223u;
        lp = 0.7 * lp + 0.3 * ((double)(rng >> 8) / (1 << 24) - 0.5);
        double f = lp * (i < 8000 - 3 * BLOCK ? 300 : 6000) + 800 * sin(2 * M_PI * 100 * i / 16000.0);
        fan[i] = (int16_t)fmax(-32768, fmin(32767, f + 0.15 * voice[i]));
        speaker[i] = (int16_t)fmax(-32768, fmin(32767, voice[i] + 0.15 * f));
    }
    for (size_t off = 0; off + BLOCK <= n; off += BLOCK) {
        int64_t t = (int64_t)(off * 1000000 / 16000);
        asr_feed(a, 3, fan + off, BLOCK, t);
        asr_feed(a, 4, speaker + off, BLOCK, t);
    }
    asr_flush(a, (int64_t)(n * 1000000 / 16000));
    printf("# fan and speaker: \"%s\" from source %d\n", h.text, h.source);
    assert_string_equal(h.text, "go to room b");
    assert_int_equal(h.source, 4);
    free(voice);
    free(fan);
    free(speaker);
    asr_destroy(a);
}

static const char *voice_file(const char *kind, int v, int i)
{
    static char path[512];
    snprintf(path, sizeof(path), "%s/share/voices/%s_%d_%02d.wav", getenv("B") ? getenv("B") : "build", kind, v, i);
    return path;
}

/* Phrases out of the grammar in espeak-ng's voices, and a fan, come out under 0.5; the
 * commands in the same voices mostly over it (the confidence was always 1). */
static void test_confidence_refuses_what_is_not_a_command(void **state)
{
    heard_t h;
    asr_t *a = recognizer(&h);
    int in = 0, in_ok = 0, out = 0, out_ok = 0;
    for (int v = 0; v < 6; v += 1)
        for (int i = 0; i < 20; i += 3) {
            size_t n;
            bool cmd = i < 16 && (i / 3 + v) % 2 == 0;
            int16_t *pcm = phrase_pcm(voice_file(cmd ? "cmd" : "oog", v, i % 16), 8000, 1, &n);
            memset(&h, 0, sizeof(h));
            feed_all(a, pcm, n);
            in += cmd;
            in_ok += cmd && h.conf >= 0.5 && !strcmp(h.text, asr_default_commands[i]);
            out += !cmd;
            out_ok += !cmd && h.text[0] && h.conf >= 0.5;
            free(pcm);
        }
    printf("# espeak-ng, clean (confidence >= 0.5): commands accepted %d/%d, other phrases accepted %d/%d\n", in_ok, in, out_ok, out);
    /* Measured: 1/24 and 6/18 (clean espeak-ng over near-silence is far from the model: the
     * score and the narrow-beam check that keep other phrases out also refuse most commands
     * here; in the room, from the array, 20 of 25: test_asr_continuous, docs/audio.md) */
    assert_true(out_ok * 10 <= out);
    assert_true(in_ok * 6 >= in);
    asr_destroy(a);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_vad_opens_and_closes_an_utterance),
        cmocka_unit_test(test_muted_hears_nothing),
        cmocka_unit_test(test_commands_raw_vs_separated),
        cmocka_unit_test(test_stream_that_ends_mid_utterance_frees_the_decoder),
        cmocka_unit_test(test_source_minus_one_is_heard),
        cmocka_unit_test(test_speech_stream_wins_over_the_fan),
        cmocka_unit_test(test_confidence_refuses_what_is_not_a_command),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
