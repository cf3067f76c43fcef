/* spawn: a program started from a child that shares the caller's memory until its exec.
 *
 * fork copies the caller's page tables, and then each page either side writes before the exec;
 * that was most of marie-am's time per component. posix_spawn and vfork share the memory
 * instead, but make the caller wait for the exec, and on a loaded machine each child first
 * waits for a CPU: a bring-up of 45 took longer that way than with fork (docs/managers.md).
 * Here the child shares the memory (CLONE_VM) on a stack of its own, and the caller goes on at
 * once. Its part (a copy of argv and envp, its stack: a mapping of its own, so that the pages
 * it touched go back to the system, not to malloc) is unmapped once the kernel has cleared ctid
 * (CLONE_CHILD_CLEARTID: at the exec, or at the exit).
 *
 * What the child may do, running beside the caller in its memory: read its own part, write its
 * own stack, and make system calls that cannot fail through glibc (resetting signals, setsid,
 * prctl, dup2, the signal mask). A call that can fail (the exec, writing why it failed) goes
 * around glibc (raw3): glibc would set errno, which is thread-local, and the child runs with
 * the caller's thread's (CLONE_VM without CLONE_SETTLS). To search PATH (execvpe, for a name
 * that marie-am did not find: a failure to come), the caller waits for the exec (CLONE_VFORK,
 * as posix_spawn does), so that glibc's calls are safe. Where raw3 is not written and tried
 * (only x86_64 so far), the child is a fork as before: its own copy of the memory. */
#include "managers/spawn.h"

#include <errno.h>
#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

/* raw3 is written for x86_64; strerrordesc_np (strerror's words without its locale) is glibc's
 * since 2.32. Elsewhere (other processors, musl, older glibc) the child is a fork. */
#define SPAWN_RAW 0
#if defined(__x86_64__)
#if defined(__GLIBC__) && defined(__GLIBC_PREREQ)
#if __GLIBC_PREREQ(2, 32)
#undef SPAWN_RAW
#define SPAWN_RAW 1
#endif
#endif
#endif

enum { CHILD_STACK = 32 * 1024 };

/* The child's code runs on a stack that a sanitizer does not know: not instrumented. */
#define CHILD __attribute__((no_sanitize_address))

typedef struct child {
    struct child *next;         /* the caller's list (the child never reads it) */
    pid_t ctid;                 /* not 0 until the kernel clears it: the child is done with this */
    bool shared;                /* CLONE_VM: the caller's memory, else a copy (fork) */
    bool raw;                   /* shared, the caller not waiting: calls that fail go around glibc */
    bool script;                /* execvpe's way: a file without #! runs through /bin/sh */
    int null_fd, out_fd, err_fd;
    int cgroup_fd;              /* > 0: the child writes "0" (itself) to it before its exec */
    long nofile;                /* > 0: its RLIMIT_NOFILE */
    int own_policy;             /* > 0: the kernel policy it keeps to itself (SCHED_RESET_ON_FORK) */
    struct sched_param own_param;
    pid_t parent;
    const char *path;           /* NULL: execvpe(argv[0]) (not raw) */
    const char *who;
    char **argv;                /* argv[-1] is "/bin/sh": the script's argv */
    char **envp;
    char *stack_top;
    size_t size;                /* of the mapping */
    max_align_t data[];         /* argv, envp, their strings, the stack */
} child_t;

struct marie_spawner {
    int null_fd;
    child_t *pending;
};

/* ---------------------------------------------------------------- the child */

#if SPAWN_RAW
/* A system call without glibc: -errno on failure, errno untouched. */
CHILD static long raw3(long nr, long a, long b, long c)
{
    long r;
    __asm__ volatile("syscall" : "=a"(r) : "a"(nr), "D"(a), "S"(b), "d"(c) : "rcx", "r11", "memory");
    return r;
}
#endif

/* A system call that may fail, around glibc in a raw child (errno is the caller's thread's). */
CHILD static long child_sys(const child_t *c, long nr, long a, long b, long d)
{
#if SPAWN_RAW
    if (c->raw)
        return raw3(nr, a, b, d);
#endif
    return syscall(nr, a, b, d);
}

