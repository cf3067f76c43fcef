/* carmen: a pure reader of CARMEN laser logs: odometry and scans as marie messages, the log's
 * own SLAM estimate as a reference. */
#include "tools/log/carmen.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"

#define MAX_BEAMS 100000
#define MAX_RANGE 1e5           /* m: a reading beyond is no number a laser writes */
#define MAX_COORD 1e6           /* m: a pose beyond is none a robot reaches */
#define MAX_TIME 1e10           /* s: a time beyond (the year 2286) is no clock's */
#define MAX_TOKENS (MAX_BEAMS + 64)
#define HIST_BIN 0.01           /* m: the survey's histogram of readings */
#define HIST_BINS 20000         /* up to 200 m */
#define NO_RETURN_SPAN 0.25     /* m below the longest reading that still belongs to its cluster */
#define NO_RETURN_SHARE 0.002   /* of all readings: a cluster that large is the sensor's code */
#define NOMINAL_SPEED 0.5       /* m/s and rad/s for synthesized times */
#define NOMINAL_TURN 1.0
#define MAX_STEP 3600.0         /* s: the longest synthesized step */

struct carmen {
    carmen_opts_t o;
    carmen_emit_t emit;
    void *user;
    carmen_stats_t st;
    const char **tok;           /* the current line's tokens (into a copy of it) */
    int ntok;
    char *copy;
    size_t copy_cap;
    float *ranges;
    int ranges_cap;
    int64_t *hist;              /* survey: readings per HIST_BIN */
    double max_reading;
    int64_t scan_steps, scan_steps_up;  /* survey: scan intervals, and those whose time increases */
    double last_scan_t;
    /* Both passes: GMapping's corrected logs follow each scan with an ODOM line at the scan's
     * estimated pose, from which the odometry goes on: that line re-bases, it is no motion. */
    bool after_laser;
    double laser_ref[3];
    bool laser_ref_ok;
    /* Pass two. */
    bool have_odom;
    double base[3], raw[3];     /* the last ODOM pose as written, and the chained odometry there */
    double v, omega, distance;
    bool odom_since_scan;
    int64_t t_us, last_odom_us;
    double last_emit_raw[3];
};

static double wrap(double a) { return atan2(sin(a), cos(a)); }

static void between(const double a[3], const double b[3], double out[3])
{
    double c = cos(a[2]), s = sin(a[2]), dx = b[0] - a[0], dy = b[1] - a[1];
    out[0] = c * dx + s * dy;
    out[1] = -s * dx + c * dy;
    out[2] = wrap(b[2] - a[2]);
}

static void compose(const double a[3], const double b[3], double out[3])
{
    double c = cos(a[2]), s = sin(a[2]), r[3] = { a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], wrap(a[2] + b[2]) };
    memcpy(out, r, sizeof r);
}

carmen_t *carmen_create(const carmen_opts_t *o, carmen_emit_t emit, void *user)
{
    if (!o || !(o->step > 0 && o->step <= 3600) || !(o->range_max >= 0 && o->range_max < 1e6) ||
        !(o->fov > 0 && o->fov <= 2 * M_PI + 1e-9))
        return marie_fail_null(EINVAL);
    carmen_t *c = calloc(1, sizeof *c);
    if (!c)
        return marie_fail_null(ENOMEM);
    c->o = *o;
    c->emit = emit;
    c->user = user;
    c->hist = calloc(HIST_BINS, sizeof *c->hist);
    c->tok = malloc(MAX_TOKENS * sizeof *c->tok);
    if (!c->hist || !c->tok) {
        carmen_destroy(c);
        return marie_fail_null(ENOMEM);
    }
    c->last_scan_t = -INFINITY;
    return c;
}

void carmen_destroy(carmen_t *c)
{
    if (!c)
        return;
    free(c->tok);
    free(c->copy);
    free(c->ranges);
    free(c->hist);
    free(c);
}

const carmen_stats_t *carmen_stats(const carmen_t *c) { return &c->st; }

/* Splits a copy of the line into tokens; 0, or -1 (ENOMEM, or E2BIG past MAX_TOKENS). */
static int tokenize(carmen_t *c, const char *line)
{
    size_t len = strlen(line);
    if (len + 1 > c->copy_cap) {
        char *p = realloc(c->copy, len + 1);
        if (!p)
            return marie_fail(ENOMEM);
        c->copy = p;
        c->copy_cap = len + 1;
    }
    memcpy(c->copy, line, len + 1);
    c->ntok = 0;
    for (char *save = NULL, *t = strtok_r(c->copy, " \t\r\n", &save); t; t = strtok_r(NULL, " \t\r\n", &save)) {
        if (c->ntok == MAX_TOKENS)
            return marie_fail(E2BIG);
        c->tok[c->ntok++] = t;
    }
    return 0;
}

