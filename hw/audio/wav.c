/* wav: pure parser and writer for RIFF/WAVE files of 16-bit PCM (what text2wave writes). */
#include "hw/audio/wav.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"
#include "core/file.h"

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint16_t le16(const uint8_t *p)
{
    return (uint16_t)(p[0] | p[1] << 8);
}

static int refuse(const char **why, const char *reason)
{
    if (why)
        *why = reason;
    return marie_fail(EINVAL);
}

int wav_parse(const uint8_t *buf, size_t len, wav_info_t *out, const char **why)
{
    if (len < 12 || memcmp(buf, "RIFF", 4) || memcmp(buf + 8, "WAVE", 4))
        return refuse(why, "not a RIFF/WAVE file");
    size_t pos = 12;
    int have_fmt = 0;
    memset(out, 0, sizeof(*out));
    while (len - pos >= 8) {
        uint32_t size = le32(buf + pos + 4);
        const uint8_t *body = buf + pos + 8;
        size_t avail = len - pos - 8;
        if (!memcmp(buf + pos, "fmt ", 4)) {
            if (size < 16 || avail < 16)
                return refuse(why, "short fmt chunk");
            uint16_t format = le16(body), bits = le16(body + 14);
            out->channels = le16(body + 2);
            out->rate = (int)le32(body + 4);
            if (format != 1 || bits != 16)
                return refuse(why, "not 16-bit PCM");
            if (out->channels < 1 || out->channels > 64 || out->rate < 1000 || out->rate > 384000)
                return refuse(why, "channel count or rate out of range");
            have_fmt = 1;
        } else if (!memcmp(buf + pos, "data", 4)) {
            if (!have_fmt)
                return refuse(why, "data before fmt");
            /* A stream written to a pipe (text2wave -o -) cannot go back to fill in its sizes:
             * 0 or 0xffffffff there means "up to the end". */
            size_t n = size == 0 || size == 0xffffffffu || size > avail ? avail : size;
            out->pcm = body;
            out->frames = n / (2u * (size_t)out->channels);
            return 0;
        }
        if (size > avail)
            break;
        pos += 8 + (size_t)size + (size & 1);
    }
    return refuse(why, "no data chunk");
}

void wav_channel_float(const wav_info_t *info, int ch, float *dst)
{
    size_t stride = 2u * (size_t)info->channels;
    for (size_t i = 0; i < info->frames; i++)
        dst[i] = (int16_t)le16(info->pcm + i * stride + 2u * (size_t)ch) / 32768.0f;
}

float *wav_load_mono(const char *path, size_t *frames, int *rate)
{
    size_t len;
    uint8_t *buf = (uint8_t *)marie_file_read(path, 64u << 20, &len);
    if (!buf)
        return NULL;
    wav_info_t info;
    float *out = NULL;
    if (wav_parse(buf, len, &info, NULL) == 0 && info.frames > 0 &&
        (out = malloc(info.frames * sizeof(float)))) {
        wav_channel_float(&info, 0, out);
        *frames = info.frames;
        *rate = info.rate;
    } else if (!errno) {
        errno = EINVAL;
    }
    MARIE_KEEP_ERRNO(free(buf));
    return out;
}

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); p[2] = (uint8_t)(v >> 16); p[3] = (uint8_t)(v >> 24);
}

int wav_write(const char *path, const int16_t *data, size_t frames, int channels, int rate)
{
    uint8_t h[44];
    uint32_t bytes = (uint32_t)(frames * (size_t)channels * 2);
    memcpy(h, "RIFF", 4); put32(h + 4, 36 + bytes); memcpy(h + 8, "WAVEfmt ", 8);
    put32(h + 16, 16); h[20] = 1; h[21] = 0; h[22] = (uint8_t)channels; h[23] = 0;
    put32(h + 24, (uint32_t)rate); put32(h + 28, (uint32_t)(rate * channels * 2));
    h[32] = (uint8_t)(channels * 2); h[33] = 0; h[34] = 16; h[35] = 0;
    memcpy(h + 36, "data", 4); put32(h + 40, bytes);
    FILE *f = fopen(path, "wb");
    if (!f)
        return -1;
    int ok = fwrite(h, 1, 44, f) == 44 && fwrite(data, 2, frames * (size_t)channels, f) == frames * (size_t)channels;
    int e = errno;
    if (fclose(f) || !ok) {
        errno = ok ? errno : (e ? e : EIO);
        return -1;
    }
    return 0;
}
