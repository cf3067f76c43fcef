/* asr_eval: a continuous scene through marie-ssl and marie-asr, scored (see asr_eval.h). */
#include "tests/audio/asr_eval.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "adapters/asr/asr.h"
#include "adapters/ssl/ssl.h"
#include "core/file.h"
#include "hw/audio/wav.h"

#define BLOCK 256
#define DEG (M_PI / 180)

typedef struct {
    asr_eval_t *e;
    asr_t *asr;
    double min_conf;
    bool verbose;
    int16_t pcm[BLOCK];
} run_t;

static bool known_kind(const char *k)
{
    static const char *const kinds[] = { "command", "oog", "real", "noise", "fan" };
    for (size_t i = 0; i < sizeof(kinds) / sizeof(kinds[0]); i++)
        if (!strcmp(k, kinds[i]))
            return true;
    return false;
}

static int load_truth(const char *tsv, asr_eval_t *e)
{
    size_t len;
    char *text = marie_file_read(tsv, 1 << 22, &len);
    if (!text)
        return -1;
    e->nevents = 0;
    int lineno = 0;
    for (char *next = text, *line; (line = strsep(&next, "\n"));) {
        lineno++;
        asr_eval_event_t *v = &e->ev[e->nevents];
        double deg;
        if (line[0] == '#' || !line[0])
            continue;
        if (e->nevents == ASR_EVAL_MAX_EVENTS ||
            sscanf(line, "%lf\t%lf\t%15[^\t]\t%159[^\t]\t%lf", &v->start, &v->end, v->kind, v->text, &deg) != 5 ||
            !(v->end >= v->start) || !known_kind(v->kind)) {
            /* a hand-written file: say where it is wrong, use the rest */
            if (e->bad_lines++ < 5)
                fprintf(stderr, "%s:%d:1: expected start_s end_s kind(command|oog|real|noise|fan) text bearing_deg, "
                        "tab-separated%s\n", tsv, lineno, e->nevents == ASR_EVAL_MAX_EVENTS ? " (too many lines)" : "");
            continue;
        }
        v->bearing = deg * DEG;
        e->nevents++;
    }
    free(text);
    return 0;
}

/* The utterance a result overlaps most, or NULL. */
static asr_eval_event_t *overlapping(asr_eval_t *e, double t0, double t1)
{
    asr_eval_event_t *best = NULL;
    double most = 0;
    for (int i = 0; i < e->nevents; i++) {
        asr_eval_event_t *v = &e->ev[i];
        double o = fmin(t1, v->end + 0.3) - fmax(t0, v->start - 0.3);
        if (strcmp(v->kind, "fan") && o > most) {
            most = o;
            best = v;
        }
    }
    return best;
}

static void on_heard(const asr_result_t *r, void *user)
{
    run_t *u = user;
    asr_eval_t *e = u->e;
    e->results++;
    double t0 = r->start_utime / 1e6, t1 = r->end_utime / 1e6;
    bool accepted = r->text[0] && r->confidence >= u->min_conf;
    asr_eval_event_t *v = overlapping(e, t0, t1);
    if (u->verbose)
        printf("# %7.2f-%7.2f src %d \"%s\" conf %.2f score %.1f %s outside %.2f s over %.1f spread %.1f | %s: %s\n",
               t0, t1, r->source_id, r->text, r->confidence, r->score, r->verified ? "verified" : "unverified",
               r->outside_s, r->over_db, r->spread_db, v ? v->kind : "-", v ? v->text : "");
    if (!accepted)
        return;
    if (!v)
        e->stray++;
    else if (strcmp(v->kind, "command") || !strcmp(v->text, r->text))
        v->heard = true;
    else
        v->wrong = true;
}

/* Is a track born during this utterance far (> 25 deg) from both the one speaking and the fan
 * (a wall's reflection)? */
