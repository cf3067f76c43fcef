/* ssl: the array pipeline of marie-ssl (see ssl.h). Frames of nfft samples every hop, windowed
 * by a square-root Hann window on analysis and on synthesis so that the separated streams
 * overlap-add back without distortion. */
#include "adapters/ssl/ssl.h"

#include <errno.h>
#include <fftw3.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"

typedef struct {
    int id;                     /* 0: free */
    float *ola;                 /* nfft */
    ssl_postfilter_t pf;
    int64_t seq;
} stream_t;

struct ssl {
    ssl_cfg_t cfg;
    ssl_result_cb_t cb;
    void *user;
    ssl_srp_t *srp;
    ssl_tracker_t tracker;
    int M, nfft, hop, nbins;
    float *ring;                /* M * nfft, newest samples last */
    int fill;                   /* new samples since the last frame */
    int64_t next_utime;         /* time of the next sample to arrive */
    float *window;
    float *fin;
    fftwf_complex *spec_mem;
    float complex **spec;
    fftwf_plan fwd, inv;
    float complex *Y;
    float *yout;
    stream_t streams[SSL_TRACK_MAX];
    float *out[SSL_TRACK_MAX];  /* hop samples handed out */
    float complex *hist;        /* the spectra of the last nhist frames (M x stride each), a ring */
    int nhist, hist_next, hist_fill;
    float *back[SSL_TRACK_MAX]; /* a new stream's history, nhist * hop samples */
};

void ssl_cfg_default(ssl_cfg_t *c)
{
    memset(c, 0, sizeof(*c));
    micarray_parse(MICARRAY_DEFAULT, &c->mics, NULL);
    ssl_srp_cfg_default(&c->srp);
    ssl_track_cfg_default(&c->track);
    ssl_sep_cfg_default(&c->sep);
    c->hop = (int)c->srp.nfft / 2;
    c->stream = (ssl_stream_params_t)SSL_STREAM_PARAMS_DEFAULTS;
}

void ssl_destroy(ssl_t *s)
{
    if (!s)
        return;
    ssl_srp_destroy(s->srp);
    if (s->fwd)
        fftwf_destroy_plan(s->fwd);
    if (s->inv)
        fftwf_destroy_plan(s->inv);
    fftwf_free(s->fin);
    fftwf_free(s->spec_mem);
    fftwf_free(s->Y);
    fftwf_free(s->yout);
    free(s->spec);
    free(s->ring);
    free(s->window);
    for (int i = 0; i < SSL_TRACK_MAX; i++) {
        free(s->streams[i].ola);
        ssl_postfilter_free(&s->streams[i].pf);
        free(s->out[i]);
        free(s->back[i]);
    }
    free(s->hist);
    free(s);
}

/* Each microphone's spectrum starts on a 16-byte boundary, as FFTW's SIMD plan expects. */
static int spec_stride(const ssl_t *s)
{
    return (s->nbins + 1) & ~1;
}

ssl_t *ssl_create(const ssl_cfg_t *cfg, ssl_result_cb_t cb, void *user)
{
    if (cfg->hop * 2 != cfg->srp.nfft || cfg->srp.potentials < 1 || cfg->srp.potentials > SSL_MAX_POTENTIALS ||
        !(cfg->stream.backfill_s >= 0 && cfg->stream.backfill_s <= 10))
        return marie_fail_null(EINVAL);
    ssl_t *s = calloc(1, sizeof(*s));
    if (!s)
        return NULL;
    s->cfg = *cfg;
    s->cb = cb;
    s->user = user;
    s->M = cfg->mics.n;
    s->nfft = (int)cfg->srp.nfft;
    s->hop = cfg->hop;
    s->nbins = s->nfft / 2 + 1;
    s->cfg.track.dt = (double)s->hop / cfg->srp.rate;
    if (!(s->srp = ssl_srp_create(&cfg->srp, &cfg->mics)))
        goto fail;
    ssl_tracker_init(&s->tracker, &s->cfg.track);
    s->ring = calloc((size_t)s->M * (size_t)s->nfft, sizeof(float));
    s->window = malloc(sizeof(float) * (size_t)s->nfft);
    s->spec = malloc(sizeof(*s->spec) * (size_t)s->M);
    s->fin = fftwf_alloc_real((size_t)s->nfft);
    s->yout = fftwf_alloc_real((size_t)s->nfft);
    s->spec_mem = fftwf_alloc_complex((size_t)spec_stride(s) * (size_t)s->M);
    s->Y = fftwf_alloc_complex((size_t)s->nbins);
    if (!s->ring || !s->window || !s->spec || !s->fin || !s->yout || !s->spec_mem || !s->Y)
        goto fail;
    for (int m = 0; m < s->M; m++)
        s->spec[m] = (float complex *)(s->spec_mem + (size_t)m * spec_stride(s));
    for (int i = 0; i < s->nfft; i++)
        s->window[i] = (float)sqrt(0.5 - 0.5 * cos(2 * M_PI * i / s->nfft));
    s->fwd = fftwf_plan_dft_r2c_1d(s->nfft, s->fin, s->spec_mem, FFTW_ESTIMATE);
    s->inv = fftwf_plan_dft_c2r_1d(s->nfft, s->Y, s->yout, FFTW_ESTIMATE);
    if (!s->fwd || !s->inv)
        goto fail;
    s->nhist = (int)(cfg->stream.backfill_s * cfg->srp.rate / s->hop + 0.5);
    if (s->nhist && !(s->hist = malloc(sizeof(float complex) * (size_t)(s->nhist * s->M * spec_stride(s)))))
        goto fail;
    for (int i = 0; i < SSL_TRACK_MAX; i++) {
        s->streams[i].ola = calloc((size_t)s->nfft, sizeof(float));
        s->out[i] = malloc(sizeof(float) * (size_t)s->hop);
        s->back[i] = malloc(sizeof(float) * (size_t)(s->hop * (s->nhist + 1)));
        if (!s->streams[i].ola || !s->out[i] || !s->back[i] || ssl_postfilter_init(&s->streams[i].pf, s->nbins))
            goto fail;
    }
    return s;
fail:
    ssl_destroy(s);
    errno = errno ? errno : ENOMEM;
    return NULL;
}

