/* mapper_replay: a recorded run (an LCM log with LASER and ODOMETRY, and SIM_TRUTH from the
 * simulator or REFERENCE from an imported log) through the mapper's library as marie-mapper feeds
 * it (tests/mapper/replay.h), alone and in log order, as fast as the mapper goes, so two versions
 * or two settings of the mapper are compared on the very same input (a live run never gives the
 * same input twice). Prints the mapper's counters, its trajectory against the truth (ATE), against
 * the reference (ATE after alignment, relation errors: map/trajeval.h), and the map against a
 * world (as `marie map compare`). Not installed.
 *   mapper_replay LOG [--world W.yaml] [--start X Y TH] [--save NAME] [--traj FILE] [--out RUN.lcm]
 *                 [--truth-odometry] [--times] [PARAM=VALUE ...]
 * --save: the map as NAME.yaml/.pgm; --out: an LCM log of the mapper's POSE at each scan and its
 * last MAP, as a live marie-mapper's recording has them (for `marie map eval`); --traj: "utime x y
 * theta" of each scan placed, then the truth's (or reference's) and the odometry's "x y theta" at
 * its time, NaN where there is none; --truth-odometry: the truth (or reference) stands in for the
 * odometry, so what error is left is the scan matcher's and the map's own; --times: the mapper's
 * time per scan (it differs from run to run). PARAMs are the mapper library's
 * (adapters/mapper/slam.params.yaml); only the log's first run is read (it ends where the
 * simulated time goes back, as in marie-demo's two-part logs). The log is read with
 * core/lcmlog, which resynchronises past damage and counts it as `corrupt`. */
#include <errno.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/mapper/slam.h"
#include "adapters/mapper/slam_params.h"
#include "core/config.h"
#include "core/lcmlog.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_laser_scan_t.h"
#include "lcmtypes/marie_occupancy_grid_t.h"
#include "lcmtypes/marie_odometry_t.h"
#include "lcmtypes/marie_pose_cov_t.h"
#include "lcmtypes/marie_types.h"
#include "map/mapeval.h"
#include "map/occmap.h"
#include "map/trajeval.h"
#include "tests/mapper/replay.h"

static const marie_param_spec_t slam_spec[] = SLAM_PARAMS;

typedef struct {
    traj_pose_t *p;
    size_t n, cap;
} traj_t;

static struct {
    replay_t *rp;
    traj_t truth;               /* SIM_TRUTH, or REFERENCE, in time order */
    bool reference;             /* the truth is an imported log's REFERENCE */
    size_t undecodable;
    bool done;                  /* the log's first run is over */
    bool truth_odometry;        /* --truth-odometry */
} R;

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

