/* ssl: the array pipeline of marie-ssl: framing of multi-channel blocks, SRP-PHAT, tracking and
 * separation, one result per hop. Pure: samples in, results through a callback. */
#ifndef MARIE_SSL_H
#define MARIE_SSL_H
#include <stdint.h>

#include "adapters/ssl/ssl_sep.h"
#include "adapters/ssl/ssl_stream_params.h"
#include "adapters/ssl/ssl_srp.h"
#include "adapters/ssl/ssl_track.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SSL_MAX_POTENTIALS 4

typedef struct {
    micarray_t mics;
    ssl_srp_cfg_t srp;          /* rate and nfft of the whole pipeline, potentials per frame (<= 4) */
    ssl_track_cfg_t track;      /* dt is set from the hop */
    ssl_sep_cfg_t sep;          /* separate: beam the tracked sources at all */
    int hop;                    /* nfft / 2 */
    /* A new track's stream starts with the sound of the stream.backfill_s before its birth,
     * beamed toward it: the birth comes a few frames after the onset, and the words' first
     * syllable (and the quiet before it, which a voice detector measures its floor on) is there. */
    ssl_stream_params_t stream;
    int nfixed;                 /* > 0: no tracking, beams toward these (az, el) with ids 1..n */
    double fixed[SSL_TRACK_MAX][2];
} ssl_cfg_t;

void ssl_cfg_default(ssl_cfg_t *c);     /* the default array of micarray.h */

typedef struct {
    int id;
    double azimuth, elevation;
    int64_t seq;                /* of samples; the history's hops take the seqs before it */
    const float *samples;       /* hop samples, full scale 1 */
    int nhistory;               /* a new stream: hops before samples (backfill_s), oldest first */
    const float *history;       /* nhistory * hop samples, ending where samples start */
} ssl_stream_t;

typedef struct {
    int64_t utime;              /* first sample of the frame this result is about */
    int npot;
    ssl_potential_t pot[SSL_MAX_POTENTIALS];
    const ssl_tracker_t *tracker;   /* confirmed tracks are the sources */
    int nstreams;
    ssl_stream_t streams[SSL_TRACK_MAX];
    int64_t stream_utime;       /* first sample of the separated hop (one frame late) */
} ssl_result_t;

typedef void (*ssl_result_cb_t)(const ssl_result_t *r, void *user);

typedef struct ssl ssl_t;

ssl_t *ssl_create(const ssl_cfg_t *cfg, ssl_result_cb_t cb, void *user);  /* NULL + errno */
void ssl_destroy(ssl_t *s);

/* nsamples samples of every channel (interleaved, nchannels == the array's count), the first
 * one at utime. -1 with EINVAL on a channel count that is not the array's. */
int ssl_feed_int16(ssl_t *s, const int16_t *data, int nchannels, int nsamples, int64_t utime);
int ssl_feed_float(ssl_t *s, const float *data, int nchannels, int nsamples, int64_t utime);

int ssl_rate(const ssl_t *s);

#ifdef __cplusplus
}
#endif
#endif