/* Its limits, set in the child so that it never runs without them: its cgroup (the caller
 * made it and set its limits) and its open-file limit. A failure leaves the child as it is: the
 * caller checks where it landed (am_limits.c). */
CHILD static void child_limits(const child_t *c)
{
    if (c->cgroup_fd > 0)
        child_sys(c, SYS_write, c->cgroup_fd, (long)"0", 1);
    if (c->nofile > 0) {
        struct rlimit rl = {(rlim_t)c->nofile, (rlim_t)c->nofile};
        child_sys(c, SYS_setrlimit, RLIMIT_NOFILE, (long)&rl, 0);
    }
    /* Its policy not passed on: it is already at it, so only the flag changes (always allowed). */
    if (c->own_policy > 0)
        child_sys(c, SYS_sched_setscheduler, 0, c->own_policy | SCHED_RESET_ON_FORK, (long)&c->own_param);
}

/* execve: returns the errno of its failure. */
CHILD static int child_execve(const child_t *c, const char *path, char *const *argv)
{
#if SPAWN_RAW
    if (c->raw)
        return (int)-raw3(SYS_execve, (long)path, (long)argv, (long)c->envp);
#endif
    execve(path, argv, c->envp);
    return errno;
}

CHILD static int child_exec(const child_t *c)
{
    if (!c->path) {
        execvpe(c->argv[0], c->argv, c->envp);      /* not raw */
        return errno;
    }
    int err = child_execve(c, c->path, c->argv);
    if (err == ENOEXEC && c->script)
        err = child_execve(c, "/bin/sh", c->argv - 1);
    return err;
}

CHILD static size_t append(char *buf, size_t len, size_t cap, const char *s)
{
    while (*s && len < cap)
        buf[len++] = *s++;
    return len;
}

#if SPAWN_RAW
CHILD static const char *decimal(int v, char out[16])
{
    char *p = out + 15;
    unsigned u = v < 0 ? 0u - (unsigned)v : (unsigned)v;
    *p = 0;
    do
        *--p = (char)('0' + u % 10);
    while ((u /= 10) != 0);
    if (v < 0)
        *--p = '-';
    return p;
}
#endif

/* "WHO: exec ARGV0: REASON" on stderr, in strerror's words (marie-am keeps the C locale). */
CHILD static void child_say_failed(const child_t *c, int err)
{
    char buf[1024];
    size_t n = 0, cap = sizeof buf - 1;
    n = append(buf, n, cap, c->who);
    n = append(buf, n, cap, ": exec ");
    n = append(buf, n, cap, c->argv[0]);
    n = append(buf, n, cap, ": ");
#if SPAWN_RAW
    if (c->raw) {
        char num[16];
        const char *why = strerrordesc_np(err);
        if (!why) {
            n = append(buf, n, cap, "Unknown error ");
            why = decimal(err, num);
        }
        n = append(buf, n, cap, why);
        buf[n++] = '\n';
        raw3(SYS_write, 2, (long)buf, (long)n);
        return;
    }
#endif
    n = append(buf, n, cap, strerror(err));
    buf[n++] = '\n';
    ssize_t w = write(2, buf, n);
    (void)w;
}

CHILD static int child_main(void *arg)
{
    const child_t *c = arg;
    /* Every signal is blocked (marie_spawn blocked them): each goes back to its default action
     * before any is let through, so that no handler of the caller runs in its memory. 32 and
     * 33 are glibc's own. */
    struct sigaction dfl = {.sa_handler = SIG_DFL};
    for (int sig = 1; sig < NSIG; sig++)
        if (sig != SIGKILL && sig != SIGSTOP && !(sig > SIGSYS && sig < SIGRTMIN))
            sigaction(sig, &dfl, NULL);
    /* Own session and process group: stop signals go to the whole group. */
    setsid();
    prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (getppid() != c->parent)
        _exit(127);
    if (c->null_fd >= 0)
        dup2(c->null_fd, 0);
    dup2(c->out_fd, 1);
    dup2(c->err_fd, 2);
    child_limits(c);
    sigset_t none;
    sigemptyset(&none);
    sigprocmask(SIG_SETMASK, &none, NULL);
    child_say_failed(c, child_exec(c));
    _exit(127);
}