static void traj_add(traj_t *t, int64_t utime, double x, double y, double th)
{
    if (t->n == t->cap) {
        t->cap = t->cap ? 2 * t->cap : 4096;
        if (!(t->p = realloc(t->p, t->cap * sizeof *t->p)))
            exit(1);
    }
    t->p[t->n++] = (traj_pose_t){ utime, x, y, th };
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

static void on_truth(const lcmlog_event_t *ev, bool reference)
{
    marie_pose_cov_t t;
    if (!decode(ev, &marie_type_pose_cov_t, &t))
        return;
    if (!reference && R.truth.n && t.utime < R.truth.p[R.truth.n - 1].utime - 5000000) {
        R.done = true;          /* simulated time went back: the log's next run */
    } else {
        R.reference |= reference;
        traj_add(&R.truth, t.utime, t.pose.x, t.pose.y, t.pose.theta);
        if (R.truth_odometry)
            replay_odometry(R.rp, t.utime, (const double[3]){ t.pose.x, t.pose.y, t.pose.theta });
    }
    marie_pose_cov_t_decode_cleanup(&t);
}

static void on_event(void *user, const lcmlog_event_t *ev)
{
    if (R.done)
        return;
    if (is(ev, "SIM_TRUTH") || is(ev, "REFERENCE")) {
        on_truth(ev, is(ev, "REFERENCE"));
    } else if (is(ev, "ODOMETRY")) {
        marie_odometry_t o;
        if (!decode(ev, &marie_type_odometry_t, &o))
            return;
        if (!R.truth_odometry)
            replay_odometry(R.rp, o.utime, (const double[3]){ o.pose.x, o.pose.y, o.pose.theta });
        marie_odometry_t_decode_cleanup(&o);
    } else if (is(ev, "LASER")) {
        marie_laser_scan_t m;
        if (!decode(ev, &marie_type_laser_scan_t, &m))
            return;
        replay_laser(R.rp, &m);
        marie_laser_scan_t_decode_cleanup(&m);
    }
}

/* The truth at time t, interpolated between its poses around it; false outside them. */
static bool truth_at(int64_t t, size_t *k, double out[3])
{
    const traj_t *T = &R.truth;
    while (*k + 2 < T->n && T->p[*k + 1].utime < t)
        (*k)++;
    if (T->n < 2 || t < T->p[*k].utime || t > T->p[*k + 1].utime)
        return false;
    const traj_pose_t *a = &T->p[*k], *b = &T->p[*k + 1];
    int64_t span = b->utime - a->utime;
    double w = span ? (double)(t - a->utime) / (double)span : 0;
    out[0] = a->x + w * (b->x - a->x);
    out[1] = a->y + w * (b->y - a->y);
    out[2] = a->th + w * remainder(b->th - a->th, 2 * M_PI);
    return true;
}

/* The trajectory against the truth at each scan (SIM_TRUTH: the same frame), and --traj. */
static int score_truth(const char *traj)
{
    size_t ns, n = 0, k = 0;
    const replay_scan_t *s = replay_scans(R.rp, &ns);
    FILE *tf = traj ? fopen(traj, "w") : NULL;
    if (traj && !tf) {
        fprintf(stderr, "mapper_replay: cannot write %s: %s\n", traj, strerror(errno));
        return 1;
    }
    double se = 0, mx = 0;
    for (size_t i = 0; i < ns; i++) {
        double t[3] = { NAN, NAN, NAN };
        if (truth_at(s[i].utime, &k, t) && !R.reference) {
            double dx = s[i].pose[0] - t[0], dy = s[i].pose[1] - t[1];
            se += dx * dx + dy * dy;
            mx = fmax(mx, hypot(dx, dy));
            n++;
        }
        if (tf)
            fprintf(tf, "%" PRId64 " %.4f %.4f %.5f %.4f %.4f %.5f %.4f %.4f %.5f\n", s[i].utime, s[i].pose[0],
                    s[i].pose[1], s[i].pose[2], t[0], t[1], t[2], s[i].odom[0], s[i].odom[1], s[i].odom[2]);
    }
    if (n)
        printf("ate_rms %.3f max %.3f poses %zu\n", sqrt(se / (double)n), mx, n);
    if (tf)
        fclose(tf);
    return 0;
}

/* Against the log's REFERENCE (an imported log's own estimate): ATE after the best rigid
 * alignment, relation errors over 1 m and 5 m of path. */
static void score_reference(void)
{
    size_t ns;
    const replay_scan_t *s = replay_scans(R.rp, &ns);
    if (!R.reference || !ns)
        return;
    traj_pose_t *est = malloc(ns * sizeof *est), *pe = malloc(ns * sizeof *pe), *pr = malloc(ns * sizeof *pr);
    if (!est || !pe || !pr)
        exit(1);
    for (size_t i = 0; i < ns; i++)
        est[i] = (traj_pose_t){ s[i].utime, s[i].pose[0], s[i].pose[1], s[i].pose[2] };
    size_t n = trajeval_pair(est, ns, R.truth.p, R.truth.n, 0, pe, pr);
    trajeval_t e;
    const double d[2] = { 1, 5 };
    if (trajeval_run(pe, pr, n, d, 2, &e) == 0)
        printf("reference pairs %zu path %.1f ate %.3f ate_max %.3f re1 %.4f re1_rot %.4f re5 %.4f re5_rot %.4f\n", e.pairs,
               e.path, e.ate_rms, e.ate_max, e.rel[0].trans_mean, e.rel[0].rot_mean, e.rel[1].trans_mean,
               e.rel[1].rot_mean);
    free(est), free(pe), free(pr);
}

static void put(FILE *f, int64_t n, int64_t utime, const char *ch, const void *msg, const marie_type_t *t)
{
    int size = t->encoded_size(msg);
    uint8_t *payload = malloc((size_t)size), *rec = malloc((size_t)size + LCMLOG_HEADER_LEN + strlen(ch));
    if (!payload || !rec || t->encode(payload, 0, size, msg) != size)
        exit(1);
    long len = lcmlog_encode(rec, (size_t)size + LCMLOG_HEADER_LEN + strlen(ch), n, utime, ch, payload, (size_t)size);
    if (len < 0 || fwrite(rec, 1, (size_t)len, f) != (size_t)len)
        exit(1);
    free(payload), free(rec);
}

/* --out: POSE at each scan and the last MAP, as marie-mapper publishes them. */
static int write_run(const char *path, const occmap_t *m)
{
    FILE *f = fopen(path, "wb");
    if (!f) {
        fprintf(stderr, "mapper_replay: cannot write %s: %s\n", path, strerror(errno));
        return 1;
    }
    size_t ns;
    const replay_scan_t *s = replay_scans(R.rp, &ns);
    int64_t n = 0;
    for (size_t i = 0; i < ns; i++) {
        marie_pose_cov_t p = { .utime = s[i].utime, .frame = "map", .pose = { s[i].pose[0], s[i].pose[1], s[i].pose[2] } };
        put(f, n++, s[i].utime, "POSE", &p, &marie_type_pose_cov_t);
    }
    if (m && ns) {
        marie_occupancy_grid_t g = { .utime = s[ns - 1].utime, .resolution = (float)m->resolution, .width = m->width,
                                     .height = m->height, .origin = { m->origin_x, m->origin_y, 0 },
                                     .ncells = m->width * m->height, .cells = m->cells };
        put(f, n++, g.utime, "MAP", &g, &marie_type_occupancy_grid_t);
    }
    return fclose(f) == 0 ? 0 : 1;
}

static int judge_world(const char *world, const occmap_t *m, const double start[3])
{
    marie_errors_t errs = { 0 };
    occmap_t *w = occmap_load(world, &errs);
    mapeval_judgement_t j;
    int rc = 0;
    if (!w || mapeval_judge(w, m, start[0], start[1], &j) < 0) {
        marie_errors_print(&errs, stderr);
        rc = 1;
    } else {
        printf("precision %.3f recall %.3f coverage %.3f\n", j.raw.precision, j.raw.recall, j.raw.coverage);
        printf("aligned by (%.2f m, %.2f m, %.3f rad): aprecision %.3f arecall %.3f acoverage %.3f\n", j.dx, j.dy, j.th,
               j.aligned.precision, j.aligned.recall, j.aligned.coverage);
    }
    occmap_destroy(w);
    marie_errors_clear(&errs);
    return rc;
}

static int read_log(FILE *f)
{
    lcmlog_parser_t *lp = lcmlog_parser_create(on_event, NULL, NULL);
    if (!lp)
        return -1;
    unsigned char buf[65536];
    size_t got;
    while (!R.done && (got = fread(buf, 1, sizeof buf, f)) > 0)
        if (lcmlog_parser_feed(lp, buf, got) < 0)
            return -1;
    if (!R.done)
        lcmlog_parser_finish(lp);       /* a record cut short at the file's end */
    int corrupt = (int)lcmlog_parser_stats(lp)->corrupt;
    lcmlog_parser_destroy(lp);
    return corrupt;
}

int main(int argc, char **argv)
{
    const char *log = NULL, *world = NULL, *save = NULL, *traj = NULL, *out = NULL;
    bool times = false;
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
        else if (!strcmp(argv[i], "--out") && i + 1 < argc)
            out = argv[++i];
        else if (!strcmp(argv[i], "--truth-odometry"))
            R.truth_odometry = true;
        else if (!strcmp(argv[i], "--times"))
            times = true;
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
        fprintf(stderr, "usage: mapper_replay LOG [--world W.yaml] [--start X Y TH] [--save NAME] [--traj FILE] "
                        "[--out RUN.lcm] [--truth-odometry] [--times] [PARAM=VALUE ...]%s%s\n",
                log ? ": " : "", log ? strerror(errno) : "");
        return 2;
    }
    if (!(R.rp = replay_create(&p, start))) {
        fprintf(stderr, "mapper_replay: the parameters are refused by slam_create\n");
        return 2;
    }
    int corrupt = read_log(f);
    fclose(f);
    if (corrupt < 0)
        return 1;
    slam_stats_t st;
    slam_get_stats(replay_slam(R.rp), &st);
    size_t ns;
    replay_scans(R.rp, &ns);
    printf("scans %zu keyframes %" PRId64 " closures %" PRId64 " optimizations %" PRId64 " ambiguous %" PRId64
           " implausible %" PRId64 " match_failures %" PRId64 " undecodable %zu corrupt %d\n",
           ns, st.keyframes, st.loop_closures, st.optimizations, st.loop_ambiguous, st.loop_implausible,
           st.match_failures, R.undecodable, corrupt);
    int rc = score_truth(traj);
    score_reference();
    if (times) {
        replay_times_t t;
        replay_times(R.rp, &t);
        printf("scan_ms p50 %.2f p99 %.2f max %.2f closures %zu closure_max %.1f total_s %.2f\n", t.p50, t.p99, t.max,
               t.closures, t.closure_max, t.total_s);
    }
    occmap_t *m = slam_render(replay_slam(R.rp));
    if (m && save && occmap_save(m, save) < 0) {
        fprintf(stderr, "mapper_replay: cannot save %s: %s\n", save, strerror(errno));
        rc = 1;
    }
    if (out)
        rc |= write_run(out, m);
    if (m && world)
        rc |= judge_world(world, m, start);
    occmap_destroy(m);
    replay_destroy(R.rp);
    free(R.truth.p);
    return rc;
}
