/* blocker: cuts a stream of interleaved 16-bit frames, read in pieces of any size, into fixed
 * blocks with a sequence number and the time of their first sample. Pure. */
#ifndef MARIE_HW_AUDIO_BLOCKER_H
#define MARIE_HW_AUDIO_BLOCKER_H
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef void (*audio_block_cb_t)(const int16_t *data, int nchannels, int nsamples, int64_t seq, int64_t utime,
                                 void *user);

typedef struct {
    int nchannels, block, rate, fill;
    int16_t *buf;
    int64_t seq, first_utime;
    audio_block_cb_t cb;
    void *user;
} audio_blocker_t;

int audio_blocker_init(audio_blocker_t *b, int nchannels, int block, int rate, audio_block_cb_t cb, void *user);
void audio_blocker_free(audio_blocker_t *b);

/* n frames, the first one sampled at utime. */
void audio_blocker_feed(audio_blocker_t *b, const int16_t *frames, int n, int64_t utime);

#ifdef __cplusplus
}
#endif
#endif
