/* scanwait: a laser scan meets the odometry of its own instant. */
#include "adapters/common/scanwait.h"

#include <stdlib.h>
#include <string.h>

/* Copy m into the wait slot (intensities are not kept). 0, or -1 (ENOMEM): nothing waits. */
static int hold(scanwait_t *w, const marie_laser_scan_t *m)
{
    if (m->nranges > w->cap) {
        float *n = realloc(w->ranges, sizeof(float) * (size_t)m->nranges);
        if (!n)
            return -1;
        w->ranges = n;
        w->cap = m->nranges;
    }
    w->scan = *m;
    memcpy(w->ranges, m->ranges, sizeof(float) * (size_t)m->nranges);
    w->scan.ranges = w->ranges;
    w->scan.nintensities = 0;
    w->scan.intensities = NULL;
    w->held = true;
    return 0;
}

void scanwait_scan(scanwait_t *w, marie_component_t *c, const posebuf_t *odom, const marie_laser_scan_t *m,
                   scanwait_fn fn)
{
    if (odom->n == 0) {
        marie_component_count(c, "scans_without_odometry", 1);
        return;
    }
    if (posebuf_newest(odom) >= m->utime) {
        fn(c, m);
        return;
    }
    /* The odometry that brackets it is at most one period behind. */
    if (w->held) {
        marie_component_count(c, "scans_late_odometry", 1);
        w->held = false;
        fn(c, &w->scan);
    }
    hold(w, m);
}

void scanwait_odometry(scanwait_t *w, marie_component_t *c, int64_t utime, scanwait_fn fn)
{
    if (w->held && utime >= w->scan.utime) {
        w->held = false;
        fn(c, &w->scan);
    }
}

void scanwait_drop(scanwait_t *w) { w->held = false; }

void scanwait_free(scanwait_t *w)
{
    free(w->ranges);
    memset(w, 0, sizeof *w);
}
