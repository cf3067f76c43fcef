/* marie-ssl: sound source localization, tracking and separation on a microphone array's
 * audio blocks; publishes the tracked sources and each one's separated stream. */
#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/ssl/ssl.h"
#include "adapters/ssl/ssl_params.h"
#include "core/clear.h"
#include "core/component.h"

typedef struct {
    marie_component_t *c;
    ssl_t *ssl;
    int nmics;
    int64_t next_seq;           /* expected seq of the next input block; -1 before the first */
    int64_t sources_every, frames;
    marie_port_t *p_sources, *p_sep;
    int16_t *pcm;
    int hop;
} ssl_state_t;

static void publish_sources(ssl_state_t *s, const ssl_result_t *r)
{
    marie_sound_source_t src[SSL_TRACK_MAX];
    int n = 0;
    for (int i = 0; i < r->tracker->n; i++) {
        const ssl_track_t *t = &r->tracker->t[i];
        if (!t->confirmed)
            continue;
        src[n] = (marie_sound_source_t){
            .id = t->id, .azimuth = (float)t->azimuth, .elevation = (float)t->elevation,
            .direction = { (float)(cos(t->elevation) * cos(t->azimuth)), (float)(cos(t->elevation) * sin(t->azimuth)),
                           (float)sin(t->elevation) },
            .energy = (float)t->energy, .activity = (float)t->activity, .first_utime = t->first_utime };
        n++;
    }
    marie_sound_sources_t m = { .utime = r->utime, .count = n, .sources = src };
    marie_port_publish(s->p_sources, &m);
}

static void publish_hop(ssl_state_t *s, const ssl_stream_t *st, const float *x, int64_t seq, int64_t utime)
{
    for (int j = 0; j < s->hop; j++)
        s->pcm[j] = (int16_t)lrintf(fmaxf(-32768.0f, fminf(32767.0f, x[j] * 32768.0f)));
    marie_separated_audio_t m = { .utime = utime, .seq = seq, .source_id = st->id, .azimuth = (float)st->azimuth,
                                  .elevation = (float)st->elevation, .sample_rate = ssl_rate(s->ssl),
                                  .nsamples = s->hop, .data = s->pcm };
    marie_port_publish(s->p_sep, &m);
}

static void on_result(const ssl_result_t *r, void *user)
{
    ssl_state_t *s = user;
    if (s->frames++ % s->sources_every == 0)
        publish_sources(s, r);
    for (int i = 0; i < r->nstreams; i++) {
        const ssl_stream_t *st = &r->streams[i];
        for (int h = 0; h < st->nhistory; h++)     /* a new stream's onset, before its first hop */
            publish_hop(s, st, st->history + (size_t)h * s->hop, st->seq - st->nhistory + h,
                        r->stream_utime - (int64_t)(st->nhistory - h) * s->hop * 1000000 / ssl_rate(s->ssl));
        publish_hop(s, st, st->samples, st->seq, r->stream_utime);
    }
}

static void on_audio(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    ssl_state_t *s = marie_component_user(c);
    const marie_audio_frame_t *f = msg;
    int rate = ssl_rate(s->ssl);
    if (f->nchannels != s->nmics || f->sample_rate != rate || f->nsamples < 0 ||
        (int64_t)f->nchannels * f->nsamples != f->nvalues) {
        marie_component_bad_input(c, "bad_audio", "audio block of %d channels x %d samples at %d Hz refused "
                                  "(the array has %d channels at %d Hz)", f->nchannels, f->nsamples,
                                  f->sample_rate, s->nmics, rate);
        return;
    }
    if (s->next_seq >= 0 && f->seq != s->next_seq)
        marie_component_count(c, "lost_blocks", f->seq > s->next_seq ? f->seq - s->next_seq : 1);
    s->next_seq = f->seq + 1;
    marie_component_count(c, "blocks", 1);
    ssl_feed_int16(s->ssl, f->data, f->nchannels, f->nsamples, f->utime);
}

static int init(marie_component_t *c)
{
    ssl_state_t *s = marie_component_user(c);
    const ssl_params_t *q = marie_component_params(c);
    MARIE_CLEAR(s->ssl, ssl_destroy);
    ssl_cfg_t cfg;
    ssl_cfg_default(&cfg);
    const char *why = NULL;
    if (micarray_parse(q->mics, &cfg.mics, &why)) {
        marie_component_fail_reason(c, "mics: %s", why);
        return -1;
    }
    cfg.srp = q->srp;
    cfg.track = q->tracker;
    cfg.sep = q->sep;
    cfg.stream = q->stream;
    cfg.hop = (int)cfg.srp.nfft / 2;
    if (!(q->sources_hz > 0)) {
        marie_component_fail_reason(c, "sources_hz must be > 0");
        return -1;
    }
    free(s->pcm);
    s->c = c;
    s->nmics = cfg.mics.n;
    s->hop = cfg.hop;
    s->next_seq = -1;
    s->frames = 0;
    double frame_hz = (double)cfg.srp.rate / cfg.hop;
    s->sources_every = q->sources_hz >= frame_hz ? 1 : (int64_t)lround(frame_hz / q->sources_hz);
    s->pcm = malloc(sizeof(int16_t) * (size_t)(cfg.hop > 0 ? cfg.hop : 1));
    if (!s->pcm || !(s->ssl = ssl_create(&cfg, on_result, s))) {
        marie_component_fail_reason(c, "cannot set up the pipeline (rate %d, nfft %d, potentials %d): %s",
                                    (int)cfg.srp.rate, (int)cfg.srp.nfft, (int)cfg.srp.potentials,
                                    strerror(errno));
        return -1;
    }
    s->p_sources = marie_port(c, "sources");
    s->p_sep = marie_port(c, "separated");
    if (marie_port_on_message(marie_port(c, "audio"), on_audio)) {
        marie_component_fail_reason(c, "cannot subscribe to the audio");
        return -1;
    }
    return 0;
}

static void quit(marie_component_t *c)
{
    ssl_state_t *s = marie_component_user(c);
    MARIE_CLEAR(s->ssl, ssl_destroy);
    MARIE_CLEAR(s->pcm, free);
}

static const marie_port_spec_t ports[] = {
    { "audio", &marie_type_audio_frame_t, MARIE_IN, MARIE_PUSH, "AUDIO" },
    { "sources", &marie_type_sound_sources_t, MARIE_OUT, MARIE_PUSH, "SOUND_SOURCES" },
    { "separated", &marie_type_separated_audio_t, MARIE_OUT, MARIE_PUSH, "SEPARATED_AUDIO" },
    { 0 },
};

static const marie_param_spec_t params[] = SSL_PARAMS;

static const marie_component_def_t def = {
    .kind = "ssl", .ports = ports, .params = params, .params_size = sizeof(ssl_params_t),
    .on_init = init, .on_quit = quit,
};

int main(int argc, char **argv)
{
    ssl_state_t s = { 0 };
    return marie_main(&def, argc, argv, &s);
}
