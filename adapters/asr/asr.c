/* asr: command recognition on mono streams with PocketSphinx (see asr.h). */
#include "adapters/asr/asr.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <pocketsphinx.h>
#include <sphinxbase/cmn.h>
#include <sphinxbase/feat.h>

#include "core/err.h"
#include "core/log.h"

const char *const asr_default_commands[] = {
    "go to room a", "go to room b", "go to room c", "go to the kitchen", "stop", "come here", "follow me",
    "turn left", "turn right", "go forward", "go back", "where are you going", "what is your name",
    "hello robot", "goodbye", "face me", "wait here", "go home", "start the mission", "cancel the mission",
};
const int asr_default_ncommands = sizeof(asr_default_commands) / sizeof(asr_default_commands[0]);

/* PocketSphinx's running cepstral mean (sphinxbase's cmn_t, a public struct): kept so that a
 * second decode of an utterance starts where the first did and leaves no trace. */
typedef struct {
    mfcc_t mean[64], sum[64];
    int32 nframe;
} cmn_state_t;

typedef struct {
    int id;
    bool used;                  /* any int is an id (input=array's -1 too): the slot says if it is taken */
    asr_vad_t vad;
    int16_t *ring;              /* pre-roll */
    int ring_len, ring_pos, ring_fill;
    int16_t *utt;               /* the current utterance, pre-roll first: fed when the stream wins */
    int utt_len, utt_cap;
    int64_t utt_start, last_utime;
    long last_used;
} stream_t;

struct asr {
    asr_cfg_t cfg;
    asr_result_cb_t cb;
    void *user;
    cmd_ln_t *config;
    ps_decoder_t *ps;
    stream_t s[ASR_MAX_STREAMS];
    int locked;                 /* index of the stream being decoded, -1 */
    long blocks;
    bool muted;
    cmn_state_t cmn_start;      /* the running cepstral mean the utterance was decoded with */
};

static const char *or_default(const char *path, const char *deflt)
{
    return path && *path ? path : deflt;
}

void asr_cfg_default(asr_cfg_t *c, const char *const *commands, int ncommands, int block)
{
    memset(c, 0, sizeof(*c));       /* model: Debian's */
    c->commands = commands;
    c->ncommands = ncommands;
    c->rate = 16000;
    c->block = block;
    c->preroll_s = 0.3;
    asr_vad_cfg_default(&c->vad, (double)block / c->rate);
    c->decide_s = 0.25;
    c->min_spread_db = 2.5;
    c->stale_s = 0.2;
    c->conf_mid = -45;
    c->conf_scale = 4;
    c->max_outside_s = c->preroll_s + c->vad.hangover_s + 1.5;
    c->doubt = 0.1;
}

/* "public <command> = (go to room a) | (stop) ...;" with only letters, digits, spaces and
 * apostrophes let through, so a phrase cannot break the grammar. */
static char *make_jsgf(const asr_cfg_t *cfg)
{
    size_t cap = 128;
    for (int i = 0; i < cfg->ncommands; i++)
        cap += strlen(cfg->commands[i]) + 8;
    char *g = malloc(cap), *p = g;
    if (!g)
        return NULL;
    p += sprintf(p, "#JSGF V1.0;\ngrammar marie;\npublic <command> = ");
    for (int i = 0; i < cfg->ncommands; i++) {
        p += sprintf(p, "%s(", i ? " | " : "");
        for (const char *c = cfg->commands[i]; *c; c++)
            *p++ = (char)(isalnum((unsigned char)*c) || *c == '\'' ? tolower((unsigned char)*c) : ' ');
        *p++ = ')';
    }
    strcpy(p, ";\n");
    return g;
}

/* The second search, "verify", decodes each utterance again with PocketSphinx's default beam
 * and a narrower phone beam (a search keeps the beams of the configuration it was made with).
 * Out of the grammar, the path of the best command falls out of such beams somewhere: measured
 * on a room scene of 120 utterances (tests/audio/room_scene.py, seed 101), 59 of 62 commands
 * heard right kept their words, 39 of 53 other sounds lost or changed theirs. */