int ssl_rate(const ssl_t *s)
{
    return (int)s->cfg.srp.rate;
}

static void analyse(ssl_t *s)
{
    for (int m = 0; m < s->M; m++) {
        const float *x = s->ring + (size_t)m * s->nfft;
        for (int i = 0; i < s->nfft; i++)
            s->fin[i] = x[i] * s->window[i];
        fftwf_execute_dft_r2c(s->fwd, s->fin, (fftwf_complex *)s->spec[m]);
    }
}

/* This frame's spectra into the history ring (after it has been used: the history is of the
 * frames before the current one). */
static void remember(ssl_t *s)
{
    if (!s->nhist)
        return;
    size_t one = (size_t)s->M * (size_t)spec_stride(s);
    memcpy(s->hist + (size_t)s->hist_next * one, s->spec_mem, sizeof(float complex) * one);
    s->hist_next = (s->hist_next + 1) % s->nhist;
    s->hist_fill += s->hist_fill < s->nhist;
}

static stream_t *stream_for(ssl_t *s, int id, bool *fresh)
{
    stream_t *free_slot = NULL;
    *fresh = false;
    for (int i = 0; i < SSL_TRACK_MAX; i++) {
        if (s->streams[i].id == id)
            return &s->streams[i];
        if (!s->streams[i].id && !free_slot)
            free_slot = &s->streams[i];
    }
    if (free_slot) {
        *fresh = true;
        free_slot->id = id;
        free_slot->seq = 0;
        memset(free_slot->ola, 0, sizeof(float) * (size_t)s->nfft);
        ssl_postfilter_free(&free_slot->pf);
        ssl_postfilter_init(&free_slot->pf, s->nbins);
    }
    return free_slot;
}

/* Streams of tracks that died are released. */
static void release_streams(ssl_t *s)
{
    for (int i = 0; i < SSL_TRACK_MAX; i++) {
        bool alive = false;
        for (int t = 0; t < s->tracker.n && !alive; t++)
            alive = s->tracker.t[t].confirmed && s->tracker.t[t].id == s->streams[i].id;
        if (!alive)
            s->streams[i].id = 0;
    }
}

/* One frame's spectra X (M pointers) beamed toward source k of dirs into the stream's next hop. */
static void beam_hop(ssl_t *s, stream_t *st, const float complex *const *X, const double (*dirs)[3], int n, int k,
                     float *hop)
{
    ssl_sep_beam(&s->cfg.sep, &s->cfg.mics, s->cfg.srp.rate, s->nfft, X, dirs, n, k, s->Y);
    if (s->cfg.sep.postfilter)
        ssl_postfilter_apply(&st->pf, &s->cfg.sep, s->Y);
    fftwf_execute_dft_c2r(s->inv, s->Y, s->yout);
    for (int i = 0; i < s->nfft; i++)
        st->ola[i] += s->yout[i] * s->window[i] / (float)s->nfft;
    memcpy(hop, st->ola, sizeof(float) * (size_t)s->hop);
    memmove(st->ola, st->ola + s->hop, sizeof(float) * (size_t)(s->nfft - s->hop));
    memset(st->ola + s->nfft - s->hop, 0, sizeof(float) * (size_t)s->hop);
}

