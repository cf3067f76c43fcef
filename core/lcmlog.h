/* lcmlog: pure reader of LCM log files (lcm-logger's event records), robust to corruption. */
#ifndef MARIE_LCMLOG_H
#define MARIE_LCMLOG_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define LCMLOG_SYNC        0xEDA1DA01u
#define LCMLOG_HEADER_LEN  28           /* sync, event number, timestamp, channel len, data len */
#define LCMLOG_MAX_CHANNEL 1024         /* longer channel names are taken for corruption */
#define LCMLOG_MAX_DATA    (64u << 20)  /* larger payloads likewise */

typedef struct lcmlog_parser lcmlog_parser_t;

/* One event record. Pointers are valid only during the callback. */
typedef struct {
    int64_t eventnum;
    int64_t utime;              /* the logger's receive time */
    const char *channel;        /* not NUL-terminated */
    size_t channel_len;
    const uint8_t *data;
    size_t data_len;
    uint64_t offset;            /* stream offset of the record's sync word */
} lcmlog_event_t;

typedef void (*lcmlog_event_cb_t)(void *user, const lcmlog_event_t *ev);
/* A stretch of the stream that is not a valid record: garbage before a sync word, a header
 * with impossible lengths, or a record cut short at the end. */
typedef void (*lcmlog_corrupt_cb_t)(void *user, uint64_t offset, const char *reason);

typedef struct {
    int64_t events;
    int64_t corrupt;            /* corrupt stretches reported */
    uint64_t skipped_bytes;     /* bytes not part of any valid record */
} lcmlog_stats_t;

/* NULL on ENOMEM. Either callback may be NULL. */
lcmlog_parser_t *lcmlog_parser_create(lcmlog_event_cb_t on_event, lcmlog_corrupt_cb_t on_corrupt, void *user);
void lcmlog_parser_destroy(lcmlog_parser_t *p);     /* NULL is a no-op */

/* Feed any number of bytes; complete records are reported at once. 0, or -1 with errno ENOMEM. */
int lcmlog_parser_feed(lcmlog_parser_t *p, const void *buf, size_t len);
/* End of stream: a partial record left over is reported as corrupt ("truncated"). */
void lcmlog_parser_finish(lcmlog_parser_t *p);
const lcmlog_stats_t *lcmlog_parser_stats(const lcmlog_parser_t *p);

/* Encode one record into out (capacity cap); returns its length, or -1 with errno ENOSPC. For
 * writers and tests. */
long lcmlog_encode(void *out, size_t cap, int64_t eventnum, int64_t utime, const char *channel,
                   const void *data, size_t data_len);

#ifdef __cplusplus
}
#endif
#endif