/* Token i as a finite number; false when it is missing or not one. */
static bool num(const carmen_t *c, int i, double *out)
{
    if (i >= c->ntok)
        return false;
    char *end;
    errno = 0;
    *out = strtod(c->tok[i], &end);
    /* An underflow (5.45506e-312: a garbage time) is a number too. */
    return end != c->tok[i] && !*end && (!errno || (errno == ERANGE && fabs(*out) < 1)) && isfinite(*out);
}

/* Column (1-based) of token i in the line, for error messages. */
static int column(const carmen_t *c, int i)
{
    return i < c->ntok ? (int)(c->tok[i] - c->copy) + 1 : (int)strlen(c->copy) + 1;
}

typedef struct {
    int n, first;               /* beams, and the token of the first range */
    double angle_min, angle_increment, range_max;   /* range_max 0: not given */
    int ref;                    /* token of the estimated pose (x y theta), or -1 */
    int time;                   /* token of the timestamp */
} laser_layout_t;

/* Where a laser line's fields are: 1 when the line is a laser, 0 when not, -1 (with *bad_tok)
 * when it is one but malformed. */
static int laser_layout(const carmen_t *c, laser_layout_t *l, int *bad_tok)
{
    const char *k = c->tok[0];
    double v;
    *bad_tok = 1;
    if (!strcmp(k, "FLASER")) {
        if (!num(c, 1, &v) || v < 1 || v > MAX_BEAMS || v != floor(v))
            return -1;
        l->n = (int)v;
        l->first = 2;
        /* CARMEN's front laser spans its field of view in n beams at pi/180 (180 or 181 beams) or
         * pi/360 (360, 361): the increment is the field over the even count. */
        l->angle_increment = c->o.fov / (double)(l->n > 1 ? l->n - l->n % 2 : 1);
        l->angle_min = -c->o.fov / 2;
        l->range_max = 0;
        l->ref = 2 + l->n;
        l->time = 2 + l->n + 6;
        *bad_tok = l->time;
        return l->time < c->ntok ? 1 : -1;
    }
    bool robot = !strcmp(k, "ROBOTLASER1");
    if (!robot && strcmp(k, "RAWLASER1") != 0)
        return 0;
    double start, fov, res, maxr, n, nrem;
    /* TYPE start_angle fov resolution max_range accuracy remission_mode n ranges... nrem rems... */
    for (int i = 2; i <= 8; i++)
        if (!num(c, i, &v)) {
            *bad_tok = i;
            return -1;
        }
    num(c, 2, &start), num(c, 3, &fov), num(c, 4, &res), num(c, 5, &maxr), num(c, 8, &n);
    *bad_tok = 8;
    if (n < 1 || n > MAX_BEAMS || n != floor(n) || !(fabs(res) > 0) || !(maxr > 0))
        return -1;
    l->n = (int)n;
    l->first = 9;
    l->angle_min = start;
    l->angle_increment = res;
    l->range_max = maxr;
    *bad_tok = 9 + l->n;
    if (!num(c, 9 + l->n, &nrem) || nrem < 0 || nrem > MAX_BEAMS || nrem != floor(nrem))
        return -1;
    int after = 10 + l->n + (int)nrem;
    /* ROBOTLASER1: laser pose, robot pose, tv rv forward side turn, timestamp. */
    l->ref = robot ? after + 3 : -1;
    l->time = robot ? after + 11 : after;
    *bad_tok = l->time;
    return l->time < c->ntok ? 1 : -1;
}

/* The laser's ranges as numbers; false (with *bad_tok) on a token that is not one. */
static bool read_ranges(carmen_t *c, const laser_layout_t *l, int *bad_tok)
{
    if (l->n > c->ranges_cap) {
        float *r = realloc(c->ranges, sizeof(float) * (size_t)l->n);
        if (!r) {
            *bad_tok = 0;
            return false;
        }
        c->ranges = r;
        c->ranges_cap = l->n;
    }
    for (int i = 0; i < l->n; i++) {
        double r;
        if (!num(c, l->first + i, &r) || fabs(r) > MAX_RANGE) {
            *bad_tok = l->first + i;
            return false;
        }
        c->ranges[i] = (float)r;
    }
    return true;
}

static bool read_pose(const carmen_t *c, int at, double p[3])
{
    return at >= 0 && num(c, at, &p[0]) && num(c, at + 1, &p[1]) && num(c, at + 2, &p[2]) && fabs(p[0]) <= MAX_COORD &&
           fabs(p[1]) <= MAX_COORD && fabs(p[2]) <= MAX_COORD;
}

static bool read_time(const carmen_t *c, int at, double *t)
{
    return num(c, at, t) && fabs(*t) <= MAX_TIME;
}

