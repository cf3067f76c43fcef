/* proc: start and stop the project's programs from tests and benchmarks. */
#ifndef MARIE_TEST_PROC_H
#define MARIE_TEST_PROC_H

#include <stdbool.h>
#include <stddef.h>
#include <sys/types.h>

/* Runs argv[0] with argv (NULL-terminated). stdout and stderr are appended to `log`
 * ("/dev/null" to drop them), or inherited when log is NULL. The pid, or -1. */
pid_t test_spawn(char *const argv[], const char *log);
/* SIGTERM, then SIGKILL if the process is still there after 5 s; reaps it. pid <= 0, or a
 * process already reaped (stopped twice) or not this process's child: no-op. */
void test_stop(pid_t pid);
/* Writes `text` to a new file named after the mkstemps template `path` (its last `suffix_len`
 * characters kept, such as ".yaml"; the name is written back into path): a system file for a
 * test. 0, or -1 with errno. */
int test_write_temp(char *path, int suffix_len, const char *text);

/* Busy loops at the normal policy, one per pid slot, keeping the cores busy until
 * test_busy_stop() (or the caller's end: they die with it). 0, or -1 when fork failed. */
int test_busy_start(pid_t *pids, int n);
void test_busy_stop(pid_t *pids, int n);

/* Whether [at, at + len) lies in a read-only mapping of a ring (/dev/shm/marie-shm.*) in this
 * process (/proc/self/maps): a message read in place, not copied out. */
bool test_in_ring(const void *at, size_t len);

#endif
