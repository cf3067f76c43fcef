/* asr_vad: energy voice activity detection on one mono stream (see asr_vad.h). */
#include "adapters/asr/asr_vad.h"

#include <math.h>
#include <string.h>

void asr_vad_cfg_default(asr_vad_cfg_t *c, double block_s)
{
    *c = (asr_vad_cfg_t){ .threshold_db = 6, .start_blocks = 3, .hangover_s = 0.45, .max_s = 6, .block_s = block_s };
}

void asr_vad_init(asr_vad_t *v, const asr_vad_cfg_t *cfg)
{
    memset(v, 0, sizeof(*v));
    v->cfg = *cfg;
    v->floor_db = -200;
}

static double block_db(const int16_t *pcm, int n)
{
    double e = 0;
    for (int i = 0; i < n; i++)
        e += (double)pcm[i] * pcm[i];
    return 10 * log10(e / (n > 0 ? n : 1) + 1e-3);
}

static void count(asr_vad_t *v, double db)
{
    v->nblk++;
    v->sum_over += db - v->floor_db;
    v->sum_db += db;
    v->sum_db2 += db * db;
}

double asr_vad_over_db(const asr_vad_t *v)
{
    return v->nblk ? v->sum_over / v->nblk : 0;
}

double asr_vad_spread_db(const asr_vad_t *v)
{
    if (v->nblk < 2)
        return 0;
    double m = v->sum_db / v->nblk, var = v->sum_db2 / v->nblk - m * m;
    return var > 0 ? sqrt(var) : 0;
}

asr_vad_event_t asr_vad_block(asr_vad_t *v, const int16_t *pcm, int n)
{
    double db = block_db(pcm, n);
    if (v->blocks++ == 0 || db < v->floor_db)
        v->floor_db = db;
    else
        v->floor_db += v->in_utt ? 0.002 : 0.02;      /* dB per block: about 1 dB/s while quiet */
    bool speech = db > v->floor_db + v->cfg.threshold_db;
    if (!v->in_utt) {
        v->run = speech ? v->run + 1 : 0;
        v->since_end_s += v->cfg.block_s;
        if (v->run < v->cfg.start_blocks)
            return ASR_VAD_SILENCE;
        v->long_sound = v->cut && v->since_end_s - v->run * v->cfg.block_s < 0.25;
        v->cut = false;
        v->in_utt = true;
        v->utt_s = v->run * v->cfg.block_s;
        v->quiet_s = 0;
        v->nblk = 0;
        v->sum_over = v->sum_db = v->sum_db2 = 0;
        count(v, db);
        return ASR_VAD_START;
    }
    count(v, db);
    v->utt_s += v->cfg.block_s;
    v->quiet_s = speech ? 0 : v->quiet_s + v->cfg.block_s;
    if (v->quiet_s >= v->cfg.hangover_s || v->utt_s >= v->cfg.max_s) {
        v->in_utt = false;
        v->run = 0;
        v->cut = v->quiet_s < v->cfg.hangover_s;
        v->long_sound = v->long_sound || v->cut;
        v->since_end_s = 0;
        return ASR_VAD_END;
    }
    return ASR_VAD_SPEECH;
}
