/* proc: start and stop the project's programs from tests and benchmarks. */
#include "tests/proc.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

extern char **environ;

pid_t test_spawn(char *const argv[], const char *log)
{
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    if (log) {
        posix_spawn_file_actions_addopen(&fa, 1, log, O_WRONLY | O_CREAT | O_APPEND, 0644);
        posix_spawn_file_actions_adddup2(&fa, 1, 2);
    }
    pid_t pid;
    int r = posix_spawn(&pid, argv[0], &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    return r == 0 ? pid : -1;
}

void test_stop(pid_t pid)
{
    if (pid <= 0)
        return;
    /* Already ended, or not (or no longer) our child, as when stopped twice: nothing to wait
     * for, and the pid may be someone else's by now. */
    pid_t r = waitpid(pid, NULL, WNOHANG);
    if (r == pid || (r < 0 && errno == ECHILD))
        return;
    kill(pid, SIGTERM);
    for (int i = 0; i < 250; i++) {
        r = waitpid(pid, NULL, WNOHANG);
        if (r == pid || (r < 0 && errno == ECHILD))
            return;
        usleep(20000);
    }
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
}

int test_write_temp(char *path, int suffix_len, const char *text)
{
    int fd = mkstemps(path, suffix_len);
    if (fd < 0)
        return -1;
    size_t len = strlen(text);
    ssize_t n = write(fd, text, len);
    close(fd);
    return n == (ssize_t)len ? 0 : -1;
}

int test_busy_start(pid_t *pids, int n)
{
    for (int i = 0; i < n; i++) {
        if ((pids[i] = fork()) < 0)
            return -1;
        if (pids[i] == 0) {
            prctl(PR_SET_PDEATHSIG, SIGKILL);
            for (volatile unsigned long k = 0;; k++)
                ;
        }
    }
    return 0;
}

void test_busy_stop(pid_t *pids, int n)
{
    for (int i = 0; i < n; i++)
        if (pids[i] > 0) {
            kill(pids[i], SIGKILL);
            waitpid(pids[i], NULL, 0);
            pids[i] = 0;
        }
}

bool test_in_ring(const void *at, size_t len)
{
    FILE *f = fopen("/proc/self/maps", "r");
    char line[512];
    bool yes = false;
    while (f && !yes && fgets(line, sizeof line, f)) {
        unsigned long lo, hi;
        char perms[8];
        if (sscanf(line, "%lx-%lx %7s", &lo, &hi, perms) == 3 && strstr(line, "/dev/shm/marie-shm.") &&
            perms[1] == '-')
            yes = (uintptr_t)at >= lo && (uintptr_t)at + len <= hi;
    }
    if (f)
        fclose(f);
    return yes;
}
