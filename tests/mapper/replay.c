/* replay: the mapper's library fed as marie-mapper feeds it, scan by scan, timed. */
#include "tests/mapper/replay.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "adapters/common/posebuf.h"
#include "adapters/common/scanwait.h"

struct replay {
    slam_t *slam;
    posebuf_t odom;
    scanwait_t wait;
    int64_t last_scan;
    replay_scan_t *scans;
    size_t n, cap;
};

/* scanwait's callbacks carry no user pointer: one replay placing scans at a time. */
static replay_t *current;

replay_t *replay_create(const slam_params_t *p, const double start[3])
{
    replay_t *r = calloc(1, sizeof *r);
    if (!r)
        return NULL;
    if (!(r->slam = slam_create(p, start))) {
        free(r);
        return NULL;
    }
    posebuf_clear(&r->odom);
    r->last_scan = INT64_MIN;
    return r;
}

void replay_destroy(replay_t *r)
{
    if (!r)
        return;
    slam_destroy(r->slam);
    scanwait_free(&r->wait);
    free(r->scans);
    free(r);
}

static double now_ms(void)
{
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);   /* the mapper's own cost, whatever else the machine runs */
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec / 1e6;
}

static void place(marie_component_t *c, const marie_laser_scan_t *m)
{
    replay_t *r = current;
    double od[3], pose[3];
    if (!posebuf_at(&r->odom, m->utime, od) || m->utime <= r->last_scan)
        return;
    slam_scan_t ss = { m->ranges, m->nranges, m->angle_min, m->angle_increment, m->range_min, m->range_max };
    slam_stats_t before, after;
    slam_get_stats(r->slam, &before);
    double t0 = now_ms();
    if (slam_add_scan(r->slam, od, &ss, pose) < 0)
        return;
    double ms = now_ms() - t0;
    slam_get_stats(r->slam, &after);
    r->last_scan = m->utime;
    if (r->n == r->cap) {
        size_t cap = r->cap ? 2 * r->cap : 4096;
        replay_scan_t *s = realloc(r->scans, cap * sizeof *s);
        if (!s)
            abort();
        r->scans = s;
        r->cap = cap;
    }
    r->scans[r->n++] = (replay_scan_t){ m->utime, { pose[0], pose[1], pose[2] }, { od[0], od[1], od[2] }, ms,
                                        after.optimizations > before.optimizations };
}

void replay_odometry(replay_t *r, int64_t utime, const double pose[3])
{
    if (posebuf_newest(&r->odom) != INT64_MIN && utime <= posebuf_newest(&r->odom))
        return;
    posebuf_add(&r->odom, utime, pose);
    current = r;
    scanwait_odometry(&r->wait, NULL, utime, place);
}

void replay_laser(replay_t *r, const marie_laser_scan_t *m)
{
    if (m->utime <= r->last_scan)
        return;
    current = r;
    scanwait_scan(&r->wait, NULL, &r->odom, m, place);
}

slam_t *replay_slam(replay_t *r) { return r->slam; }

const replay_scan_t *replay_scans(const replay_t *r, size_t *n)
{
    *n = r->n;
    return r->scans;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

void replay_times(const replay_t *r, replay_times_t *t)
{
    memset(t, 0, sizeof *t);
    double *ms = malloc((r->n ? r->n : 1) * sizeof *ms);
    if (!ms)
        return;
    size_t n = 0;
    for (size_t i = 0; i < r->n; i++) {
        t->total_s += r->scans[i].ms / 1e3;
        if (r->scans[i].optimized) {
            t->closures++;
            if (r->scans[i].ms > t->closure_max)
                t->closure_max = r->scans[i].ms;
        } else {
            ms[n++] = r->scans[i].ms;
        }
    }
    if (n) {
        qsort(ms, n, sizeof *ms, cmp_double);
        t->p50 = ms[n / 2];
        t->p99 = ms[(size_t)(0.99 * (double)(n - 1) + 0.5)];
        t->max = ms[n - 1];
    }
    free(ms);
}
