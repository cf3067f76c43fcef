/* wav: pure parser and writer for RIFF/WAVE files of 16-bit PCM (what text2wave writes). */
#ifndef MARIE_HW_AUDIO_WAV_H
#define MARIE_HW_AUDIO_WAV_H
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int rate;           /* Hz */
    int channels;
    size_t frames;      /* samples per channel */
    const uint8_t *pcm; /* little-endian int16, interleaved; points into the parsed buffer */
} wav_info_t;

/* Reads the header of a WAVE file held in buf (len bytes). 0, or -1 with errno EINVAL
 * (not a 16-bit PCM WAVE file). A data chunk longer than the file, or of size 0 or
 * 0xffffffff (written to a pipe), holds what is there. `why` (may be NULL) gets a reason. */
int wav_parse(const uint8_t *buf, size_t len, wav_info_t *out, const char **why);

/* Channel ch of the file as floats in [-1, 1); dst holds info->frames values. */
void wav_channel_float(const wav_info_t *info, int ch, float *dst);

/* Loads a mono (or first channel of a) 16-bit WAVE file. Returns a malloc'd array the caller
 * frees, its length in *frames and rate in *rate; NULL with errno on failure. */
float *wav_load_mono(const char *path, size_t *frames, int *rate);

/* Writes 16-bit PCM; the header is 44 bytes. 0 or -1 with errno. */
int wav_write(const char *path, const int16_t *data, size_t frames, int channels, int rate);

#ifdef __cplusplus
}
#endif
#endif
