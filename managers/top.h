/* top: the table model of `marie top`: managers' status and components' heartbeats merged into
 * rows, with rates, staleness, sorting and lines cut to a terminal's width. No I/O: times are
 * passed in. */
#ifndef MARIE_TOP_H
#define MARIE_TOP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "lcmtypes/marie_am_status_t.h"
#include "lcmtypes/marie_heartbeat_t.h"

#ifdef __cplusplus
extern "C" {
#endif

#define TOP_NAME_MAX 64              /* host and component names are cut to this (with the NUL) */
#define TOP_LINE_MAX 512             /* a line of the screen, NUL included: widths are capped below it */
#define TOP_HOST_LOST_US 3000000     /* a manager silent this long is lost */
#define TOP_RATE_STALE_US 3000000    /* rates of a component silent this long are unknown */
#define TOP_HB_ONLY_KEEP_US 10000000 /* a component heard only by heartbeat is dropped after this */

typedef enum { TOP_SORT_CPU = 0, TOP_SORT_MEM, TOP_SORT_NAME, TOP_SORT_HOST } top_sort_t;
int top_sort_parse(const char *name);           /* "cpu" "mem" "name" "host"; -1 if unknown */

/* One component as shown. Unknown numbers are negative. */
typedef struct {
    char host[TOP_NAME_MAX];
    char name[TOP_NAME_MAX];
    char state[16];             /* the manager's state; "lost" when its host is lost */
    int32_t pid;
    int32_t restarts;           /* -1: no manager reports it */
    float cpu;
    int64_t rss;
    int64_t uptime_us;
    double in_rate, out_rate;   /* messages per second between the last heartbeats */
    int64_t bad;                /* bad_input of the last heartbeat */
} top_row_t;

typedef struct {
    char name[TOP_NAME_MAX];
    bool heard;                 /* a status has come from it (else only named in another's host list) */
    bool lost;
    int64_t silent_us;          /* since its last status */
    float load1, load5, load15;
    int32_t ncpu;
    float am_cpu;
    int64_t am_rss;
    char system[TOP_NAME_MAX];
    int32_t ncomponents;
} top_host_t;

typedef struct top top_t;

top_t *top_create(void);                        /* NULL + errno */
void top_destroy(top_t *t);                     /* NULL is a no-op */

/* Merge a manager's status / a component's heartbeat received at now_us (monotonic). 0 or -1 + errno (ENOMEM). */
int top_on_status(top_t *t, const marie_am_status_t *st, int64_t now_us);
int top_on_heartbeat(top_t *t, const marie_heartbeat_t *hb, int64_t now_us);

/* The hosts by name and the rows in `sort` order, as of now_us. The arrays belong to t and
 * stay valid until its next call. */
size_t top_hosts(top_t *t, int64_t now_us, const top_host_t **hosts);
size_t top_rows(top_t *t, top_sort_t sort, int64_t now_us, const top_row_t **rows);

/* Column layout for a width: columns are dropped (BAD, OUT/s, IN/s, UPTIME, PID, RST, RSS, in
 * that order) and names narrowed until a row fits. */
typedef struct {
    int width;
    int host_w, name_w;
    unsigned shown;             /* bit i: column i of the table is shown */
} top_layout_t;
void top_layout(top_layout_t *l, const top_row_t *rows, size_t n, int width);
/* The column header and a row, at most l->width characters (printable ASCII only). Return the length. */
int top_format_header(const top_layout_t *l, char *buf, size_t len);
int top_format_row(const top_layout_t *l, const top_row_t *r, char *buf, size_t len);

/* A whole screen. */
typedef enum {
    TOP_LINE_TITLE, TOP_LINE_HOST, TOP_LINE_HOST_LOST, TOP_LINE_BLANK, TOP_LINE_HEADER,
    TOP_LINE_ROW, TOP_LINE_ROW_WARN, TOP_LINE_ROW_BAD, TOP_LINE_MORE,
} top_line_kind_t;
typedef struct {
    top_line_kind_t kind;
    char text[TOP_LINE_MAX];
} top_line_t;
typedef struct {
    top_sort_t sort;
    int width;                  /* characters per line (capped to TOP_LINE_MAX - 1) */
    int height;                 /* lines; 0: as many as needed */
    double interval_s;          /* shown in the title */
    int64_t malformed;          /* messages refused by the checked decode, shown when not 0 */
} top_view_t;
/* Fills at most max lines (each no wider than v->width; no more than v->height lines: rows
 * that do not fit become one "... N more" line). Returns the number of lines. */
int top_frame(top_t *t, const top_view_t *v, int64_t now_us, top_line_t *lines, int max);
/* Lines a frame needs when its height is unlimited. */
int top_frame_lines(top_t *t, int64_t now_us);

#ifdef __cplusplus
}
#endif
#endif
