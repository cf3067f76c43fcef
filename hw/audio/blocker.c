/* blocker: fixed blocks out of a stream of frames read in pieces of any size (see blocker.h). */
#include "hw/audio/blocker.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include "core/clear.h"
#include "core/err.h"

int audio_blocker_init(audio_blocker_t *b, int nchannels, int block, int rate, audio_block_cb_t cb, void *user)
{
    *b = (audio_blocker_t){ 0 };
    if (nchannels < 1 || nchannels > 64 || block < 1 || block > 65536 || rate < 1)
        return marie_fail(EINVAL);
    *b = (audio_blocker_t){ .nchannels = nchannels, .block = block, .rate = rate, .cb = cb, .user = user,
                            .buf = malloc(sizeof(int16_t) * (size_t)nchannels * (size_t)block) };
    return b->buf ? 0 : -1;
}

void audio_blocker_free(audio_blocker_t *b)
{
    MARIE_CLEAR(b->buf, free);
}

void audio_blocker_feed(audio_blocker_t *b, const int16_t *frames, int n, int64_t utime)
{
    int done = 0;
    while (done < n) {
        if (b->fill == 0)
            b->first_utime = utime + (int64_t)done * 1000000 / b->rate;
        int take = b->block - b->fill < n - done ? b->block - b->fill : n - done;
        memcpy(b->buf + (size_t)b->fill * b->nchannels, frames + (size_t)done * b->nchannels,
               sizeof(int16_t) * (size_t)take * (size_t)b->nchannels);
        b->fill += take;
        done += take;
        if (b->fill == b->block) {
            b->cb(b->buf, b->nchannels, b->block, b->seq++, b->first_utime, b->user);
            b->fill = 0;
        }
    }
}