/* ---------------------------------------------------------------- the child's scheduling */

/* The child is born with its scheduling: the caller's thread takes the policy and CPUs asked
 * for just before the clone and goes back to its own right after (clone passes a thread's
 * scheduling on, and execve keeps it). Done so, the kernel's refusal comes to the caller with
 * its errno, the child has no call that can fail before its exec, and nothing it starts (a
 * shell's command, a thread) runs a moment at the normal policy first. */
typedef struct {
    bool policy, cpus;          /* changed: to be put back */
    int old_policy;
    struct sched_param old_param;
    cpu_set_t old_cpus;
} sched_saved_t;

static int sched_kernel_policy(marie_sched_policy_t p)
{
    return p == MARIE_SCHED_FIFO ? SCHED_FIFO : p == MARIE_SCHED_RR ? SCHED_RR : SCHED_OTHER;
}

static void sched_enter(const marie_sched_cfg_t *want, sched_saved_t *saved, marie_spawn_refused_t *refused)
{
    *saved = (sched_saved_t){0};
    *refused = (marie_spawn_refused_t){0};
    if (!want)
        return;
    if (want->policy != MARIE_SCHED_OTHER) {
        struct sched_param p = {.sched_priority = want->priority};
        saved->old_policy = sched_getscheduler(0);
        if (saved->old_policy < 0 || sched_getparam(0, &saved->old_param) < 0)
            refused->policy_err = errno;
        else if (sched_setscheduler(0, sched_kernel_policy(want->policy), &p) < 0)
            refused->policy_err = errno;
        else
            saved->policy = true;
    }
    if (want->ncpus) {
        cpu_set_t set;
        CPU_ZERO(&set);
        for (size_t i = 0; i < want->ncpus; i++)
            CPU_SET(want->cpus[i], &set);
        if (sched_getaffinity(0, sizeof saved->old_cpus, &saved->old_cpus) < 0 ||
            sched_setaffinity(0, sizeof set, &set) < 0)
            refused->cpus_err = errno;
        else
            saved->cpus = true;
    }
}

/* Going back to one's own policy and CPUs is always allowed. */
static void sched_leave(const sched_saved_t *saved)
{
    if (saved->policy)
        sched_setscheduler(0, saved->old_policy, &saved->old_param);
    if (saved->cpus)
        sched_setaffinity(0, sizeof saved->old_cpus, &saved->old_cpus);
}

/* ---------------------------------------------------------------- the caller */

marie_spawner_t *marie_spawner_create(void)
{
    marie_spawner_t *s = calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->null_fd = open("/dev/null", O_RDONLY | O_CLOEXEC);
    if (s->null_fd >= 0 && s->null_fd < 3) {
        /* not one of 0, 1 and 2: dup2 onto itself would leave it close-on-exec in the child */
        int fd = fcntl(s->null_fd, F_DUPFD_CLOEXEC, 3);
        close(s->null_fd);
        s->null_fd = fd;
    }
    return s;
}

void marie_spawner_destroy(marie_spawner_t *s)
{
    if (!s)
        return;
    marie_spawner_sweep(s);
    if (s->null_fd >= 0)
        close(s->null_fd);
    free(s);
}

size_t marie_spawner_sweep(marie_spawner_t *s)
{
    size_t left = 0;
    for (child_t **p = &s->pending; *p;) {
        child_t *c = *p;
        if (__atomic_load_n(&c->ctid, __ATOMIC_ACQUIRE) == 0) {
            *p = c->next;
            munmap(c, c->size);
        } else {
            left++;
            p = &c->next;
        }
    }
    return left;
}

