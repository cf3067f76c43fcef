/* fuzz_audio_wav: arbitrary bytes as a WAVE file and as an array geometry text must parse or
 * be refused, never read outside the buffer. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "hw/audio/micarray.h"
#include "hw/audio/wav.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    wav_info_t w;
    if (wav_parse(data, size, &w, NULL) == 0) {
        if (w.pcm < data || w.pcm + w.frames * 2u * (size_t)w.channels > data + size)
            abort();
        float *x = malloc((w.frames ? w.frames : 1) * sizeof(float));
        if (x)
            wav_channel_float(&w, w.channels - 1, x);
        free(x);
    }
    char *text = malloc(size + 1);
    if (!text)
        return 0;
    memcpy(text, data, size);
    text[size] = 0;
    micarray_t a;
    if (micarray_parse(text, &a, NULL) == 0 && (a.n < 2 || a.n > MICARRAY_MAX))
        abort();
    free(text);
    return 0;
}