static int set_verify_beams(cmd_ln_t *c)
{
    cmd_ln_set_float_r(c, "-beam", 1e-48);
    cmd_ln_set_float_r(c, "-pbeam", 1e-35);
    cmd_ln_set_float_r(c, "-wbeam", 1e-20);
    return 0;
}

asr_t *asr_create(const asr_cfg_t *cfg, asr_result_cb_t cb, void *user, char *why, size_t whylen)
{
    if (cfg->ncommands < 1 || cfg->block < 1 || cfg->rate != 16000) {
        marie_fail_why(why, whylen, "need commands, a block size and 16000 Hz (the model's rate)");
        return marie_fail_null(EINVAL);
    }
    asr_t *a = calloc(1, sizeof(*a));
    char *jsgf = make_jsgf(cfg);
    if (!a || !jsgf)
        goto fail;
    a->cfg = *cfg;
    a->cb = cb;
    a->user = user;
    a->locked = -1;
    const char *hmm = or_default(cfg->model.hmm, ASR_DEFAULT_HMM);
    const char *dict = or_default(cfg->model.dict, ASR_DEFAULT_DICT);
    a->config = cmd_ln_init(NULL, ps_args(), TRUE, "-hmm", hmm, "-dict", dict, "-logfn", "/dev/null",
                            "-samprate", "16000",
                            /* wider beams than the defaults: 103 of 120 clean espeak-ng commands
                               instead of 93 (the narrow ones lose the grammar's end) */
                            "-beam", "1e-80", "-wbeam", "1e-60", "-pbeam", "1e-80", NULL);
    if (!a->config || !(a->ps = ps_init(a->config))) {
        marie_fail_why(why, whylen, "PocketSphinx cannot load the model %s with %s", hmm, dict);
        goto fail;
    }
    if (ps_set_jsgf_string(a->ps, "commands", jsgf) || set_verify_beams(a->config) ||
        ps_set_jsgf_string(a->ps, "verify", jsgf) || ps_set_search(a->ps, "commands")) {
        marie_fail_why(why, whylen, "the command grammar is refused (a word missing from %s?)", dict);
        goto fail;
    }
    int preroll = (int)(cfg->preroll_s * cfg->rate) + cfg->block;
    int cap = preroll + (int)((cfg->vad.max_s + 1) * cfg->rate);
    for (int i = 0; i < ASR_MAX_STREAMS; i++) {
        a->s[i].ring_len = preroll;
        a->s[i].utt_cap = cap;
        a->s[i].ring = malloc(sizeof(int16_t) * (size_t)preroll);
        a->s[i].utt = malloc(sizeof(int16_t) * (size_t)cap);
        if (!a->s[i].ring || !a->s[i].utt)
            goto fail;
    }
    free(jsgf);
    return a;
fail:
    free(jsgf);
    asr_destroy(a);
    return marie_fail_null(EINVAL);
}

void asr_destroy(asr_t *a)
{
    if (!a)
        return;
    if (a->ps)
        ps_free(a->ps);
    if (a->config)
        cmd_ln_free_r(a->config);
    for (int i = 0; i < ASR_MAX_STREAMS; i++) {
        free(a->s[i].ring);
        free(a->s[i].utt);
    }
    free(a);
}

static stream_t *stream_for(asr_t *a, int id)
{
    stream_t *lru = NULL;
    for (int i = 0; i < ASR_MAX_STREAMS; i++) {
        if (a->s[i].used && a->s[i].id == id)
            return &a->s[i];
        if (i != a->locked && (!lru || !a->s[i].used || (lru->used && a->s[i].last_used < lru->last_used)))
            lru = &a->s[i];
    }
    lru->id = id;
    lru->used = true;
    lru->ring_pos = lru->ring_fill = lru->utt_len = 0;
    asr_vad_init(&lru->vad, &a->cfg.vad);
    return lru;
}

static void ring_push(stream_t *s, const int16_t *pcm, int n)
{
    for (int i = 0; i < n; i++) {
        s->ring[s->ring_pos] = pcm[i];
        s->ring_pos = (s->ring_pos + 1) % s->ring_len;
    }
    s->ring_fill = s->ring_fill + n > s->ring_len ? s->ring_len : s->ring_fill + n;
}

