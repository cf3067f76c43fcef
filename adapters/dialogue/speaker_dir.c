/* speaker_dir: where a speaker was while the words were said (see speaker_dir.h). */
#include "adapters/dialogue/speaker_dir.h"

#include <math.h>
#include <stddef.h>

void speaker_dir_init(speaker_dir_t *h)
{
    h->next = h->n = 0;
}

void speaker_dir_add(speaker_dir_t *h, int64_t utime, int id, double azimuth, double energy, double activity)
{
    double w = energy * activity;
    h->s[h->next] = (speaker_dir_sighting_t){ .utime = utime, .id = id, .azimuth = (float)azimuth,
                                              .weight = isfinite(w) && w > 0 ? (float)w : 0 };
    h->next = (h->next + 1) % SPEAKER_DIR_MAX;
    if (h->n < SPEAKER_DIR_MAX)
        h->n++;
}

/* The k-th sighting, oldest first. */
static const speaker_dir_sighting_t *at(const speaker_dir_t *h, int k)
{
    return &h->s[(h->next - h->n + k + SPEAKER_DIR_MAX) % SPEAKER_DIR_MAX];
}

bool speaker_dir_get(const speaker_dir_t *h, int id, int64_t t0, int64_t t1, double *azimuth)
{
    double c = 0, s = 0;
    const speaker_dir_sighting_t *first = NULL, *before = NULL;
    for (int k = 0; k < h->n; k++) {
        const speaker_dir_sighting_t *g = at(h, k);
        if (g->id != id || g->utime > t1 || !isfinite(g->azimuth))
            continue;
        if (g->utime < t0) {
            before = g;
            continue;
        }
        first = first ? first : g;
        c += g->weight * cos(g->azimuth);
        s += g->weight * sin(g->azimuth);
    }
    if (c != 0 || s != 0)
        *azimuth = atan2(s, c);
    else if (first || before)
        *azimuth = (first ? first : before)->azimuth;
    else
        return false;
    return true;
}
