/* scanwait: a laser scan meets the odometry of its own instant. */
#include "adapters/common/scanwait.h"

#include <stdlib.h>
#include <string.h>

static void count(marie_component_t *c, const char *counter)
{
    if (c)
        marie_component_count(c, counter, 1);
}

/* Copy m into the next free slot (intensities are not kept). 0, or -1 (ENOMEM): it does not wait. */
static int hold(scanwait_t *w, const marie_laser_scan_t *m)
{
    scanwait_slot_t *s = &w->slot[(w->head + w->n) % SCANWAIT_CAP];
    if (m->nranges > s->cap) {
        float *r = realloc(s->scan.ranges, sizeof(float) * (size_t)m->nranges);
        if (!r)
            return -1;
        s->scan.ranges = r;
        s->cap = m->nranges;
    }
    float *r = s->scan.ranges;
    s->scan = *m;
    s->scan.ranges = r;
    memcpy(r, m->ranges, sizeof(float) * (size_t)m->nranges);
    s->scan.nintensities = 0;
    s->scan.intensities = NULL;
    w->n++;
    return 0;
}

/* Take the oldest waiting scan out of the queue; its slot stays valid until the next hold(). */
static const marie_laser_scan_t *pop(scanwait_t *w)
{
    const marie_laser_scan_t *m = &w->slot[w->head].scan;
    w->head = (w->head + 1) % SCANWAIT_CAP;
    w->n--;
    return m;
}

void scanwait_scan(scanwait_t *w, marie_component_t *c, const posebuf_t *odom, const marie_laser_scan_t *m,
                   scanwait_fn fn)
{
    if (odom->n == 0) {
        count(c, "scans_without_odometry");
        return;
    }
    if (posebuf_newest(odom) >= m->utime) {
        while (w->n)            /* older than this one, so covered too */
            fn(c, pop(w));
        fn(c, m);
        return;
    }
    if (w->n && m->utime <= w->slot[(w->head + w->n - 1) % SCANWAIT_CAP].scan.utime) {
        count(c, "scans_out_of_order");     /* not after the newest waiting one */
        return;
    }
    if (w->n == SCANWAIT_CAP) {
        /* Odometry a whole queue behind: the oldest would be placed with odometry older than
         * itself (a turning robot's heading off by more than any matcher searches), so it goes. */
        count(c, "scans_late_odometry");
        pop(w);
    }
    hold(w, m);
}

void scanwait_odometry(scanwait_t *w, marie_component_t *c, int64_t utime, scanwait_fn fn)
{
    while (w->n && w->slot[w->head].scan.utime <= utime)
        fn(c, pop(w));
}

int scanwait_waiting(const scanwait_t *w) { return w->n; }

void scanwait_drop(scanwait_t *w)
{
    w->head = 0;
    w->n = 0;
}

void scanwait_free(scanwait_t *w)
{
    for (int i = 0; i < SCANWAIT_CAP; i++)
        free(w->slot[i].scan.ranges);
    memset(w, 0, sizeof *w);
}
