/* marie-log: `marie log import carmen LOG[.gz] OUT.lcm` turns a CARMEN laser log into an LCM log
 * that marie's components replay: the robot's own odometry on ODOMETRY, its scans on LASER, and
 * the poses the log's own SLAM wrote (GMapping's "-corrected" logs) on REFERENCE, for scoring
 * with `marie map eval` only (docs/mapping.md, "Scoring a robot's log"). */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <zlib.h>

#include "core/cli.h"
#include "core/config.h"
#include "core/err.h"
#include "core/lcmlog.h"
#include "lcmtypes/marie_laser_scan_t.h"
#include "lcmtypes/marie_odometry_t.h"
#include "lcmtypes/marie_pose_cov_t.h"
#include "proto/am_proto.h"
#include "tools/log/carmen.h"

#define MAX_LINE (4 << 20)      /* bytes: a line of 100000 beams fits */
#define MAX_ERRORS 20

typedef struct {
    FILE *out;
    const char *laser_ch, *odom_ch, *ref_ch;
    int64_t events, references;
    uint8_t *buf;
    size_t cap;
    int failed;                 /* errno of the first write that failed */
} writer_t;

/* One record: the payload encoded by lcm-gen's encoder into the writer's buffer, then framed. */
static void put(writer_t *w, const char *channel, int64_t utime, int size, int (*encode)(void *, int, int, const void *),
                const void *msg)
{
    /* The payload at the buffer's end, the record framed before it without overlapping it. */
    size_t need = 2 * (size_t)size + LCMLOG_HEADER_LEN + strlen(channel) + 64;
    if (w->failed)
        return;
    if (need > w->cap) {
        uint8_t *b = realloc(w->buf, need);
        if (!b) {
            w->failed = ENOMEM;
            return;
        }
        w->buf = b;
        w->cap = need;
    }
    uint8_t *payload = w->buf + w->cap - (size_t)size;
    if (encode(payload, 0, size, msg) != size) {
        w->failed = EINVAL;
        return;
    }
    long n = lcmlog_encode(w->buf, w->cap - (size_t)size, w->events, utime, channel, payload, (size_t)size);
    if (n < 0 || fwrite(w->buf, 1, (size_t)n, w->out) != (size_t)n)
        w->failed = n < 0 ? -n : errno ? errno : EIO;
    w->events++;
}

static int enc_odom(void *b, int o, int n, const void *m) { return marie_odometry_t_encode(b, o, n, m); }
static int enc_scan(void *b, int o, int n, const void *m) { return marie_laser_scan_t_encode(b, o, n, m); }
static int enc_pose(void *b, int o, int n, const void *m) { return marie_pose_cov_t_encode(b, o, n, m); }

static void on_msg(void *user, const carmen_msg_t *m)
{
    writer_t *w = user;
    if (m->kind == CARMEN_ODOMETRY) {
        marie_odometry_t o = { .utime = m->utime, .pose = { m->pose[0], m->pose[1], m->pose[2] }, .v = m->v,
                               .omega = m->omega, .distance = m->distance };
        put(w, w->odom_ch, m->utime, marie_odometry_t_encoded_size(&o), enc_odom, &o);
        return;
    }
    marie_laser_scan_t s = { .utime = m->utime, .angle_min = (float)m->angle_min,
                             .angle_increment = (float)m->angle_increment, .range_min = 0,
                             .range_max = (float)m->range_max, .nranges = m->n, .ranges = (float *)m->ranges };
    /* The reference first: a replay that takes it for the odometry has it when the scan comes. */
    if (m->has_reference && w->ref_ch[0]) {
        marie_pose_cov_t p = { .utime = m->utime, .frame = "reference",
                               .pose = { m->reference[0], m->reference[1], m->reference[2] } };
        put(w, w->ref_ch, m->utime, marie_pose_cov_t_encoded_size(&p), enc_pose, &p);
        w->references++;
    }
    put(w, w->laser_ch, m->utime, marie_laser_scan_t_encoded_size(&s), enc_scan, &s);
}

/* Every line of the file to the pass: 0, or -1 with errno. */
static int each_line(const char *path, carmen_t *c, bool survey, marie_errors_t *errs)
{
    gzFile f = gzopen(path, "rb");
    if (!f)
        return -1;
    char *line = malloc(MAX_LINE);
    if (!line) {
        gzclose(f);
        return marie_fail(ENOMEM);
    }
    int rc = 0;
    while (gzgets(f, line, MAX_LINE)) {
        size_t len = strlen(line);
        bool whole = len == 0 || line[len - 1] == '\n' || gzeof(f);
        if (!whole) {           /* the rest of an overlong line is dropped with it */
            line[0] = '\0';
            int ch;
            while ((ch = gzgetc(f)) != -1 && ch != '\n')
                ;
        }
        survey ? carmen_survey(c, line) : carmen_line(c, line, path, errs, MAX_ERRORS);
    }
    int err;
    const char *why = gzerror(f, &err);
    if (err != Z_OK && err != Z_STREAM_END) {
        fprintf(stderr, "marie: log import: %s: %s\n", path, why);
        rc = marie_fail(EIO);
    }
    free(line);
    gzclose(f);
    return rc;
}