/* An ODOM line right after a laser line, at that scan's estimated pose: a re-basing. */
static bool rebases(const carmen_t *c, const double p[3])
{
    return c->after_laser && c->laser_ref_ok && fabs(p[0] - c->laser_ref[0]) < 1e-4 &&
           fabs(p[1] - c->laser_ref[1]) < 1e-4 && fabs(wrap(p[2] - c->laser_ref[2])) < 1e-4;
}

static void note_param(carmen_t *c)
{
    double v;
    if (c->ntok >= 3 && !strcmp(c->tok[1], "robot_frontlaser_offset") && num(c, 2, &v))
        c->st.laser_offset = v;
}

void carmen_survey(carmen_t *c, const char *line)
{
    if (tokenize(c, line) < 0 || c->ntok == 0)
        return;
    const char *k = c->tok[0];
    double p[3], t;
    if (!strcmp(k, "ODOM")) {
        if (!read_pose(c, 1, p) || !read_time(c, 7, &t))
            return;
        c->after_laser = false;
        return;
    }
    laser_layout_t l;
    int bad;
    if (laser_layout(c, &l, &bad) <= 0 || !read_ranges(c, &l, &bad) || !read_time(c, l.time, &t))
        return;
    if (c->last_scan_t > -INFINITY) {
        c->scan_steps++;
        c->scan_steps_up += t > c->last_scan_t;
    }
    c->last_scan_t = t;
    for (int i = 0; i < l.n; i++)
        if (c->ranges[i] > 0) {
            c->hist[(int)fmin(HIST_BINS - 1, c->ranges[i] / HIST_BIN)]++;
            c->max_reading = fmax(c->max_reading, c->ranges[i]);
            c->st.readings++;
        }
    c->after_laser = true;
    c->laser_ref_ok = read_pose(c, l.ref, c->laser_ref);
}

/* A cluster of readings at the very top of the log is the sensor's "nothing seen" code (an
 * LMS200 reads 8.183, 32.767 or 81.91 m, depending on its mode), not walls at that distance. */
static double find_no_return(const carmen_t *c)
{
    if (c->st.readings == 0)
        return 0;
    int top = (int)fmin(HIST_BINS - 1, c->max_reading / HIST_BIN);
    int lo = (int)fmax(0, top - NO_RETURN_SPAN / HIST_BIN);
    int64_t n = 0;
    int first = top;
    for (int b = top; b >= lo; b--)
        if (c->hist[b]) {
            n += c->hist[b];
            first = b;
        }
    return (double)n >= NO_RETURN_SHARE * (double)c->st.readings ? first * HIST_BIN : 0;
}

void carmen_begin(carmen_t *c)
{
    /* Times that mostly increase are the log's (Intel's clock jumps back by up to 0.6 s four times
     * in 910 scans); times that do not (all alike, zero, garbage) are no clock at all. */
    c->st.log_times = c->scan_steps > 0 && c->scan_steps_up >= 0.9 * (double)c->scan_steps;
    c->st.no_return_m = c->o.range_max > 0 ? c->o.range_max : find_no_return(c);
    c->st.readings = 0;
    c->after_laser = false;
    c->laser_ref_ok = false;
    c->t_us = c->st.log_times ? INT64_MIN : 0;
    c->last_odom_us = -1;
}

/* The next synthesized time: `step` on, more where the odometry moved further than a robot at
 * a nominal speed would in a step (a log that jumps metres between lines). */
static int64_t next_time(carmen_t *c)
{
    double d[3];
    between(c->last_emit_raw, c->raw, d);
    double dt = fmin(MAX_STEP, fmax(c->o.step, fmax(hypot(d[0], d[1]) / NOMINAL_SPEED, fabs(d[2]) / NOMINAL_TURN)));
    memcpy(c->last_emit_raw, c->raw, sizeof c->raw);
    c->t_us += (int64_t)llround(dt * 1e6);
    return c->t_us;
}

/* The log's time t, kept after the last message written: messages go in the file's order. */
static int64_t log_time(carmen_t *c, double t)
{
    int64_t us = llround(t * 1e6);
    c->st.times_moved += us < c->t_us;
    c->t_us = us > c->t_us ? us : c->t_us + 1;
    return c->t_us;
}

static void emit_odometry(carmen_t *c, int64_t utime)
{
    carmen_msg_t m = { .kind = CARMEN_ODOMETRY, .utime = utime, .pose = { c->raw[0], c->raw[1], c->raw[2] },
                       .v = c->v, .omega = c->omega, .distance = c->distance };
    c->last_odom_us = utime;
    c->odom_since_scan = true;
    c->st.odometry++;
    if (c->emit)
        c->emit(c->user, &m);
}

