/* micarray: a microphone array's geometry (robot frame, m), parsed from one text parameter. */
#include "hw/audio/micarray.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"

static int refuse(const char **why, const char *reason)
{
    if (why)
        *why = reason;
    return marie_fail(EINVAL);
}

int micarray_parse(const char *text, micarray_t *out, const char **why)
{
    memset(out, 0, sizeof(*out));
    if (!text)
        return refuse(why, "no geometry");
    const char *p = text;
    for (;;) {
        if (out->n == MICARRAY_MAX)
            return refuse(why, "too many microphones");
        for (int k = 0; k < 3; k++) {
            char *end;
            errno = 0;
            double v = strtod(p, &end);
            if (end == p || errno || !isfinite(v) || fabs(v) > 10)
                return refuse(why, "expected x,y,z numbers within 10 m");
            out->pos[out->n][k] = v;
            p = end;
            while (*p == ' ')
                p++;
            if (k < 2 && *p++ != ',')
                return refuse(why, "expected ',' between coordinates");
        }
        out->n++;
        if (*p == 0)
            break;
        if (*p++ != ';')
            return refuse(why, "expected ';' between microphones");
        while (*p == ' ')
            p++;
        if (*p == 0)
            break;
    }
    if (out->n < 2)
        return refuse(why, "at least two microphones");
    for (int i = 0; i < out->n; i++)
        for (int k = 0; k < 3; k++)
            out->center[k] += out->pos[i][k] / out->n;
    return 0;
}

double micarray_aperture(const micarray_t *a)
{
    double best = 0;
    for (int i = 0; i < a->n; i++)
        for (int j = i + 1; j < a->n; j++) {
            double d = 0;
            for (int k = 0; k < 3; k++)
                d += (a->pos[i][k] - a->pos[j][k]) * (a->pos[i][k] - a->pos[j][k]);
            best = fmax(best, sqrt(d));
        }
    return best;
}
