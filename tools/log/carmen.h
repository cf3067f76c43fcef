/* carmen: a pure reader of CARMEN laser logs (ODOM, FLASER, ROBOTLASER1, RAWLASER1 lines): the
 * robot's own odometry and its laser scans as marie messages, the poses a SLAM wrote into the log
 * (GMapping's "-corrected" logs) as a reference for scoring, never as input. Two passes over the
 * same lines: the first learns what the whole log says (its no-return code, whether its times
 * can be used), the second emits. */
#ifndef TOOLS_LOG_CARMEN_H
#define TOOLS_LOG_CARMEN_H

#include <stdbool.h>
#include <stdint.h>

#include "core/config.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct carmen carmen_t;

typedef struct {
    double step;                /* s between messages when the log's own times cannot be used */
    double range_max;           /* > 0: readings at or beyond it are no returns; 0: found from the log */
    double fov;                 /* rad covered by an FLASER's beams (CARMEN's front laser: pi) */
} carmen_opts_t;

#define CARMEN_OPTS_DEFAULT { .step = 0.1, .range_max = 0, .fov = 3.14159265358979323846 }

typedef enum { CARMEN_ODOMETRY, CARMEN_LASER } carmen_kind_t;

/* One message to write. Pointers are valid during the callback only. */
typedef struct {
    carmen_kind_t kind;
    int64_t utime;
    /* CARMEN_ODOMETRY: the robot's own odometry, chained across the log's re-basings. */
    double pose[3], v, omega, distance;
    /* CARMEN_LASER: ranges in m, +INFINITY for no return (REP 117), NAN for no reading. */
    const float *ranges;
    int n;
    double angle_min, angle_increment, range_max;
    bool has_reference;         /* the pose the log's writer estimated at this scan */
    double reference[3];
} carmen_msg_t;

typedef void (*carmen_emit_t)(void *user, const carmen_msg_t *m);

typedef struct {
    int64_t lines, scans, odometry;
    int64_t rebased;            /* ODOM lines that re-base the odometry on the log's estimate (skipped) */
    int64_t still_scans;        /* scans with no odometry line since the scan before */
    int64_t readings, no_returns, no_readings;
    int64_t skipped;            /* lines of other kinds (NEFF, PARAM, SYNC, comments, rear lasers) */
    int64_t bad;                /* malformed lines: each in the error list */
    bool log_times;             /* the log's own times are used (else synthesized, `step` apart) */
    int64_t times_moved;        /* messages whose time went back, moved to just after the one before */
    double no_return_m;         /* readings at or beyond this were no returns (0: none found) */
    double laser_offset;        /* m, PARAM robot_frontlaser_offset (last given) */
} carmen_stats_t;

/* NULL with errno (EINVAL: bad options; ENOMEM). carmen_destroy(NULL) is a no-op. */
carmen_t *carmen_create(const carmen_opts_t *o, carmen_emit_t emit, void *user);
void carmen_destroy(carmen_t *c);
/* Pass one: every line of the log, in order (without its newline). */
void carmen_survey(carmen_t *c, const char *line);
/* Between the passes: what the survey found decides the times and the no-return code. */
void carmen_begin(carmen_t *c);
/* Pass two: the same lines again; messages go to `emit`. A malformed line is counted and added
 * to errs as FILE:LINE:COL (at most `max_errors` of them, the rest only counted). */
void carmen_line(carmen_t *c, const char *line, const char *file, marie_errors_t *errs, int max_errors);
const carmen_stats_t *carmen_stats(const carmen_t *c);

#ifdef __cplusplus
}
#endif
#endif
