/* asr_vad: energy voice activity detection on one mono stream: a noise floor that follows the
 * block energy down at once and up slowly, speech when a block stands out of it, an utterance
 * from the first speech blocks until a silence (hangover) or a length limit. Pure. */
#ifndef MARIE_ASR_VAD_H
#define MARIE_ASR_VAD_H
#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double threshold_db;        /* over the floor */
    int start_blocks;           /* consecutive speech blocks that open an utterance */
    double hangover_s, max_s, block_s;
} asr_vad_cfg_t;

void asr_vad_cfg_default(asr_vad_cfg_t *c, double block_s);

typedef enum { ASR_VAD_SILENCE, ASR_VAD_START, ASR_VAD_SPEECH, ASR_VAD_END } asr_vad_event_t;

typedef struct {
    asr_vad_cfg_t cfg;
    double floor_db;
    long blocks;
    int run;                    /* consecutive speech blocks */
    bool in_utt;
    double utt_s, quiet_s;
    /* What the current utterance looks like: its blocks' dB over the floor (speech stands
     * well out of it) and the spread of their dB (speech comes in syllables, a fan is steady). */
    int nblk;
    double sum_over, sum_db, sum_db2;
    /* The utterance is part of a sound longer than max_s: cut at the limit, or starting right
     * after one that was (no command lasts that long: a talk, a radio, a fan's change). */
    bool long_sound;
    bool cut;                   /* the last utterance ended at the limit */
    double since_end_s;
} asr_vad_t;

void asr_vad_init(asr_vad_t *v, const asr_vad_cfg_t *cfg);

/* One block: START when it opens an utterance, SPEECH inside one, END on the block that
 * closes it (silence long enough, or the limit), SILENCE otherwise. */
asr_vad_event_t asr_vad_block(asr_vad_t *v, const int16_t *pcm, int n);

/* The current utterance's mean dB over the floor, and the standard deviation of its blocks' dB
 * (0 before any block). */
double asr_vad_over_db(const asr_vad_t *v);
double asr_vad_spread_db(const asr_vad_t *v);

#ifdef __cplusplus
}
#endif
#endif
