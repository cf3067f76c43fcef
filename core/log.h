/* log: leveled logging to stderr with file:line, filtered by MARIE_LOG at run time. */
#ifndef MARIE_LOG_H
#define MARIE_LOG_H

#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    MARIE_LOG_DEBUG = 0,
    MARIE_LOG_INFO,
    MARIE_LOG_WARN,
    MARIE_LOG_ERROR,
    MARIE_LOG_OFF,
} marie_log_level_t;

/* Threshold from MARIE_LOG (debug|info|warn|error|off), read once; default info. */
marie_log_level_t marie_log_threshold(void);
void marie_log_set_threshold(marie_log_level_t level);
/* Name shown on every line (the component name); NULL shows the program name. */
void marie_log_set_name(const char *name);
void marie_log_write(marie_log_level_t level, const char *file, int line, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

#define MARIE_LOG_AT(lvl, ...) \
    do { if ((lvl) >= marie_log_threshold()) marie_log_write((lvl), __FILE__, __LINE__, __VA_ARGS__); } while (0)
#define marie_debug(...) MARIE_LOG_AT(MARIE_LOG_DEBUG, __VA_ARGS__)
#define marie_info(...)  MARIE_LOG_AT(MARIE_LOG_INFO, __VA_ARGS__)
#define marie_warn(...)  MARIE_LOG_AT(MARIE_LOG_WARN, __VA_ARGS__)
#define marie_error(...) MARIE_LOG_AT(MARIE_LOG_ERROR, __VA_ARGS__)

/* Log at most once per `every_s` seconds per call site (bad-input storms). */
#define marie_warn_ratelimited(every_s, ...) do { \
        static long long marie_rl_last_; \
        if (marie_log_ratelimit_pass(&marie_rl_last_, (every_s))) marie_warn(__VA_ARGS__); \
    } while (0)
int marie_log_ratelimit_pass(long long *last_s, int every_s);

/* The error rule's reason (docs/core.md): the printf-style reason goes to why[0..len) when why is
 * given, errno becomes EINVAL, and -1 is returned: `return marie_fail_why(why, len, "...", ...);` */
int marie_fail_why(char *why, size_t len, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* In a function ending in `fmt, ...`: its message, formatted into the char array buf (cut at
 * the array's size). The one way marie's reporters (bad input, errors, events) format. */
#define MARIE_VFORMAT(buf, fmt) \
    do { \
        va_list ap_; \
        va_start(ap_, fmt); \
        vsnprintf(buf, sizeof(buf), fmt, ap_); \
        va_end(ap_); \
    } while (0)

#ifdef __cplusplus
}
#endif
#endif
