/* log: leveled stderr logging; MARIE_LOG=debug|info|warn|error|off sets the threshold. */
#include "core/log.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <time.h>

#include "core/err.h"
#include "core/time.h"

static int threshold = -1;
static char log_name[64];

marie_log_level_t marie_log_threshold(void)
{
    if (threshold < 0) {
        const char *v = getenv("MARIE_LOG");
        threshold = MARIE_LOG_INFO;
        if (v) {
            static const char *const names[] = {"debug", "info", "warn", "error", "off"};
            for (int i = 0; i <= MARIE_LOG_OFF; i++)
                if (strcasecmp(v, names[i]) == 0)
                    threshold = i;
        }
    }
    return (marie_log_level_t)threshold;
}

void marie_log_set_threshold(marie_log_level_t level) { threshold = (int)level; }

void marie_log_set_name(const char *name)
{
    snprintf(log_name, sizeof log_name, "%s", name ? name : "");
}

void marie_log_write(marie_log_level_t level, const char *file, int line, const char *fmt, ...)
{
    static const char *const tags[] = {"debug", "info", "warn", "error"};
    int saved = errno;
    const char *base = strrchr(file, '/');
    base = base ? base + 1 : file;
    extern char *program_invocation_short_name;
    char msg[1024];
    MARIE_VFORMAT(msg, fmt);
    int64_t now = marie_wall_us();
    time_t secs = (time_t)(now / 1000000);
    struct tm tm;
    localtime_r(&secs, &tm);
    fprintf(stderr, "%02d:%02d:%02d.%03d %s %s %s:%d: %s\n", tm.tm_hour, tm.tm_min, tm.tm_sec,
            (int)(now / 1000 % 1000), log_name[0] ? log_name : program_invocation_short_name,
            tags[level < MARIE_LOG_OFF ? level : MARIE_LOG_ERROR], base, line, msg);
    errno = saved;
}

int marie_log_ratelimit_pass(long long *last_s, int every_s)
{
    long long now = (long long)(marie_mono_us() / 1000000);
    if (*last_s != 0 && now - *last_s < every_s)
        return 0;
    *last_s = now ? now : 1;
    return 1;
}

int marie_fail_why(char *why, size_t len, const char *fmt, ...)
{
    if (why && len) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(why, len, fmt, ap);
        va_end(ap);
    }
    return marie_fail(EINVAL);
}