static void utt_push(stream_t *s, const int16_t *pcm, int n)
{
    if (n > s->utt_cap - s->utt_len)
        n = s->utt_cap - s->utt_len;
    memcpy(s->utt + s->utt_len, pcm, sizeof(int16_t) * (size_t)n);
    s->utt_len += n;
}

/* An utterance opens: the pre-roll, oldest first, starts its buffer. */
static void utt_open(asr_t *a, stream_t *s, int64_t utime)
{
    s->utt_len = 0;
    s->utt_start = utime - (int64_t)s->ring_fill * 1000000 / a->cfg.rate;
    int start = (s->ring_pos - s->ring_fill + s->ring_len) % s->ring_len;
    for (int k = 0; k < s->ring_fill; k++)
        utt_push(s, &s->ring[(start + k) % s->ring_len], 1);
    s->ring_fill = 0;
}

/* The words' mean acoustic score per frame (PocketSphinx scores every frame against its best
 * state, so this is how far the grammar's path falls below the best any sound could do), and
 * how many of the utterance's frames are outside the words (silence, fillers). */
static double word_score(asr_t *a, int *outside)
{
    double sum = 0;
    int frames = 0, all = 0;
    for (ps_seg_t *g = ps_seg_iter(a->ps); g; g = ps_seg_next(g)) {
        int32 ascr, lscr, lback;
        int sf, ef;
        ps_seg_prob(g, &ascr, &lscr, &lback);
        ps_seg_frames(g, &sf, &ef);
        all += ef - sf + 1;
        const char *w = ps_seg_word(g);
        if (w[0] == '<' || w[0] == '[')
            continue;           /* silence and fillers */
        sum += ascr;
        frames += ef - sf + 1;
    }
    *outside = all - frames;
    return frames > 0 ? sum / frames : -1e9;
}

static cmn_t *running_cmn(asr_t *a)
{
    feat_t *f = ps_get_feat(a->ps);
    return f && f->cmn_struct && f->cmn_struct->veclen <= 64 ? f->cmn_struct : NULL;
}

static void cmn_save(asr_t *a, cmn_state_t *st)
{
    cmn_t *c = running_cmn(a);
    if (!c)
        return;
    memcpy(st->mean, c->cmn_mean, sizeof(mfcc_t) * (size_t)c->veclen);
    memcpy(st->sum, c->sum, sizeof(mfcc_t) * (size_t)c->veclen);
    st->nframe = c->nframe;
}

static void cmn_restore(asr_t *a, const cmn_state_t *st)
{
    cmn_t *c = running_cmn(a);
    if (!c)
        return;
    memcpy(c->cmn_mean, st->mean, sizeof(mfcc_t) * (size_t)c->veclen);
    memcpy(c->sum, st->sum, sizeof(mfcc_t) * (size_t)c->veclen);
    c->nframe = st->nframe;
}

/* The utterance decoded again by the "verify" search: do its words stay? It starts from the
 * cepstral mean the first decode started from (the first decode moved it: a fresh decoder's
 * first command was refused for that), and the mean the first decode left is put back. */
static bool verified(asr_t *a, const stream_t *s, const char *hyp)
{
    cmn_state_t after;
    cmn_save(a, &after);
    cmn_restore(a, &a->cmn_start);
    bool same = false;
    if (!ps_set_search(a->ps, "verify") && ps_start_utt(a->ps) >= 0) {
        ps_process_raw(a->ps, s->utt, (size_t)s->utt_len, FALSE, FALSE);
        ps_end_utt(a->ps);
        int32 best;
        const char *again = ps_get_hyp(a->ps, &best);
        same = again && !strcmp(again, hyp);
    }
    ps_set_search(a->ps, "commands");
    cmn_restore(a, &after);
    return same;
}

