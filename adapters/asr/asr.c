/* asr: command recognition on mono streams with PocketSphinx (see asr.h). */
#include "adapters/asr/asr.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <pocketsphinx.h>

#include "core/err.h"
#include "core/log.h"

const char *const asr_default_commands[] = {
    "go to room a", "go to room b", "go to room c", "go to the kitchen", "stop", "come here", "follow me",
    "turn left", "turn right", "go forward", "go back", "where are you going", "what is your name",
    "hello robot", "goodbye", "face me", "wait here", "go home", "start the mission", "cancel the mission",
};
const int asr_default_ncommands = sizeof(asr_default_commands) / sizeof(asr_default_commands[0]);

typedef struct {
    int id;                     /* -1: free */
    asr_vad_t vad;
    int16_t *ring;              /* pre-roll */
    int ring_len, ring_pos, ring_fill;
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
    int64_t utt_start;
    long blocks;
    bool muted;
};

void asr_cfg_default(asr_cfg_t *c, const char *const *commands, int ncommands, int block)
{
    memset(c, 0, sizeof(*c));
    c->hmm = "/usr/share/pocketsphinx/model/en-us/en-us";
    c->dict = "/usr/share/pocketsphinx/model/en-us/cmudict-en-us.dict";
    c->commands = commands;
    c->ncommands = ncommands;
    c->rate = 16000;
    c->block = block;
    c->preroll_s = 0.3;
    asr_vad_cfg_default(&c->vad, (double)block / c->rate);
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
    a->config = cmd_ln_init(NULL, ps_args(), TRUE, "-hmm", cfg->hmm, "-dict", cfg->dict, "-logfn", "/dev/null",
                            "-samprate", "16000", NULL);
    if (!a->config || !(a->ps = ps_init(a->config))) {
        marie_fail_why(why, whylen, "PocketSphinx cannot load the model %s with %s", cfg->hmm, cfg->dict);
        goto fail;
    }
    if (ps_set_jsgf_string(a->ps, "commands", jsgf) || ps_set_search(a->ps, "commands")) {
        marie_fail_why(why, whylen, "the command grammar is refused (a word missing from %s?)", cfg->dict);
        goto fail;
    }
    int preroll = (int)(cfg->preroll_s * cfg->rate) + cfg->block;
    for (int i = 0; i < ASR_MAX_STREAMS; i++) {
        a->s[i].id = -1;
        a->s[i].ring_len = preroll;
        if (!(a->s[i].ring = malloc(sizeof(int16_t) * (size_t)preroll)))
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
    for (int i = 0; i < ASR_MAX_STREAMS; i++)
        free(a->s[i].ring);
    free(a);
}

static stream_t *stream_for(asr_t *a, int id)
{
    stream_t *lru = NULL;
    for (int i = 0; i < ASR_MAX_STREAMS; i++) {
        if (a->s[i].id == id)
            return &a->s[i];
        if (i != a->locked && (!lru || a->s[i].last_used < lru->last_used))
            lru = &a->s[i];
    }
    lru->id = id;
    lru->ring_pos = lru->ring_fill = 0;
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

/* The pre-roll, oldest first, into the decoder. */
static void ring_feed(asr_t *a, stream_t *s)
{
    int start = (s->ring_pos - s->ring_fill + s->ring_len) % s->ring_len;
    for (int k = 0; k < s->ring_fill;) {
        int i = (start + k) % s->ring_len, run = s->ring_len - i;
        if (run > s->ring_fill - k)
            run = s->ring_fill - k;
        ps_process_raw(a->ps, s->ring + i, (size_t)run, FALSE, FALSE);
        k += run;
    }
    s->ring_fill = 0;
}

static void finish(asr_t *a, stream_t *s, int64_t end_utime)
{
    ps_end_utt(a->ps);
    int32 score;
    const char *hyp = ps_get_hyp(a->ps, &score);
    double conf = logmath_exp(ps_get_logmath(a->ps), ps_get_prob(a->ps));
    asr_result_t r = { .source_id = s->id, .text = hyp ? hyp : "", .confidence = conf > 1 ? 1 : conf,
                       .start_utime = a->utt_start, .end_utime = end_utime };
    a->locked = -1;
    if (a->cb)
        a->cb(&r, a->user);
}

int asr_feed(asr_t *a, int source_id, const int16_t *pcm, int n, int64_t utime)
{
    if (n != a->cfg.block || a->muted) {
        errno = EINVAL;
        return a->muted ? 0 : -1;
    }
    stream_t *s = stream_for(a, source_id);
    s->last_used = ++a->blocks;
    asr_vad_event_t ev = asr_vad_block(&s->vad, pcm, n);
    int idx = (int)(s - a->s);
    if (a->locked < 0 && ev == ASR_VAD_START) {
        a->locked = idx;
        a->utt_start = utime - (int64_t)(s->ring_fill + 0) * 1000000 / a->cfg.rate;
        ps_start_utt(a->ps);
        ring_feed(a, s);
    }
    if (a->locked == idx && (ev == ASR_VAD_START || ev == ASR_VAD_SPEECH || ev == ASR_VAD_END)) {
        ps_process_raw(a->ps, pcm, (size_t)n, FALSE, FALSE);
        if (ev == ASR_VAD_END)
            finish(a, s, utime + (int64_t)n * 1000000 / a->cfg.rate);
        return 0;
    }
    ring_push(s, pcm, n);
    return 0;
}

void asr_flush(asr_t *a, int64_t utime)
{
    if (a->locked >= 0) {
        stream_t *s = &a->s[a->locked];
        asr_vad_init(&s->vad, &a->cfg.vad);
        finish(a, s, utime);
    }
}

void asr_mute(asr_t *a, bool muted)
{
    if (muted && a->locked >= 0) {
        ps_end_utt(a->ps);          /* what was being said is drowned by the robot's voice */
        a->locked = -1;
    }
    a->muted = muted;
}
