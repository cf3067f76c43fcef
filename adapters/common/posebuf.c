/* posebuf: odometry history for the pose at a measurement's time, shared by the adapters. */
#include "adapters/common/posebuf.h"

#include <math.h>
#include <string.h>

static double wrap(double a)
{
    return atan2(sin(a), cos(a));
}

void posebuf_clear(posebuf_t *b)
{
    b->n = b->head = 0;
}

void posebuf_add(posebuf_t *b, int64_t utime, const double pose[3])
{
    b->utime[b->head] = utime;
    memcpy(b->pose[b->head], pose, sizeof b->pose[0]);
    b->head = (b->head + 1) % POSEBUF_CAP;
    if (b->n < POSEBUF_CAP)
        b->n++;
}

bool posebuf_at(const posebuf_t *b, int64_t t, double out[3])
{
    if (b->n == 0)
        return false;
    int prev = -1;
    for (int k = 0; k < b->n; k++) {
        int i = (b->head - b->n + k + POSEBUF_CAP) % POSEBUF_CAP;
        if (b->utime[i] >= t) {
            if (prev < 0 || b->utime[i] == b->utime[prev]) {
                memcpy(out, b->pose[i], sizeof b->pose[0]);
            } else {
                double a = (double)(t - b->utime[prev]) / (double)(b->utime[i] - b->utime[prev]);
                out[0] = b->pose[prev][0] + a * (b->pose[i][0] - b->pose[prev][0]);
                out[1] = b->pose[prev][1] + a * (b->pose[i][1] - b->pose[prev][1]);
                out[2] = wrap(b->pose[prev][2] + a * wrap(b->pose[i][2] - b->pose[prev][2]));
            }
            return true;
        }
        prev = i;
    }
    memcpy(out, b->pose[prev], sizeof b->pose[0]);
    return true;
}

int64_t posebuf_newest(const posebuf_t *b)
{
    return b->n ? b->utime[(b->head - 1 + POSEBUF_CAP) % POSEBUF_CAP] : INT64_MIN;
}

bool posebuf_covers(const posebuf_t *b, int64_t t, int64_t slack)
{
    return b->n && t >= b->utime[(b->head - b->n + POSEBUF_CAP) % POSEBUF_CAP] && t <= posebuf_newest(b) + slack;
}

bool posebuf_last(const posebuf_t *b, double out[3])
{
    if (b->n == 0)
        return false;
    memcpy(out, b->pose[(b->head - 1 + POSEBUF_CAP) % POSEBUF_CAP], sizeof b->pose[0]);
    return true;
}

void pose2d_compose(const double a[3], const double b[3], double out[3])
{
    double c = cos(a[2]), s = sin(a[2]);
    out[0] = a[0] + c * b[0] - s * b[1];
    out[1] = a[1] + s * b[0] + c * b[1];
    out[2] = wrap(a[2] + b[2]);
}

void pose2d_between(const double a[3], const double b[3], double out[3])
{
    double c = cos(a[2]), s = sin(a[2]), dx = b[0] - a[0], dy = b[1] - a[1];
    out[0] = c * dx + s * dy;
    out[1] = -s * dx + c * dy;
    out[2] = wrap(b[2] - a[2]);
}

bool posebuf_frame_changed(const posebuf_t *b, const marie_odometry_t *m, double last_distance, double *jump)
{
    double last[3];
    *jump = 0;
    if (!posebuf_last(b, last))
        return false;
    int64_t last_utime = posebuf_newest(b);
    double dt = (double)(m->utime - last_utime) / 1e6;
    *jump = hypot(m->pose.x - last[0], m->pose.y - last[1]);
    return m->utime < last_utime || m->distance < last_distance - 1e-6 || *jump > 0.5 + 3.0 * fabs(dt);
}
