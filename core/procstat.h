/* procstat: CPU time and resident memory of a process, and the host load, from /proc. */
#ifndef MARIE_PROCSTAT_H
#define MARIE_PROCSTAT_H

#include <stdint.h>
#include <sys/types.h>

#ifdef __cplusplus
extern "C" {
#endif

/* CPU time (user + system) in microseconds and RSS in bytes of pid. 0, or -1 with errno. */
int marie_proc_usage(pid_t pid, int64_t *cpu_us, int64_t *rss_bytes);
/* Parse the text of /proc/PID/stat (the command may hold spaces and parentheses). */
int marie_proc_parse_stat(const char *text, int64_t *utime_ticks, int64_t *stime_ticks);
int marie_host_load(float load[3]);
/* A "Key:  N kB" field of /proc/PID/FILE in bytes, or -1: file "status" (VmRSS, RssAnon)
 * or "smaps_rollup" (Pss: shared library pages divided among the processes that map them). */
int64_t marie_proc_field_bytes(pid_t pid, const char *file, const char *key);
/* When the process started (clock ticks since boot, /proc/PID/stat field 22): with the pid,
 * it names one process for good (a pid alone may be reused). 0, or -1 with errno. */
int marie_proc_starttime(pid_t pid, int64_t *ticks);

/* Percent of one core between two samples. */
typedef struct {
    int64_t cpu_us, at_us;
} marie_cpu_sample_t;
float marie_cpu_percent(marie_cpu_sample_t *prev, int64_t cpu_us, int64_t now_us);

#ifdef __cplusplus
}
#endif
#endif
