/* asr: command recognition on mono streams: per-stream voice activity detection picks the
 * utterance, PocketSphinx decodes it against a grammar made of the command phrases. */
#ifndef MARIE_ASR_H
#define MARIE_ASR_H
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "adapters/asr/asr_model_params.h"
#include "adapters/asr/asr_vad.h"

#ifdef __cplusplus
extern "C" {
#endif

#define ASR_MAX_STREAMS 8

typedef struct {
    asr_model_t model;          /* hmm and dict; empty or NULL: ASR_DEFAULT_HMM, ASR_DEFAULT_DICT */
    const char *const *commands;/* phrases of the grammar, lower case */
    int ncommands;
    int rate;                   /* Hz of the streams (the model's: 16000) */
    int block;                  /* samples per fed block */
    double preroll_s;           /* kept before the detected start */
    asr_vad_cfg_t vad;
    /* Which stream gets the decoder: the streams whose voice detector opened within decide_s
     * of the first are compared, and the one standing most over its own floor wins, if it
     * looks like speech (its blocks' dB spread at least min_spread_db: a fan is steady). */
    double decide_s;
    double min_spread_db;
    /* A stream that sends nothing for stale_s has ended (its track died): what it was saying
     * is decoded with what came. */
    double stale_s;
    /* Confidence: the hypothesis's words' mean acoustic score per frame against the best
     * state of each frame (PocketSphinx's own normalization: a garbage model of every state),
     * through a logistic: 0.5 at conf_mid, conf_scale per step of e; multiplied by doubt when
     * a second decode with narrow beams does not find the same words, or when more than
     * max_outside_s of the utterance lies outside the words (pre-roll and end wait included:
     * something longer than a command was said), or when it is part of a sound longer than
     * the voice detector's limit. */
    double conf_mid, conf_scale;
    double max_outside_s, doubt;
} asr_cfg_t;

#define ASR_DEFAULT_HMM "/usr/share/pocketsphinx/model/en-us/en-us"
#define ASR_DEFAULT_DICT "/usr/share/pocketsphinx/model/en-us/cmudict-en-us.dict"

/* The default model of Debian's pocketsphinx-en-us, and a 16 kHz rate. */
void asr_cfg_default(asr_cfg_t *c, const char *const *commands, int ncommands, int block);

typedef struct {
    int source_id;
    const char *text;           /* "" when nothing of the grammar was heard; valid in the callback */
    double confidence;          /* 0..1: 0.5 where in-grammar and other speech are told apart */
    double score;               /* the words' mean acoustic score per frame it comes from */
    bool verified;              /* the narrow-beam decode found the same words */
    double outside_s;           /* of the utterance, outside the words */
    double over_db, spread_db;  /* what the stream's voice detector saw */
    int64_t start_utime, end_utime;
} asr_result_t;

typedef void (*asr_result_cb_t)(const asr_result_t *r, void *user);

typedef struct asr asr_t;

/* NULL with errno and a reason in why (a phrase's word missing from the dictionary, no model). */
asr_t *asr_create(const asr_cfg_t *cfg, asr_result_cb_t cb, void *user, char *why, size_t whylen);
void asr_destroy(asr_t *a);

/* One block of a stream (cfg.block samples; any int id, -1 included). One utterance is
 * decoded at a time: the speech stream chosen among those that started together holds the
 * decoder until it ends, or until it has sent nothing for stale_s. */
int asr_feed(asr_t *a, int source_id, const int16_t *pcm, int n, int64_t utime);

/* Time passes without blocks (no stream at all): an utterance whose stream sent nothing for
 * stale_s before utime is decoded now. marie-asr calls it from a timer. */
void asr_expire(asr_t *a, int64_t utime);

/* The input ended: an utterance in progress is decoded now. */
void asr_flush(asr_t *a, int64_t utime);

/* While muted (the robot speaks) nothing is heard, and an utterance in progress is dropped. */
void asr_mute(asr_t *a, bool muted);

/* The default command phrases. */
extern const char *const asr_default_commands[];
extern const int asr_default_ncommands;

#ifdef __cplusplus
}
#endif
#endif