static void finish(asr_t *a, stream_t *s, int64_t end_utime)
{
    ps_end_utt(a->ps);
    int32 best;
    const char *hyp = ps_get_hyp(a->ps, &best);
    if (!hyp)
        hyp = "";
    int outside = 0;
    double score = hyp[0] ? word_score(a, &outside) : -1e9;
    double conf = hyp[0] ? 1 / (1 + exp((a->cfg.conf_mid - score) / a->cfg.conf_scale)) : 0;
    char text[256];
    snprintf(text, sizeof(text), "%s", hyp);     /* the verifying decode reuses the decoder's */
    double outside_s = outside / 100.0;         /* PocketSphinx's frames are 10 ms */
    bool ok = text[0] && verified(a, s, text);
    if (!ok || outside_s > a->cfg.max_outside_s || s->vad.long_sound)
        conf *= a->cfg.doubt;
    asr_result_t r = { .source_id = s->id, .text = text, .confidence = conf, .score = score, .verified = ok,
                       .outside_s = outside_s,
                       .over_db = asr_vad_over_db(&s->vad), .spread_db = asr_vad_spread_db(&s->vad),
                       .start_utime = s->utt_start, .end_utime = end_utime };
    a->locked = -1;
    s->utt_len = 0;
    if (a->cb)
        a->cb(&r, a->user);
}

/* The decoder goes to the stream that stands most over its floor among those in an utterance
 * that looks like speech, once the first of them has been speaking decide_s (or has ended). */
static void admit(asr_t *a, int64_t utime, bool ending)
{
    stream_t *best = NULL;
    bool ripe = ending;
    for (int i = 0; i < ASR_MAX_STREAMS; i++) {
        stream_t *s = &a->s[i];
        if (!s->used || (!s->vad.in_utt && !(ending && s->utt_len)))
            continue;
        ripe = ripe || utime - s->utt_start >= (int64_t)((a->cfg.decide_s + a->cfg.preroll_s) * 1e6);
        if (asr_vad_spread_db(&s->vad) < a->cfg.min_spread_db)
            continue;
        if (!best || asr_vad_over_db(&s->vad) > asr_vad_over_db(&best->vad))
            best = s;
    }
    if (!ripe || !best)
        return;
    a->locked = (int)(best - a->s);
    cmn_save(a, &a->cmn_start);
    ps_start_utt(a->ps);
    ps_process_raw(a->ps, best->utt, (size_t)best->utt_len, FALSE, FALSE);
}

void asr_expire(asr_t *a, int64_t utime)
{
    for (int i = 0; i < ASR_MAX_STREAMS; i++) {
        stream_t *s = &a->s[i];
        if (!s->used || utime - s->last_utime <= (int64_t)(a->cfg.stale_s * 1e6) || !(s->vad.in_utt || i == a->locked))
            continue;
        if (i == a->locked)
            finish(a, s, s->last_utime);
        asr_vad_init(&s->vad, &a->cfg.vad);     /* what it began to say is over */
        s->utt_len = 0;
    }
}

int asr_feed(asr_t *a, int source_id, const int16_t *pcm, int n, int64_t utime)
{
    if (n != a->cfg.block || a->muted) {
        errno = EINVAL;
        return a->muted ? 0 : -1;
    }
    asr_expire(a, utime);
    stream_t *s = stream_for(a, source_id);
    s->last_used = ++a->blocks;
    s->last_utime = utime + (int64_t)n * 1000000 / a->cfg.rate;
    asr_vad_event_t ev = asr_vad_block(&s->vad, pcm, n);
    if (ev == ASR_VAD_SILENCE) {
        ring_push(s, pcm, n);
        return 0;
    }
    if (ev == ASR_VAD_START)
        utt_open(a, s, utime);
    int idx = (int)(s - a->s);
    if (a->locked == idx)
        ps_process_raw(a->ps, pcm, (size_t)n, FALSE, FALSE);
    utt_push(s, pcm, n);
    if (a->locked < 0)
        admit(a, utime, ev == ASR_VAD_END);
    if (ev == ASR_VAD_END) {
        if (a->locked == idx)
            finish(a, s, s->last_utime);
        s->utt_len = 0;
    }
    return 0;
}

void asr_flush(asr_t *a, int64_t utime)
{
    if (a->locked >= 0) {
        stream_t *s = &a->s[a->locked];
        finish(a, s, utime);
        asr_vad_init(&s->vad, &a->cfg.vad);
    }
}

void asr_mute(asr_t *a, bool muted)
{
    if (muted && a->locked >= 0) {
        ps_end_utt(a->ps);          /* what was being said is drowned by the robot's voice */
        a->locked = -1;
    }
    if (muted)
        for (int i = 0; i < ASR_MAX_STREAMS; i++)
            a->s[i].utt_len = 0;
    a->muted = muted;
}
