/* marie-audio: captures a multi-channel ALSA device (a microphone array) into AUDIO blocks, and
 * plays the blocks of its `play` port (the robot's voice) on an ALSA device. ALSA's poll
 * descriptors are watched by the component's loop. */
#include <alsa/asoundlib.h>
#include <errno.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>

#include "core/clear.h"
#include "core/component.h"
#include "hw/audio/audio_params.h"
#include "hw/audio/blocker.h"

#define MAX_FDS 8

typedef struct {
    marie_component_t *c;
    snd_pcm_t *cap, *play;
    struct pollfd fds[MAX_FDS];
    int nfds;
    audio_blocker_t blocker;
    int16_t *rbuf;
    marie_port_t *p_audio;
} audio_t;

static const audio_params_t *params_of(const audio_t *s) { return marie_component_params(s->c); }

static void on_block(const int16_t *data, int nchannels, int nsamples, int64_t seq, int64_t utime, void *user)
{
    audio_t *s = user;
    char *dev = (char *)params_of(s)->device;     /* the block names the parameter's device: a use, no copy */
    marie_audio_frame_t f = { .utime = utime, .seq = seq, .device = dev, .sample_rate = (int32_t)params_of(s)->rate,
                              .nchannels = (int16_t)nchannels, .nsamples = nsamples, .nvalues = nchannels * nsamples,
                              .data = (int16_t *)data };
    marie_port_publish(s->p_audio, &f);
}

static void on_capture(marie_loop_t *loop, int fd, short revents, void *user)
{
    audio_t *s = user;
    for (int i = 0; i < s->nfds; i++)
        if (s->fds[i].fd == fd)
            s->fds[i].revents = revents;
    unsigned short ev = 0;
    snd_pcm_poll_descriptors_revents(s->cap, s->fds, (unsigned)s->nfds, &ev);
    if (!(ev & POLLIN) && !(ev & POLLERR))
        return;
    /* A few periods per wake-up at most: a device that is always ready (ALSA's null and file
     * plugins) must not keep the loop from its signals and timers. */
    for (int k = 0; k < 4; k++) {
        snd_pcm_sframes_t n = snd_pcm_readi(s->cap, s->rbuf, (snd_pcm_uframes_t)params_of(s)->block);
        if (n == -EAGAIN || n == 0)
            return;
        if (n < 0) {
            /* An overrun (the loop was late) loses samples: counted, and capture goes on. */
            marie_component_count(s->c, "xruns", 1);
            if (snd_pcm_recover(s->cap, (int)n, 1) < 0) {
                marie_component_set_degraded(s->c, true, "capture failed: %s", snd_strerror((int)n));
                return;
            }
            snd_pcm_start(s->cap);
            continue;
        }
        /* The samples just read ended now: the first of them was taken n/rate ago. */
        int64_t utime = marie_component_now(s->c) - (int64_t)n * 1000000 / params_of(s)->rate;
        audio_blocker_feed(&s->blocker, s->rbuf, (int)n, utime);
    }
}

static void on_play(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    audio_t *s = marie_component_user(c);
    const marie_audio_frame_t *f = msg;
    if (!s->play)
        return;
    int rate = (int)params_of(s)->rate;
    if (f->nchannels != 1 || f->sample_rate != rate || f->nvalues != f->nsamples) {
        marie_component_bad_input(c, "bad_play", "play block of %d channels at %d Hz refused (mono at %d)",
                                  f->nchannels, f->sample_rate, rate);
        return;
    }
    snd_pcm_sframes_t n = snd_pcm_writei(s->play, f->data, (snd_pcm_uframes_t)f->nsamples);
    if (n < 0) {
        marie_component_count(c, "play_xruns", 1);
        snd_pcm_recover(s->play, (int)n, 1);
    }
}

static int open_pcm(marie_component_t *c, snd_pcm_t **pcm, const char *dev, snd_pcm_stream_t st, int channels,
                    int rate, int block)
{
    int e = snd_pcm_open(pcm, dev, st, SND_PCM_NONBLOCK);
    if (e >= 0)
        e = snd_pcm_set_params(*pcm, SND_PCM_FORMAT_S16_LE, SND_PCM_ACCESS_RW_INTERLEAVED, (unsigned)channels,
                               (unsigned)rate, 0, (unsigned)((int64_t)block * 4 * 1000000 / rate));
    if (e < 0) {
        marie_component_fail_reason(c, "%s %s: %s", st == SND_PCM_STREAM_CAPTURE ? "capture" : "playback", dev,
                                    snd_strerror(e));
        if (*pcm)
            snd_pcm_close(*pcm);
        *pcm = NULL;
        return -1;
    }
    return 0;
}

static void close_all(marie_component_t *c, audio_t *s)
{
    for (int i = 0; i < s->nfds; i++)
        marie_loop_remove_fd(marie_component_loop(c), s->fds[i].fd);
    s->nfds = 0;
    if (s->cap)
        snd_pcm_close(s->cap);
    if (s->play)
        snd_pcm_close(s->play);
    s->cap = s->play = NULL;
    audio_blocker_free(&s->blocker);
    MARIE_CLEAR(s->rbuf, free);
}

static int init(marie_component_t *c)
{
    audio_t *s = marie_component_user(c);
    const audio_params_t *q = marie_component_params(c);
    close_all(c, s);
    s->c = c;
    int channels = (int)q->channels, rate = (int)q->rate, block = (int)q->block;
    s->p_audio = marie_port(c, "audio");
    if (audio_blocker_init(&s->blocker, channels, block, rate, on_block, s) ||
        !(s->rbuf = malloc(sizeof(int16_t) * (size_t)channels * (size_t)block))) {
        marie_component_fail_reason(c, "channels in [1, 64], block in [1, 65536], rate > 0");
        return -1;
    }
    if (*q->device) {
        if (open_pcm(c, &s->cap, q->device, SND_PCM_STREAM_CAPTURE, channels, rate, block))
            return -1;
        s->nfds = snd_pcm_poll_descriptors(s->cap, s->fds, MAX_FDS);
        for (int i = 0; i < s->nfds; i++)
            marie_loop_add_fd(marie_component_loop(c), s->fds[i].fd, s->fds[i].events, on_capture, s);
        snd_pcm_start(s->cap);
    }
    if (*q->playback) {
        if (open_pcm(c, &s->play, q->playback, SND_PCM_STREAM_PLAYBACK, 1, rate, block))
            return -1;
        marie_port_on_message(marie_port(c, "play"), on_play);
    }
    marie_info("capture %s (%d ch), playback %s, %d Hz, blocks of %d", *q->device ? q->device : "off", channels,
               *q->playback ? q->playback : "off", rate, block);
    return 0;
}

static void quit(marie_component_t *c)
{
    close_all(c, marie_component_user(c));
}

static const marie_port_spec_t ports[] = {
    { "audio", &marie_type_audio_frame_t, MARIE_OUT, MARIE_PUSH, "AUDIO" },
    { "play", &marie_type_audio_frame_t, MARIE_IN, MARIE_PUSH, "TTS_AUDIO" },
    { 0 },
};

static const marie_param_spec_t params[] = AUDIO_PARAMS;

static const marie_component_def_t def = {
    .kind = "audio", .ports = ports, .params = params, .params_size = sizeof(audio_params_t),
    .on_init = init, .on_quit = quit,
};

int main(int argc, char **argv)
{
    audio_t s = { 0 };
    return marie_main(&def, argc, argv, &s);
}
