/* fuzz_carmen: any bytes, split into lines, through both passes of the CARMEN reader: never a
 * crash, and every message it emits is one a mapper can take (finite times that never go back,
 * finite poses, beams that are finite, +inf or NaN, a positive finite range_max). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "tools/log/carmen.h"

typedef struct {
    int64_t last;
} seen_t;

static void on_msg(void *user, const carmen_msg_t *m)
{
    seen_t *s = user;
    if (m->utime < s->last)
        abort();
    s->last = m->utime;
    if (m->kind == CARMEN_ODOMETRY) {
        if (!isfinite(m->pose[0]) || !isfinite(m->pose[1]) || !isfinite(m->pose[2]) || !isfinite(m->distance))
            abort();
        return;
    }
    if (m->n < 1 || !(m->range_max > 0) || !isfinite(m->range_max) || !isfinite(m->angle_min) ||
        !isfinite(m->angle_increment))
        abort();
    for (int i = 0; i < m->n; i++)
        if (isinf(m->ranges[i]) && m->ranges[i] < 0)
            abort();
}

static void each_line(carmen_t *c, const uint8_t *data, size_t size, bool survey, marie_errors_t *errs)
{
    char *text = malloc(size + 1);
    if (!text)
        return;
    memcpy(text, data, size);
    text[size] = '\0';
    for (char *save = NULL, *l = strtok_r(text, "\n", &save); l; l = strtok_r(NULL, "\n", &save))
        survey ? carmen_survey(c, l) : carmen_line(c, l, "fuzz", errs, 5);
    free(text);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    carmen_opts_t o = CARMEN_OPTS_DEFAULT;
    seen_t s = { INT64_MIN };
    carmen_t *c = carmen_create(&o, on_msg, &s);
    if (!c)
        return 0;
    marie_errors_t errs = { 0 };
    each_line(c, data, size, true, NULL);
    carmen_begin(c);
    each_line(c, data, size, false, &errs);
    if (errs.n > 5)
        abort();
    marie_errors_clear(&errs);
    carmen_destroy(c);
    return 0;
}