static void count_tracks(asr_eval_t *e, const ssl_result_t *r)
{
    double t = r->utime / 1e6, speaker = NAN, fan = NAN, since = 0;
    for (int i = 0; i < e->nevents; i++) {
        const asr_eval_event_t *v = &e->ev[i];
        if (!strcmp(v->kind, "fan"))
            fan = v->bearing;
        else if (strcmp(v->kind, "noise") && t >= v->start + 0.1 && t < v->end - 0.1) {
            speaker = v->bearing;
            since = v->start;
        }
    }
    if (isnan(speaker))
        return;
    e->speech_frames++;
    for (int i = 0; i < r->tracker->n; i++) {
        const ssl_track_t *k = &r->tracker->t[i];
        /* born while this one speaks (a track left from the one before is not this one's echo) */
        if (k->confirmed && k->first_utime >= (int64_t)(since * 1e6) && fabs(ssl_wrap(k->azimuth - speaker)) > 25 * DEG &&
            (isnan(fan) || fabs(ssl_wrap(k->azimuth - fan)) > 25 * DEG)) {
            e->false_track_frames++;
            return;
        }
    }
}

static void feed_hop(run_t *u, int id, const float *x, int64_t utime)
{
    for (int j = 0; j < BLOCK; j++)
        u->pcm[j] = (int16_t)lrintf(fmaxf(-32768.0f, fminf(32767.0f, x[j] * 32768.0f)));
    asr_feed(u->asr, id, u->pcm, BLOCK, utime);
}

/* What marie-asr does with marie-ssl's output: every separated stream to the recognizer. */
static void on_frame(const ssl_result_t *r, void *user)
{
    run_t *u = user;
    count_tracks(u->e, r);
    for (int i = 0; i < r->nstreams; i++) {
        const ssl_stream_t *st = &r->streams[i];
        for (int h = 0; h < st->nhistory; h++)
            feed_hop(u, st->id, st->history + h * BLOCK, r->stream_utime - (int64_t)(st->nhistory - h) * BLOCK * 1000000 / 16000);
        feed_hop(u, st->id, st->samples, r->stream_utime);
    }
    asr_expire(u->asr, r->stream_utime);    /* marie-asr's timer */
}

static void score(asr_eval_t *e)
{
    for (int i = 0; i < e->nevents; i++) {
        const asr_eval_event_t *v = &e->ev[i];
        if (!strcmp(v->kind, "fan"))
            continue;
        bool cmd = !strcmp(v->kind, "command");
        e->commands += cmd;
        e->recognized += cmd && v->heard;
        e->wrong += cmd && v->wrong && !v->heard;
        e->others += !cmd;
        e->accepted += !cmd && v->heard;
    }
}

int asr_eval_run(const char *wav, const char *tsv, double min_confidence, bool verbose, asr_eval_t *e)
{
    memset(e, 0, sizeof(*e));
    size_t len;
    uint8_t *buf = (uint8_t *)marie_file_read(wav, (size_t)1 << 31, &len);
    wav_info_t info;
    if (!buf || load_truth(tsv, e) || wav_parse(buf, len, &info, NULL) || info.channels != 8 || info.rate != 16000 ||
        info.frames < 16000) {
        free(buf);
        errno = errno ? errno : EINVAL;
        return -1;
    }
    clock_t c0 = clock();
    run_t u = { .e = e, .min_conf = min_confidence, .verbose = verbose };
    asr_cfg_t acfg;
    asr_cfg_default(&acfg, asr_default_commands, asr_default_ncommands, BLOCK);
    char why[256];
    u.asr = asr_create(&acfg, on_heard, &u, why, sizeof(why));
    ssl_cfg_t scfg;
    ssl_cfg_default(&scfg);
    ssl_t *ssl = ssl_create(&scfg, on_frame, &u);
    if (!u.asr || !ssl) {
        fprintf(stderr, "asr_eval: %s\n", why);
        asr_destroy(u.asr);
        ssl_destroy(ssl);
        free(buf);
        return -1;
    }
    const int16_t *pcm = (const int16_t *)info.pcm;
    for (size_t off = 0; off + BLOCK <= info.frames; off += BLOCK)
        ssl_feed_int16(ssl, pcm + off * 8, 8, BLOCK, (int64_t)(off * 1000000 / 16000));
    asr_flush(u.asr, (int64_t)(info.frames * 1000000 / 16000));
    e->seconds = info.frames / 16000.0;
    e->cpu_s = (double)(clock() - c0) / CLOCKS_PER_SEC;
    score(e);
    ssl_destroy(ssl);
    asr_destroy(u.asr);
    free(buf);
    return 0;
}
