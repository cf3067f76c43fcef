/* procstat: /proc readers for the manager's per-component CPU and RSS. */
#include "core/procstat.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/err.h"

static ssize_t read_small(const char *path, char *buf, size_t len)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return -1;
    ssize_t n = read(fd, buf, len - 1);
    MARIE_KEEP_ERRNO(close(fd));
    if (n < 0)
        return -1;
    buf[n] = 0;
    return n;
}

int marie_proc_parse_stat(const char *text, int64_t *utime, int64_t *stime)
{
    /* fields after the last ')': state(3) ppid pgrp session tty tpgid flags minflt cminflt
     * majflt cmajflt utime(14) stime(15) */
    const char *p = strrchr(text, ')');
    if (!p)
        return marie_fail(EINVAL);
    p++;
    long long v[13];
    char state;
    if (sscanf(p, " %c %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld", &state,
               &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &v[6], &v[7], &v[8], &v[9], &v[10], &v[11]) != 13)
        return marie_fail(EINVAL);
    *utime = v[10];
    *stime = v[11];
    return 0;
}

int marie_proc_usage(pid_t pid, int64_t *cpu_us, int64_t *rss_bytes)
{
    static long tck, page;
    if (!tck) {
        tck = sysconf(_SC_CLK_TCK);
        page = sysconf(_SC_PAGESIZE);
    }
    char path[64], buf[1024];
    snprintf(path, sizeof path, "/proc/%d/stat", (int)pid);
    ssize_t n = read_small(path, buf, sizeof buf);
    if (n < 0)
        return -1;
    int64_t ut, st;
    if (marie_proc_parse_stat(buf, &ut, &st) < 0)
        return marie_fail(EINVAL);
    *cpu_us = (ut + st) * 1000000 / tck;
    snprintf(path, sizeof path, "/proc/%d/statm", (int)pid);
    n = read_small(path, buf, sizeof buf);
    if (n < 0)
        return -1;
    long long size, res;
    if (sscanf(buf, "%lld %lld", &size, &res) != 2)
        return marie_fail(EINVAL);
    *rss_bytes = res * page;
    return 0;
}

int marie_host_load(float load[3])
{
    char buf[256];
    if (read_small("/proc/loadavg", buf, sizeof buf) < 0)
        return -1;
    return sscanf(buf, "%f %f %f", &load[0], &load[1], &load[2]) == 3 ? 0 : marie_fail(EINVAL);
}

float marie_cpu_percent(marie_cpu_sample_t *prev, int64_t cpu_us, int64_t now_us)
{
    float pct = 0;
    if (prev->at_us && now_us > prev->at_us && cpu_us >= prev->cpu_us)
        pct = (float)(100.0 * (double)(cpu_us - prev->cpu_us) / (double)(now_us - prev->at_us));
    prev->cpu_us = cpu_us;
    prev->at_us = now_us;
    return pct;
}

int marie_proc_starttime(pid_t pid, int64_t *ticks)
{
    char path[64], buf[1024];
    snprintf(path, sizeof path, "/proc/%d/stat", (int)pid);
    ssize_t n = read_small(path, buf, sizeof buf);
    if (n < 0)
        return -1;
    const char *p = strrchr(buf, ')');
    if (!p)
        return marie_fail(EINVAL);
    /* after ')': field 3 (state) ... field 22 (starttime) is the 20th token */
    long long v = 0;
    p++;
    for (int field = 3; field <= 22; field++) {
        while (*p == ' ')
            p++;
        if (!*p)
            return marie_fail(EINVAL);
        if (field == 22)
            v = atoll(p);
        while (*p && *p != ' ')
            p++;
    }
    *ticks = v;
    return 0;
}

int64_t marie_proc_field_bytes(pid_t pid, const char *file, const char *key)
{
    char path[96], line[256];
    snprintf(path, sizeof path, "/proc/%d/%s", (int)pid, file);
    FILE *f = fopen(path, "r");
    if (!f)
        return -1;
    size_t klen = strlen(key);
    long long kb = -1;
    while (fgets(line, sizeof line, f))
        if (strncmp(line, key, klen) == 0 && line[klen] == ':' && sscanf(line + klen + 1, " %lld kB", &kb) == 1)
            break;
    fclose(f);
    return kb < 0 ? -1 : (int64_t)kb * 1024;
}