static void bad_line(carmen_t *c, int tok, const char *file, marie_errors_t *errs, int max_errors, const char *why)
{
    c->st.bad++;
    if (errs && (int)errs->n < max_errors)
        marie_errors_add(errs, file, (int)c->st.lines, column(c, tok), "%s line: %s", c->tok[0], why);
}

/* ODOM x y theta tv rv accel timestamp [host logger_timestamp] */
static void odom_line(carmen_t *c, const char *file, marie_errors_t *errs, int max_errors)
{
    double p[3], tv, rv, t;
    for (int i = 1; i <= 7; i++)
        if (!num(c, i, &t))
            return bad_line(c, i, file, errs, max_errors, "expected a number");
    if (!read_pose(c, 1, p))
        return bad_line(c, 1, file, errs, max_errors, "a pose no robot reaches");
    if (!read_time(c, 7, &t))
        return bad_line(c, 7, file, errs, max_errors, "a time no clock gives");
    num(c, 4, &tv), num(c, 5, &rv);
    bool rebase = rebases(c, p);
    c->after_laser = false;
    if (rebase) {
        memcpy(c->base, p, sizeof c->base);
        c->st.rebased++;
        return;
    }
    if (!c->have_odom) {
        memcpy(c->base, p, sizeof c->base);
        memcpy(c->raw, p, sizeof c->raw);
        memcpy(c->last_emit_raw, p, sizeof c->raw);
        c->have_odom = true;
    }
    double d[3];
    between(c->base, p, d);
    compose(c->raw, d, c->raw);
    memcpy(c->base, p, sizeof c->base);
    c->distance += hypot(d[0], d[1]);
    c->v = tv;
    c->omega = rv;
    emit_odometry(c, c->st.log_times ? log_time(c, t) : next_time(c));
}

/* The no-return code and the non-positive readings of CARMEN become REP 117's +inf and NaN. */
static double mark_ranges(carmen_t *c, const laser_layout_t *l)
{
    double code = l->range_max > 0 ? l->range_max : c->st.no_return_m;
    for (int i = 0; i < l->n; i++) {
        float *r = &c->ranges[i];
        c->st.readings++;
        if (!(*r > 0)) {
            *r = NAN;
            c->st.no_readings++;
        } else if (code > 0 && *r >= code) {
            *r = INFINITY;
            c->st.no_returns++;
        }
    }
    return code > 0 ? code : fmax(c->max_reading + HIST_BIN, HIST_BIN);
}

static void laser_line(carmen_t *c, const laser_layout_t *l, const char *file, marie_errors_t *errs, int max_errors)
{
    int bad;
    double t;
    if (!read_ranges(c, l, &bad))
        return bad_line(c, bad, file, errs, max_errors, bad ? "expected a range" : "out of memory");
    if (!read_time(c, l->time, &t))
        return bad_line(c, l->time, file, errs, max_errors, "expected a timestamp");
    carmen_msg_t m = { .kind = CARMEN_LASER, .ranges = c->ranges, .n = l->n, .angle_min = l->angle_min,
                       .angle_increment = l->angle_increment };
    m.range_max = mark_ranges(c, l);
    m.has_reference = read_pose(c, l->ref, m.reference);
    bool moved = c->odom_since_scan;
    if (c->st.scans && !moved)
        c->st.still_scans++;
    if (c->st.log_times) {
        m.utime = log_time(c, t);
    } else if (moved) {
        m.utime = c->last_odom_us;      /* the log wrote the odometry of the scan just before it */
    } else {
        m.utime = next_time(c);
        if (c->have_odom)
            emit_odometry(c, m.utime);  /* the robot's odometry did not move: say so at the scan */
    }
    c->odom_since_scan = false;
    c->after_laser = true;
    c->laser_ref_ok = m.has_reference;
    memcpy(c->laser_ref, m.reference, sizeof c->laser_ref);
    c->st.scans++;
    if (c->emit)
        c->emit(c->user, &m);
}

void carmen_line(carmen_t *c, const char *line, const char *file, marie_errors_t *errs, int max_errors)
{
    c->st.lines++;
    if (tokenize(c, line) < 0) {
        c->ntok = 0;
        c->st.bad++;
        if (errs && (int)errs->n < max_errors)
            marie_errors_add(errs, file, (int)c->st.lines, 1, "line of more than %d fields", MAX_TOKENS);
        return;
    }
    if (c->ntok == 0)
        return;
    if (!strcmp(c->tok[0], "ODOM"))
        return odom_line(c, file, errs, max_errors);
    laser_layout_t l;
    int bad, kind = laser_layout(c, &l, &bad);
    if (kind > 0)
        return laser_line(c, &l, file, errs, max_errors);
    if (kind < 0)
        return bad_line(c, bad, file, errs, max_errors, "missing or malformed field");
    if (!strcmp(c->tok[0], "PARAM"))
        note_param(c);
    c->st.skipped++;
}
