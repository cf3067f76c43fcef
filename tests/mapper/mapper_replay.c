/* mapper_replay: a recorded run (an LCM log with LASER and ODOMETRY, and SIM_TRUTH from the
 * simulator) through the mapper's library as marie-mapper feeds it, alone and in log order, so
 * two versions or two settings of the mapper are compared on the very same input (a live run
 * never gives the same input twice). Prints the mapper's counters, its trajectory against the
 * truth (ATE) and the map against a world (as `marie map compare`). Not installed.
 *   mapper_replay LOG [--world W.yaml] [--start X Y TH] [--save NAME] [--traj FILE] [--truth-odometry] [--times]
 *                 [PARAM=VALUE ...]
 * (--times: the mapper's time per scan, p50 p99 max; --traj: "utime x y theta" of each scan placed, then the truth's and the odometry's "x y theta"
 * at its time, the truth's NaN where it has none; --truth-odometry: the simulator's truth stands
 * in for the odometry, so what error is left is the scan matcher's and the map's own).
 * PARAMs are the mapper library's (adapters/mapper/slam.params.yaml); only the log's first run
 * is read (it ends where the simulated time goes back, as in marie-demo's two-part logs). The log
 * is read with the viewer's parser (core/lcmlog), which resynchronises past damage and
 * counts it as `corrupt`. */
#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "adapters/common/posebuf.h"
#include "adapters/common/scanwait.h"
#include "adapters/mapper/slam.h"
#include "adapters/mapper/slam_params.h"
#include "core/config.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_laser_scan_t.h"
#include "lcmtypes/marie_odometry_t.h"
#include "lcmtypes/marie_pose_cov_t.h"
#include "lcmtypes/marie_types.h"
#include "map/mapeval.h"
#include "map/occmap.h"
#include "map/trajeval.h"
#include "core/lcmlog.h"

static const marie_param_spec_t slam_spec[] = SLAM_PARAMS;

typedef struct {
    slam_t *slam;
    posebuf_t odom;
    scanwait_t wait;
    int64_t last_scan;
    double (*est)[7];           /* utime, x, y, theta of each placed scan, and its odometry x, y, theta */
    size_t nest, cap;
    struct { int64_t t; double x, y, th; } *truth; /* SIM_TRUTH, in time order */
    size_t nt, tcap;
    traj_pose_t *ref;           /* REFERENCE (an imported log's own estimate), in time order */
    size_t nref, rcap;
    double *ms;                 /* each placed scan's time in the mapper, ms */
    size_t undecodable;
    bool done;                  /* the log's first run is over */
    bool truth_odometry;        /* --truth-odometry */
    bool times;                 /* --times: the mapper's time per scan (differs from run to run) */
} replay_t;

static replay_t R;

/* NAME=VALUE onto the library's parameters: 0, or -1 with a message. */
static int set_param(slam_params_t *p, const char *arg)
{
    const char *eq = strchr(arg, '=');
    for (const marie_param_spec_t *s = slam_spec; eq && s->name; s++) {
        if (strlen(s->name) != (size_t)(eq - arg) || strncmp(s->name, arg, (size_t)(eq - arg)) != 0)
            continue;
        char *end;
        errno = 0;
        double v = strtod(eq + 1, &end);
        if (s->type == MARIE_PARAM_BOOL && (!strcmp(eq + 1, "true") || !strcmp(eq + 1, "false"))) {
            *(bool *)((char *)p + s->offset) = eq[1] == 't';
            return 0;
        }
        if (errno || end == eq + 1 || *end || !isfinite(v))
            break;
        if (s->type == MARIE_PARAM_DOUBLE)
            *(double *)((char *)p + s->offset) = v;
        else if (s->type == MARIE_PARAM_INT && v == (double)(int64_t)v)
            *(int64_t *)((char *)p + s->offset) = (int64_t)v;
        else if (s->type == MARIE_PARAM_BOOL && (v == 0 || v == 1))
            *(bool *)((char *)p + s->offset) = v != 0;
        else
            break;
        return 0;
    }
    fprintf(stderr, "mapper_replay: %s: not NAME=VALUE with a parameter of slam.params.yaml and its type\n", arg);
    return -1;
}

