/* speaker_dir: where a speaker was while the words were said. marie-ssl's tracks are kept for a
 * few seconds, and an utterance's direction is the mean of its source's directions over the
 * utterance, weighed by how strongly and surely the source was heard. A track's latest
 * direction will not do: by the time the recognizer has waited out the end of the words, the
 * track coasts on its last rate (about 10 degrees in a second, measured) or is gone. Pure. */
#ifndef MARIE_SPEAKER_DIR_H
#define MARIE_SPEAKER_DIR_H
#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* 10 Hz x 16 sources x 12 s: more than an utterance (6 s at most) and its decoding. */
#define SPEAKER_DIR_MAX 2048

typedef struct {
    int64_t utime;
    int id;
    float azimuth;              /* rad, robot frame */
    float weight;               /* energy x activity */
} speaker_dir_sighting_t;

typedef struct {
    speaker_dir_sighting_t s[SPEAKER_DIR_MAX];
    int next, n;
} speaker_dir_t;

void speaker_dir_init(speaker_dir_t *h);

/* One tracked source as marie-ssl reported it at utime. */
void speaker_dir_add(speaker_dir_t *h, int64_t utime, int id, double azimuth, double energy, double activity);

/* Source id's direction over [t0, t1] (the utterance), into *azimuth: the weighed circular mean
 * of its sightings there; if none was heard (all weights 0), its first sighting there; if it
 * was not seen there at all, its latest sighting before t1. false when it was never seen. */
bool speaker_dir_get(const speaker_dir_t *h, int id, int64_t t0, int64_t t1, double *azimuth);

#ifdef __cplusplus
}
#endif
#endif
