/* replay_check: compares the poses a fresh localizer publishes on POSE_REPLAY while a recorded
 * log is played back with the poses recorded on POSE in that log, matched by timestamp.
 *   replay_check LOG SECONDS     prints matched count, median and max error; exit 0 if they agree
 * It listens until the localizer has replayed the log's last pose, or SECONDS at most. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <lcm/lcm.h>

#include "core/time.h"
#include "lcmtypes/marie_types.h"

typedef struct {
    int64_t t;
    double x, y;
} pose_t;

static pose_t *recorded, *replayed;
static size_t nrec, nrep, caprep;

static void on_replay(const lcm_recv_buf_t *rb, const char *ch, const marie_pose_cov_t *m, void *user)
{
    if (nrep == caprep) {
        caprep = caprep ? caprep * 2 : 1024;
        replayed = realloc(replayed, caprep * sizeof *replayed);
    }
    replayed[nrep++] = (pose_t){m->utime, m->pose.x, m->pose.y};
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: replay_check LOG SECONDS\n");
        return 2;
    }
    lcm_eventlog_t *log = lcm_eventlog_create(argv[1], "r");
    if (!log) {
        fprintf(stderr, "replay_check: cannot open %s\n", argv[1]);
        return 2;
    }
    size_t cap = 0;
    lcm_eventlog_event_t *ev;
    while ((ev = lcm_eventlog_read_next_event(log)) != NULL) {
        marie_pose_cov_t m;
        if (strcmp(ev->channel, "POSE") == 0 && marie_pose_cov_t_decode(ev->data, 0, ev->datalen, &m) >= 0) {
            if (nrec == cap) {
                cap = cap ? cap * 2 : 1024;
                recorded = realloc(recorded, cap * sizeof *recorded);
            }
            recorded[nrec++] = (pose_t){m.utime, m.pose.x, m.pose.y};
            marie_pose_cov_t_decode_cleanup(&m);
        }
        lcm_eventlog_free_event(ev);
    }
    lcm_eventlog_destroy(log);
    lcm_t *lcm = lcm_create(NULL);
    marie_pose_cov_t_subscription_t *sub = marie_pose_cov_t_subscribe(lcm, "POSE_REPLAY", on_replay, NULL);
    int64_t end = marie_mono_us() + (int64_t)(atof(argv[2]) * 1e6);
    int64_t last = nrec ? recorded[nrec - 1].t : INT64_MAX;
    while (marie_mono_us() < end && !(nrep && replayed[nrep - 1].t >= last))
        lcm_handle_timeout(lcm, 100);
    marie_pose_cov_t_unsubscribe(lcm, sub);
    lcm_destroy(lcm);
    /* Match by timestamp: both come from the same scans. */
    double *err = malloc((nrep ? nrep : 1) * sizeof *err);
    size_t n = 0, k = 0;
    for (size_t i = 0; i < nrep; i++) {
        while (k < nrec && recorded[k].t < replayed[i].t)
            k++;
        if (k < nrec && recorded[k].t == replayed[i].t)
            err[n++] = hypot(recorded[k].x - replayed[i].x, recorded[k].y - replayed[i].y);
    }
    qsort(err, n, sizeof *err, cmp_double);
    double median = n ? err[n / 2] : NAN, p95 = n ? err[(size_t)(0.95 * (n - 1))] : NAN, max = n ? err[n - 1] : NAN;
    printf("replay_check: %zu recorded, %zu replayed, %zu matched; error median %.3f m, p95 %.3f m, max %.3f m\n",
           nrec, nrep, n, median, p95, max);
    int ok = nrec > 50 && n >= nrec * 8 / 10 && p95 < 0.10;
    free(err);
    free(recorded);
    free(replayed);
    return ok ? 0 : 1;
}