/* Grow an array of n elements of size `size` to hold one more. */
static void *room(void *a, size_t n, size_t *cap, size_t size)
{
    if (n < *cap)
        return a;
    *cap = *cap ? 2 * *cap : 4096;
    a = realloc(a, *cap * size);
    if (!a)
        exit(1);
    return a;
}

static void place(marie_component_t *c, const marie_laser_scan_t *m)
{
    double od[3], pose[3];
    if (!posebuf_at(&R.odom, m->utime, od) || m->utime <= R.last_scan)
        return;
    slam_scan_t ss = { m->ranges, m->nranges, m->angle_min, m->angle_increment, m->range_min, m->range_max };
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    if (slam_add_scan(R.slam, od, &ss, pose) < 0)
        return;
    clock_gettime(CLOCK_MONOTONIC, &t1);
    R.last_scan = m->utime;
    size_t cap = R.cap;
    R.est = room(R.est, R.nest, &R.cap, sizeof R.est[0]);
    R.ms = room(R.ms, R.nest, &cap, sizeof R.ms[0]);
    R.ms[R.nest] = (double)(t1.tv_sec - t0.tv_sec) * 1e3 + (double)(t1.tv_nsec - t0.tv_nsec) / 1e6;
    memcpy(R.est[R.nest++], (double[7]){ (double)m->utime, pose[0], pose[1], pose[2], od[0], od[1], od[2] },
           sizeof R.est[0]);
}

static void add_odometry(int64_t utime, const double pose[3])
{
    if (posebuf_newest(&R.odom) == INT64_MIN || utime > posebuf_newest(&R.odom)) {
        posebuf_add(&R.odom, utime, pose);
        scanwait_odometry(&R.wait, NULL, utime, place);
    }
}

static bool is(const lcmlog_event_t *ev, const char *ch)
{
    return ev->channel_len == strlen(ch) && memcmp(ev->channel, ch, ev->channel_len) == 0;
}

/* A record of type t from the log, through the checked decode path (a damaged log may hold
 * anything): true, or counted as undecodable. */
static bool decode(const lcmlog_event_t *ev, const marie_type_t *t, void *out)
{
    if (marie_decode_input(t, ev->data, ev->data_len, out, NULL) == 0)
        return true;
    R.undecodable++;
    return false;
}

static void on_event(void *user, const lcmlog_event_t *ev)
{
    if (R.done)
        return;
    if (is(ev, "SIM_TRUTH")) {
        marie_pose_cov_t t;
        if (!decode(ev, &marie_type_pose_cov_t, &t))
            return;
        if (R.nt && t.utime < R.truth[R.nt - 1].t - 5000000) {
            R.done = true;      /* simulated time went back: the log's next run */
        } else {
            R.truth = room(R.truth, R.nt, &R.tcap, sizeof *R.truth);
            R.truth[R.nt].t = t.utime;
            R.truth[R.nt].x = t.pose.x;
            R.truth[R.nt].y = t.pose.y;
            R.truth[R.nt++].th = t.pose.theta;
            if (R.truth_odometry)
                add_odometry(t.utime, (const double[3]){ t.pose.x, t.pose.y, t.pose.theta });
        }
        marie_pose_cov_t_decode_cleanup(&t);
    } else if (is(ev, "REFERENCE")) {
        marie_pose_cov_t t;
        if (!decode(ev, &marie_type_pose_cov_t, &t))
            return;
        R.ref = room(R.ref, R.nref, &R.rcap, sizeof *R.ref);
        R.ref[R.nref++] = (traj_pose_t){ t.utime, t.pose.x, t.pose.y, t.pose.theta };
        R.truth = room(R.truth, R.nt, &R.tcap, sizeof *R.truth);     /* for --traj */
        R.truth[R.nt].t = t.utime;
        R.truth[R.nt].x = t.pose.x;
        R.truth[R.nt].y = t.pose.y;
        R.truth[R.nt++].th = t.pose.theta;
        if (R.truth_odometry)
            add_odometry(t.utime, (const double[3]){ t.pose.x, t.pose.y, t.pose.theta });
        marie_pose_cov_t_decode_cleanup(&t);
    } else if (is(ev, "ODOMETRY")) {
        marie_odometry_t o;
        if (!decode(ev, &marie_type_odometry_t, &o))
            return;
        if (!R.truth_odometry)
            add_odometry(o.utime, (const double[3]){ o.pose.x, o.pose.y, o.pose.theta });
        marie_odometry_t_decode_cleanup(&o);
    } else if (is(ev, "LASER")) {
        marie_laser_scan_t m;
        if (!decode(ev, &marie_type_laser_scan_t, &m))
            return;
        if (m.utime > R.last_scan)
            scanwait_scan(&R.wait, NULL, &R.odom, &m, place);
        marie_laser_scan_t_decode_cleanup(&m);
    }
}