static size_t count(char *const *v, size_t *bytes)
{
    size_t n = 0;
    for (; v[n]; n++)
        *bytes += strlen(v[n]) + 1;
    return n;
}

static char *copy_strv(char **dst, char *const *src, size_t n, char *str)
{
    for (size_t i = 0; i < n; i++) {
        size_t l = strlen(src[i]) + 1;
        dst[i] = memcpy(str, src[i], l);
        str += l;
    }
    dst[n] = NULL;
    return str;
}

/* One mapping: the child's part, its strings and its stack. */
static child_t *child_new(const marie_spawner_t *s, const marie_spawn_req_t *req)
{
    size_t bytes = (req->path ? strlen(req->path) : 0) + strlen(req->who) + 2;
    size_t argc = count(req->argv, &bytes), envc = count(req->envp, &bytes);
    size_t head = offsetof(child_t, data) + (argc + 2 + envc + 1) * sizeof(char *) + bytes;
    head = (head + 15) & ~(size_t)15;
    /* execvpe puts a script's argv on the stack */
    size_t page = (size_t)sysconf(_SC_PAGESIZE);
    size_t size = (head + CHILD_STACK + (argc + 2) * sizeof(char *) + page - 1) / page * page;
    child_t *c = mmap(NULL, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_STACK, -1, 0);
    if (c == MAP_FAILED)
        return NULL;
    c->size = size;
    char **ptrs = (char **)c->data;
    ptrs[0] = "/bin/sh";
    c->argv = ptrs + 1;
    c->envp = ptrs + argc + 2;
    char *str = (char *)(c->envp + envc + 1);
    str = copy_strv(c->argv, req->argv, argc, str);
    str = copy_strv(c->envp, req->envp, envc, str);
    c->who = strcpy(str, req->who);
    str += strlen(str) + 1;
    c->path = req->path ? strcpy(str, req->path) : NULL;
    c->stack_top = (char *)c + size;
    c->null_fd = s->null_fd;
    c->out_fd = req->out_fd;
    c->err_fd = req->err_fd;
    c->cgroup_fd = req->cgroup_fd;
    c->nofile = req->nofile;
    c->parent = getpid();
    /* execvpe's ways without it: a name with '/' is executed as is, then through /bin/sh if
     * it has no #!; a bare name is searched in PATH, by execvpe itself */
    c->script = !c->path;
    if (!c->path && strchr(c->argv[0], '/'))
        c->path = c->argv[0];
    c->shared = SPAWN_RAW;
    c->raw = c->shared && c->path;
    c->ctid = -1;
    c->next = NULL;
    return c;
}

pid_t marie_spawn(marie_spawner_t *s, const marie_spawn_req_t *req)
{
    marie_spawner_sweep(s);
    if (!req->argv || !req->argv[0] || !req->envp || !req->who) {
        errno = EINVAL;
        return -1;
    }
    child_t *c = child_new(s, req);
    if (!c)
        return -1;
    sigset_t all, old;
    sigfillset(&all);
    sigprocmask(SIG_SETMASK, &all, &old);
    int flags = SIGCHLD;
    if (c->shared)
        flags |= CLONE_VM | CLONE_CHILD_CLEARTID | (c->raw ? 0 : CLONE_VFORK);
    sched_saved_t saved;
    marie_spawn_refused_t refused;
    sched_enter(req->sched, &saved, &refused);
    if (req->sched_own && saved.policy) {
        c->own_policy = sched_kernel_policy(req->sched->policy);
        c->own_param.sched_priority = req->sched->priority;
    }
    pid_t pid = clone(child_main, c->stack_top, flags, c, NULL, NULL, &c->ctid);
    int err = errno;
    sched_leave(&saved);
    sigprocmask(SIG_SETMASK, &old, NULL);
    if (req->refused)
        *req->refused = refused;
    if (pid >= 0 && c->shared) {
        c->next = s->pending;
        s->pending = c;
    } else {
        munmap(c, c->size);         /* a fork's child has a copy of its own */
    }
    errno = err;
    return pid;
}