static void summary(const char *in, const char *out, const carmen_stats_t *st, const writer_t *w)
{
    printf("imported %s -> %s: %lld scans, %lld odometry messages, %lld reference poses\n", in, out,
           (long long)st->scans, (long long)st->odometry, (long long)w->references);
    if (st->rebased)
        printf("  %lld ODOM lines re-based the odometry on the log's own estimate (a corrected log): the robot's "
               "motion was chained across them\n", (long long)st->rebased);
    if (st->still_scans)
        printf("  %lld scans had no odometry line since the scan before: the odometry says the robot stood still\n",
               (long long)st->still_scans);
    printf("  readings: %lld, no return %lld (+inf: from %.2f m on, the log's code), no reading %lld (NaN)\n",
           (long long)st->readings, (long long)st->no_returns, st->no_return_m, (long long)st->no_readings);
    if (st->log_times)
        printf("  times: the log's own; %lld that went back were moved to just after the message before\n",
               (long long)st->times_moved);
    else
        printf("  times: synthesized (the log's times do not increase): not the robot's pace\n");
    if (st->laser_offset != 0)
        printf("  the laser is %.3f m ahead of the robot's centre (PARAM robot_frontlaser_offset): "
               "marie-mapper --param laser_x=%.3f\n", st->laser_offset, st->laser_offset);
    printf("  other lines skipped: %lld; malformed: %lld\n", (long long)st->skipped, (long long)st->bad);
}

static int usage(FILE *f, const marie_cli_opt_t *opts)
{
    fprintf(f, "usage: marie log import carmen LOG[.gz] OUT.lcm [OPTION VALUE]...\n"
               "  the robot's odometry (ODOM lines) and laser scans (FLASER, ROBOTLASER1, RAWLASER1) as an LCM log;\n"
               "  the poses the log's SLAM wrote at each scan go to the reference channel, for `marie map eval`\n");
    marie_cli_usage("marie log", opts, f);
    return f == stdout ? MARIE_EXIT_OK : MARIE_EXIT_USAGE;
}

static int import(const char *in, const char *out, const carmen_opts_t *o, writer_t *w)
{
    marie_errors_t errs = { 0 };
    carmen_t *c = carmen_create(o, on_msg, w);
    size_t len = strlen(out);
    char *tmp = malloc(len + 8);
    int rc = MARIE_EXIT_FAIL;
    if (!c || !tmp) {
        fprintf(stderr, "marie: log import: %s\n", strerror(errno));
        goto out;
    }
    snprintf(tmp, len + 8, "%s.part", out);
    if (each_line(in, c, true, NULL) < 0) {
        fprintf(stderr, "marie: log import: %s: %s\n", in, strerror(errno));
        goto out;
    }
    carmen_begin(c);
    if (!(w->out = fopen(tmp, "wb"))) {
        fprintf(stderr, "marie: log import: %s: %s\n", tmp, strerror(errno));
        goto out;
    }
    int read_rc = each_line(in, c, false, &errs);
    if (fclose(w->out) != 0 && !w->failed)
        w->failed = errno;
    marie_errors_print(&errs, stderr);
    const carmen_stats_t *st = carmen_stats(c);
    if (read_rc < 0 || w->failed || st->scans == 0) {
        fprintf(stderr, "marie: log import: %s\n", w->failed ? strerror(w->failed) : read_rc < 0 ? "read error"
                                                                                   : "no laser scan in the log");
        remove(tmp);
        goto out;
    }
    if (rename(tmp, out) != 0) {
        fprintf(stderr, "marie: log import: %s: %s\n", out, strerror(errno));
        remove(tmp);
        goto out;
    }
    summary(in, out, st, w);
    rc = MARIE_EXIT_OK;
out:
    marie_errors_clear(&errs);
    carmen_destroy(c);
    free(tmp);
    return rc;
}

int main(int argc, char **argv)
{
    carmen_opts_t o = CARMEN_OPTS_DEFAULT;
    writer_t w = { .laser_ch = "LASER", .odom_ch = "ODOMETRY", .ref_ch = "REFERENCE" };
    double fov_deg = o.fov * 180 / 3.14159265358979323846;
    const marie_cli_opt_t opts[] = {
        { "laser", MARIE_CLI_STRING, &w.laser_ch, 0, 0, "CH   channel of the scans (LASER)" },
        { "odometry", MARIE_CLI_STRING, &w.odom_ch, 0, 0, "CH   channel of the odometry (ODOMETRY)" },
        { "reference", MARIE_CLI_STRING, &w.ref_ch, 0, 0, "CH   channel of the log's own pose estimates (REFERENCE; '': none)" },
        { "range-max", MARIE_CLI_DOUBLE, &o.range_max, 0, 1e5,
          "M    readings at or beyond M saw nothing (default: the log's own code, found from its longest readings)" },
        { "fov", MARIE_CLI_DOUBLE, &fov_deg, 1, 360, "DEG  field of view of an FLASER line's beams (180)" },
        { "step", MARIE_CLI_DOUBLE, &o.step, 0.001, 60, "S    seconds between messages when the log's times do not increase (0.1)" },
        { NULL },
    };
    int rc = marie_cli_parse("marie log", opts, argc, argv);
    if (rc >= 0)
        return rc == 0 ? usage(stdout, opts) : rc;
    if (argc - optind != 4 || strcmp(argv[optind], "import") != 0 || strcmp(argv[optind + 1], "carmen") != 0)
        return usage(stderr, opts);
    if (!w.laser_ch[0] || !w.odom_ch[0])
        return usage(stderr, opts);
    o.fov = fov_deg * 3.14159265358979323846 / 180;
    rc = import(argv[optind + 2], argv[optind + 3], &o, &w);
    free(w.buf);
    return rc;
}