/* A new stream: the remembered frames, oldest first, beamed toward it; returns the hops made. */
static int backfill(ssl_t *s, stream_t *st, int slot, const double (*dirs)[3], int n, int k)
{
    size_t one = (size_t)s->M * (size_t)spec_stride(s);
    const float complex *X[MICARRAY_MAX];
    for (int f = 0; f < s->hist_fill; f++) {
        int at = (s->hist_next - s->hist_fill + f + s->nhist) % s->nhist;
        for (int m = 0; m < s->M; m++)
            X[m] = s->hist + (size_t)at * one + (size_t)m * spec_stride(s);
        beam_hop(s, st, X, dirs, n, k, s->back[slot] + (size_t)f * s->hop);
    }
    return s->hist_fill;
}

static void separate(ssl_t *s, ssl_result_t *r)
{
    double dirs[SSL_TRACK_MAX][3];
    const ssl_track_t *tr[SSL_TRACK_MAX];
    int n = 0;
    for (int i = 0; i < s->tracker.n; i++) {
        const ssl_track_t *t = &s->tracker.t[i];
        if (!t->confirmed)
            continue;
        dirs[n][0] = cos(t->elevation) * cos(t->azimuth);
        dirs[n][1] = cos(t->elevation) * sin(t->azimuth);
        dirs[n][2] = sin(t->elevation);
        tr[n++] = t;
    }
    release_streams(s);
    for (int k = 0; k < n; k++) {
        bool fresh;
        stream_t *st = stream_for(s, tr[k]->id, &fresh);
        if (!st)
            continue;
        int slot = r->nstreams++;
        int nhistory = fresh && s->cfg.nfixed <= 0 ? backfill(s, st, slot, (const double (*)[3])dirs, n, k) : 0;
        st->seq += nhistory;
        beam_hop(s, st, (const float complex *const *)s->spec, (const double (*)[3])dirs, n, k, s->out[slot]);
        r->streams[slot] = (ssl_stream_t){ .id = tr[k]->id, .azimuth = tr[k]->azimuth,
                                           .elevation = tr[k]->elevation, .seq = st->seq++,
                                           .samples = s->out[slot], .nhistory = nhistory,
                                           .history = s->back[slot] };
    }
}

/* Steered mode: the beams point where the configuration says (a face tracker, a test). */
static void fix_tracks(ssl_t *s, int64_t utime)
{
    int n = s->cfg.nfixed < SSL_TRACK_MAX ? s->cfg.nfixed : SSL_TRACK_MAX;
    s->tracker.n = n;
    for (int i = 0; i < n; i++)
        s->tracker.t[i] = (ssl_track_t){ .id = i + 1, .confirmed = true, .azimuth = s->cfg.fixed[i][0],
                                         .elevation = s->cfg.fixed[i][1], .activity = 1, .seen = true,
                                         .last_utime = utime };
}

static void frame(ssl_t *s)
{
    ssl_result_t r = { .utime = s->next_utime - (int64_t)s->nfft * 1000000 / s->cfg.srp.rate };
    r.stream_utime = r.utime;
    analyse(s);
    r.npot = ssl_srp_frame(s->srp, (const float complex *const *)s->spec, r.pot, (int)s->cfg.srp.potentials);
    if (s->cfg.nfixed > 0)
        fix_tracks(s, r.utime);
    else
        ssl_tracker_update(&s->tracker, r.pot, r.npot, r.utime);
    r.tracker = &s->tracker;
    if (s->cfg.sep.separate)
        separate(s, &r);
    if (s->cb)
        s->cb(&r, s->user);
    remember(s);
}

static int feed(ssl_t *s, const int16_t *i16, const float *f32, int nchannels, int nsamples, int64_t utime)
{
    if (nchannels != s->M || nsamples < 0)
        return marie_fail(EINVAL);
    int rate = (int)s->cfg.srp.rate;
    for (int j = 0; j < nsamples; j++) {
        for (int m = 0; m < s->M; m++) {
            float *x = s->ring + (size_t)m * s->nfft;
            size_t at = (size_t)j * (size_t)nchannels + (size_t)m;
            x[s->nfft - s->hop + s->fill] = i16 ? i16[at] / 32768.0f : f32[at];
        }
        s->fill++;
        s->next_utime = utime + (int64_t)(j + 1) * 1000000 / rate;
        if (s->fill == s->hop) {
            frame(s);
            for (int m = 0; m < s->M; m++) {
                float *x = s->ring + (size_t)m * s->nfft;
                memmove(x, x + s->hop, sizeof(float) * (size_t)(s->nfft - s->hop));
            }
            s->fill = 0;
        }
    }
    return 0;
}

int ssl_feed_int16(ssl_t *s, const int16_t *data, int nchannels, int nsamples, int64_t utime)
{
    return feed(s, data, NULL, nchannels, nsamples, utime);
}

int ssl_feed_float(ssl_t *s, const float *data, int nchannels, int nsamples, int64_t utime)
{
    return feed(s, NULL, data, nchannels, nsamples, utime);
}
