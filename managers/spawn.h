/* spawn: starts a supervised program without fork's copy of the caller: the child runs in the
 * caller's memory (CLONE_VM) on a stack of its own until its exec, while the caller goes on
 * (x86_64 with glibc 2.32 or later; elsewhere the child is a fork, as before). */
#ifndef MARIE_SPAWN_H
#define MARIE_SPAWN_H

#include <stddef.h>
#include <stdbool.h>
#include <sys/types.h>

#include "core/config.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct marie_spawner marie_spawner_t;

/* What of a request's scheduling the kernel refused: 0, or its errno. The child runs all the
 * same, with the caller's policy (or CPUs) in place of the refused ones. */
typedef struct {
    int policy_err;
    int cpus_err;
} marie_spawn_refused_t;

/* What to start. The spawner copies all of it: the caller may free it once marie_spawn returns. */
typedef struct {
    const char *path;           /* executed as is (execve); NULL: argv[0] as execvpe takes it */
    char *const *argv, *const *envp;
    int out_fd, err_fd;         /* the child's stdout and stderr; its stdin is /dev/null */
    const char *who;            /* a failed exec writes "WHO: exec ARGV0: REASON" to err_fd */
    const marie_sched_cfg_t *sched;     /* the child's policy, priority and CPUs; NULL: the caller's */
    bool sched_own;             /* sched's real-time policy is the child's only: what it starts
                                 * (threads, processes) begins at the normal policy
                                 * (SCHED_RESET_ON_FORK, set before its exec) */
    marie_spawn_refused_t *refused;     /* written by marie_spawn when not NULL */
    int cgroup_fd;              /* an open cgroup.procs the child moves itself into before its
                                 * exec (so it runs in that cgroup from its first instruction);
                                 * < 0: the caller's cgroup. 0 is taken as none: set it */
    long nofile;                /* the child's RLIMIT_NOFILE (soft and hard), set before its exec; 0: the caller's */
} marie_spawn_req_t;

/* NULL with errno on failure. */
marie_spawner_t *marie_spawner_create(void);
/* Frees what the children no longer use; one still before its exec keeps its part (a leak,
 * never a crash). NULL is a no-op. */
void marie_spawner_destroy(marie_spawner_t *s);

/* Starts req: the child's pid, or -1 with errno (nothing started). The child is born with
 * req->sched (from its first instruction: what it starts inherits it too), or with the
 * caller's scheduling where the kernel refuses it (req->refused says which). It gets its own
 * session and process group, SIGTERM when the caller's thread ends (PR_SET_PDEATHSIG; it
 * exits 127 at once if the caller has already gone), every signal at its default action and
 * none blocked, and only the caller's descriptors that are not close-on-exec. A failed exec
 * is a child that writes why to err_fd and exits 127. */
pid_t marie_spawn(marie_spawner_t *s, const marie_spawn_req_t *req);

/* Frees the memory of children that have exec'd or exited (marie_spawn does it too); returns
 * how many are still before their exec. */
size_t marie_spawner_sweep(marie_spawner_t *s);

#ifdef __cplusplus
}
#endif

#endif