/* Against the log's REFERENCE (an imported log's own estimate): ATE after the best rigid
 * alignment, relation errors over 1 m and 5 m of path (map/trajeval.h). */
static void score_reference(void)
{
    if (!R.nref || !R.nest)
        return;
    traj_pose_t *est = malloc(R.nest * sizeof *est), *pe = malloc(R.nest * sizeof *pe), *pr = malloc(R.nest * sizeof *pr);
    if (!est || !pe || !pr)
        exit(1);
    for (size_t i = 0; i < R.nest; i++)
        est[i] = (traj_pose_t){ (int64_t)R.est[i][0], R.est[i][1], R.est[i][2], R.est[i][3] };
    size_t n = trajeval_pair(est, R.nest, R.ref, R.nref, 0, pe, pr);
    trajeval_t e;
    const double d[2] = { 1, 5 };
    if (trajeval_run(pe, pr, n, d, 2, &e) == 0)
        printf("reference pairs %zu path %.1f ate %.3f ate_max %.3f re1 %.4f re1_rot %.4f re5 %.4f re5_rot %.4f\n", e.pairs,
               e.path, e.ate_rms, e.ate_max, e.rel[0].trans_mean, e.rel[0].rot_mean, e.rel[1].trans_mean,
               e.rel[1].rot_mean);
    free(est), free(pe), free(pr);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The mapper's time per scan (closures and their re-renders included). */
static void print_times(void)
{
    if (!R.nest)
        return;
    double *ms = malloc(R.nest * sizeof *ms), sum = 0;
    if (!ms)
        exit(1);
    memcpy(ms, R.ms, R.nest * sizeof *ms);
    qsort(ms, R.nest, sizeof *ms, cmp_double);
    for (size_t i = 0; i < R.nest; i++)
        sum += ms[i];
    printf("scan_ms p50 %.2f p99 %.2f max %.2f total_s %.2f\n", ms[R.nest / 2], ms[(size_t)(0.99 * (double)(R.nest - 1))],
           ms[R.nest - 1], sum / 1e3);
    free(ms);
}

int main(int argc, char **argv)
{
    const char *log = NULL, *world = NULL, *save = NULL, *traj = NULL;
    double start[3] = { 0, 0, 0 };
    slam_params_t p;
    slam_params_default(&p);
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--world") && i + 1 < argc)
            world = argv[++i];
        else if (!strcmp(argv[i], "--save") && i + 1 < argc)
            save = argv[++i];
        else if (!strcmp(argv[i], "--traj") && i + 1 < argc)
            traj = argv[++i];
        else if (!strcmp(argv[i], "--truth-odometry"))
            R.truth_odometry = true;
        else if (!strcmp(argv[i], "--times"))
            R.times = true;
        else if (!strcmp(argv[i], "--start") && i + 3 < argc)
            for (int k = 0; k < 3; k++)
                start[k] = atof(argv[++i]);
        else if (strchr(argv[i], '=')) {
            if (set_param(&p, argv[i]) < 0)
                return 2;
        } else if (!log)
            log = argv[i];
        else
            log = NULL, i = argc;
    }
    FILE *f = log ? fopen(log, "rb") : NULL;
    if (!f) {
        fprintf(stderr, "usage: mapper_replay LOG [--world W.yaml] [--start X Y TH] [--save NAME] [--traj FILE] [--truth-odometry] [--times] [PARAM=VALUE ...]%s%s\n",
                log ? ": " : "", log ? strerror(errno) : "");
        return 2;
    }
    R.slam = slam_create(&p, start);
    if (!R.slam) {
        fprintf(stderr, "mapper_replay: the parameters are refused by slam_create\n");
        return 2;
    }
    posebuf_clear(&R.odom);
    R.last_scan = INT64_MIN;
    lcmlog_parser_t *lp = lcmlog_parser_create(on_event, NULL, NULL);
    if (!lp)
        return 1;
    unsigned char buf[65536];
    size_t got;
    while (!R.done && (got = fread(buf, 1, sizeof buf, f)) > 0)
        if (lcmlog_parser_feed(lp, buf, got) < 0)
            return 1;
    if (!R.done)
        lcmlog_parser_finish(lp);       /* a record cut short at the file's end */
    int64_t corrupt = lcmlog_parser_stats(lp)->corrupt;
    lcmlog_parser_destroy(lp);
    fclose(f);
    slam_stats_t st;
    slam_get_stats(R.slam, &st);
    printf("scans %zu keyframes %" PRId64 " closures %" PRId64 " optimizations %" PRId64 " ambiguous %" PRId64
           " implausible %" PRId64 " match_failures %" PRId64 " undecodable %zu corrupt %" PRId64 "\n",
           R.nest, st.keyframes, st.loop_closures, st.optimizations, st.loop_ambiguous, st.loop_implausible,
           st.match_failures, R.undecodable, corrupt);
    /* The trajectory against the truth, interpolated at each scan's time. */
    int rc = 0;
    FILE *tf = traj ? fopen(traj, "w") : NULL;
    if (traj && !tf) {
        fprintf(stderr, "mapper_replay: cannot write %s: %s\n", traj, strerror(errno));
        rc = 1;
    }
    double se = 0, mx = 0;
    size_t n = 0, k = 0;
    for (size_t i = 0; i < R.nest; i++) {
        int64_t t = (int64_t)R.est[i][0];
        while (k + 2 < R.nt && R.truth[k + 1].t < t)
            k++;
        double tx = NAN, ty = NAN, tth = NAN;
        if (R.nt > 1 && t >= R.truth[k].t && t <= R.truth[k + 1].t) {
            int64_t span = R.truth[k + 1].t - R.truth[k].t;
            double w = span ? (double)(t - R.truth[k].t) / (double)span : 0;
            tx = R.truth[k].x + w * (R.truth[k + 1].x - R.truth[k].x);
            ty = R.truth[k].y + w * (R.truth[k + 1].y - R.truth[k].y);
            tth = R.truth[k].th + w * remainder(R.truth[k + 1].th - R.truth[k].th, 2 * M_PI);
            double dx = R.est[i][1] - tx, dy = R.est[i][2] - ty;
            se += dx * dx + dy * dy;
            mx = fmax(mx, hypot(dx, dy));
            n++;
        }
        if (tf)
            fprintf(tf, "%.0f %.4f %.4f %.5f %.4f %.4f %.5f %.4f %.4f %.5f\n", R.est[i][0], R.est[i][1], R.est[i][2],
                    R.est[i][3], tx, ty, tth, R.est[i][4], R.est[i][5], R.est[i][6]);
    }
    if (n)
        printf("ate_rms %.3f max %.3f poses %zu\n", sqrt(se / (double)n), mx, n);
    score_reference();
    if (R.times)
        print_times();
    if (tf)
        fclose(tf);
    occmap_t *m = slam_render(R.slam);
    if (m && save && occmap_save(m, save) < 0) {
        fprintf(stderr, "mapper_replay: cannot save %s: %s\n", save, strerror(errno));
        rc = 1;
    }
    if (m && world) {
        marie_errors_t errs = { 0 };
        occmap_t *w = occmap_load(world, &errs);
        mapeval_judgement_t j;
        if (!w || mapeval_judge(w, m, start[0], start[1], &j) < 0) {
            marie_errors_print(&errs, stderr);
            rc = 1;
        } else {
            printf("precision %.3f recall %.3f coverage %.3f\n", j.raw.precision, j.raw.recall, j.raw.coverage);
            printf("aligned by (%.2f m, %.2f m, %.3f rad): aprecision %.3f arecall %.3f acoverage %.3f\n", j.dx, j.dy,
                   j.th, j.aligned.precision, j.aligned.recall, j.aligned.coverage);
        }
        occmap_destroy(w);
        marie_errors_clear(&errs);
    }
    occmap_destroy(m);
    slam_destroy(R.slam);
    scanwait_free(&R.wait);
    free(R.est);
    free(R.truth);
    free(R.ref);
    free(R.ms);
    return rc;
}
