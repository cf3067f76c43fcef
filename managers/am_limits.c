/* am_limits: marie-am holds components to their `limits:` (docs/managers.md, "Resource limits"):
 * a cgroup v2 of their own where the manager may make one (the kernel caps memory and CPU), the
 * open-file rlimit always, and its own watch of what they use; a breach is an event and the
 * policy (restart or stop). The decisions are limits.c's. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/clear.h"
#include "core/err.h"
#include "core/log.h"
#include "lcmtypes/marie_event_t.h"
#include "managers/am.h"

#define SAMPLE_US 100000        /* a limited component is looked at ten times a second */

struct am_limits {
    bool tried;
    char *base;                 /* the cgroup v2 directory components' cgroups go in; NULL: none */
    char why[300];              /* why there is none */
};

/* ---------------------------------------------------------------- files */

static int write_text(const char *dir, const char *name, const char *text)
{
    char path[PATH_MAX];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    int fd = open(path, O_WRONLY | O_CLOEXEC);
    if (fd < 0)
        return -1;
    ssize_t n = write(fd, text, strlen(text));
    MARIE_KEEP_ERRNO(close(fd));
    return n < 0 ? -1 : 0;
}

/* The number after "key " in a flat-keyed file (memory.events, cpu.stat); -1 when absent. */
static int64_t read_key(const char *dir, const char *name, const char *key)
{
    char path[PATH_MAX], line[256];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "re");
    int64_t v = -1;
    size_t kl = strlen(key);
    while (f && fgets(line, sizeof line, f))
        if (strncmp(line, key, kl) == 0 && line[kl] == ' ')
            v = strtoll(line + kl + 1, NULL, 10);
    if (f)
        fclose(f);
    return v;
}

/* Where the cgroup v2 hierarchy is mounted and this process's place in it, joined; NULL (why)
 * when there is none (a host with cgroup v1 controllers, a container without it). */
static char *own_cgroup(char *why, size_t len)
{
    char line[1024], mnt[PATH_MAX] = "", path[PATH_MAX] = "";
    FILE *f = fopen("/proc/self/mountinfo", "re");
    while (f && !mnt[0] && fgets(line, sizeof line, f)) {
        char *dash = strstr(line, " - cgroup2 ");
        if (dash && sscanf(line, "%*s %*s %*s %*s %4095s", mnt) != 1)
            mnt[0] = 0;
    }
    if (f)
        fclose(f);
    f = fopen("/proc/self/cgroup", "re");
    while (f && !path[0] && fgets(line, sizeof line, f))
        if (strncmp(line, "0::", 3) == 0)
            snprintf(path, sizeof path, "%s", line + 3);
    if (f)
        fclose(f);
    path[strcspn(path, "\n")] = 0;
    if (!mnt[0] || !path[0]) {
        snprintf(why, len, "no cgroup v2 hierarchy is mounted");
        return NULL;
    }
    char *dir;
    if (asprintf(&dir, "%s%s", mnt, strcmp(path, "/") == 0 ? "" : path) < 0)
        return NULL;
    return dir;
}

/* cgroup v2 with memory and cpu, made ready for components' cgroups: marie-am moves itself into a
 * leaf of its own (processes may not sit beside child cgroups that have controllers) and gives
 * its cgroup's children the two controllers. NULL (why) when any of it is refused. */
static char *make_base(char *why, size_t len)
{
    char *dir = own_cgroup(why, len), ctl[256] = "", leaf[PATH_MAX];
    if (!dir)
        return NULL;
    size_t dl = strlen(dir);
    if (dl > 9 && strcmp(dir + dl - 9, "/marie-am") == 0)
        dir[dl - 9] = 0;        /* a manager started again where the last one moved itself */
    snprintf(leaf, sizeof leaf, "%s/cgroup.controllers", dir);
    FILE *f = fopen(leaf, "re");
    if (f && !fgets(ctl, sizeof ctl, f))
        ctl[0] = 0;
    if (f)
        fclose(f);
    if (!strstr(ctl, "memory") || !strstr(ctl, "cpu"))
        snprintf(why, len, "the cgroup v2 of marie-am (%s) has no memory and cpu controllers (it has: %s)", dir,
                 ctl[0] ? strtok(ctl, "\n") : "none");
    else if (snprintf(leaf, sizeof leaf, "%s/marie-am", dir) > 0 && mkdir(leaf, 0755) < 0 && errno != EEXIST)
        snprintf(why, len, "cannot make %.200s: %s", leaf, strerror(errno));
    else if (write_text(leaf, "cgroup.procs", "0") < 0)
        snprintf(why, len, "cannot move marie-am into %.200s: %s", leaf, strerror(errno));
    else if (write_text(dir, "cgroup.subtree_control", "+memory +cpu") < 0)
        snprintf(why, len, "cannot give %s's children the memory and cpu controllers: %s (other processes in "
                 "it, or not delegated: Delegate=yes in the unit)", dir, strerror(errno));
    else
        return dir;
    free(dir);
    return NULL;
}

static bool needs_cgroup(const am_t *am)
{
    for (size_t i = 0; i < am_ncomps(am); i++)
        if (am_comp_at(am, i)->sv.local && (am_comp_at(am, i)->cfg->limits.memory > 0 || am_comp_at(am, i)->cfg->limits.cpu > 0))
            return true;
    return false;
}

/* Once, at the first start of a component with memory or cpu limits. */
static struct am_limits *limits_of(am_t *am)
{
    if (!am->limits && !(am->limits = calloc(1, sizeof *am->limits)))
        return NULL;
    struct am_limits *l = am->limits;
    if (!l->tried && needs_cgroup(am)) {
        l->tried = true;
        l->base = make_base(l->why, sizeof l->why);
        if (l->base)
            marie_info("limits: memory and cpu limits are cgroup v2 limits, in %s", l->base);
        else
            marie_info("limits: no cgroup for memory and cpu limits (%s): marie-am watches them", l->why);
    }
    return l;
}

void am_limits_comp_free(comp_t *c)
{
    if (c->lim.cgroup)
        rmdir(c->lim.cgroup);     /* empty once its processes are gone */
    MARIE_CLEAR(c->lim.cgroup, free);
}

void am_limits_free(am_t *am)
{
    if (am->limits)
        free(am->limits->base);
    MARIE_CLEAR(am->limits, free);
}

/* ---------------------------------------------------------------- starting */

/* The component's cgroup with its limits set, and cgroup.procs open for the child (-1: none). */
static int prepare_cgroup(comp_t *c, const char *base)
{
    const marie_limits_cfg_t *l = &c->cfg->limits;
    char mem[32] = "max", cpu[48] = "max 100000";
    if (!c->lim.cgroup && asprintf(&c->lim.cgroup, "%s/c.%s", base, c->cfg->name) < 0)
        c->lim.cgroup = NULL;
    if (!c->lim.cgroup || (mkdir(c->lim.cgroup, 0755) < 0 && errno != EEXIST))
        return -1;
    if (l->memory > 0)
        snprintf(mem, sizeof mem, "%lld", (long long)l->memory);
    if (l->cpu > 0)
        snprintf(cpu, sizeof cpu, "%lld 100000", (long long)(l->cpu * 100000 + 0.5));
    int err = write_text(c->lim.cgroup, "memory.max", mem) < 0 ? errno : 0;
    write_text(c->lim.cgroup, "memory.swap.max", "0");     /* absent without swap accounting */
    if (err == 0 && write_text(c->lim.cgroup, "cpu.max", cpu) < 0)
        err = errno;
    if (err) {
        am_event(c->am, MARIE_EVENT_T_SEV_WARN, "limit_refused", "%s: cgroup %s refuses its limits (%s): marie-am "
                 "watches them instead", c->cfg->name, c->lim.cgroup, strerror(err));
        return -1;
    }
    char procs[PATH_MAX];
    snprintf(procs, sizeof procs, "%s/cgroup.procs", c->lim.cgroup);
    return open(procs, O_WRONLY | O_CLOEXEC);
}

/* The open-file limit, within what marie-am itself may give (a user without the right cannot
 * raise a hard limit). */
static long nofile_for(comp_t *c)
{
    long want = (long)c->cfg->limits.nofile;
    struct rlimit own;
    if (want <= 0 || getrlimit(RLIMIT_NOFILE, &own) < 0 || geteuid() == 0 || (rlim_t)want <= own.rlim_max)
        return want;
    am_event(c->am, MARIE_EVENT_T_SEV_WARN, "limit_refused", "%s: nofile %ld is above marie-am's own hard limit "
             "%llu: it gets %llu", c->cfg->name, want, (unsigned long long)own.rlim_max,
             (unsigned long long)own.rlim_max);
    return (long)own.rlim_max;
}

void am_limits_prepare(comp_t *c, int *cgroup_fd, long *nofile)
{
    *cgroup_fd = -1;
    *nofile = nofile_for(c);
    struct am_limits *l = marie_limits_cfg_any(&c->cfg->limits) ? limits_of(c->am) : NULL;
    if (l && l->base && (c->cfg->limits.memory > 0 || c->cfg->limits.cpu > 0))
        *cgroup_fd = prepare_cgroup(c, l->base);
    c->lim.in_cgroup = *cgroup_fd >= 0;
}

/* ---------------------------------------------------------------- watching */

static int64_t count_files(pid_t pid)
{
    char path[64];
    snprintf(path, sizeof path, "/proc/%d/fd", (int)pid);
    DIR *d = opendir(path);
    if (!d)
        return -1;
    int64_t n = 0;
    for (struct dirent *e; (e = readdir(d));)
        n += e->d_name[0] != '.';
    closedir(d);
    return n;
}

static marie_limit_sample_t sample(const comp_t *c, bool exited)
{
    marie_limit_sample_t s = {am_now_us(), -1, -1, -1, -1, -1};
    if (!exited) {
        marie_proc_usage(c->sv.pid, &s.cpu_us, &s.rss);
        if (c->cfg->limits.nofile > 0)
            s.nfiles = count_files(c->sv.pid);
    }
    if (c->lim.in_cgroup) {
        s.oom_kills = read_key(c->lim.cgroup, "memory.events", "oom_kill");
        s.throttled_us = read_key(c->lim.cgroup, "cpu.stat", "throttled_usec");
    }
    return s;
}

void am_limits_spawned(comp_t *c, int cgroup_fd)
{
    if (cgroup_fd >= 0)
        close(cgroup_fd);
    c->lim.w = (marie_limit_watch_t){0};
    c->lim.next_us = am_now_us() + SAMPLE_US;
    if (c->lim.in_cgroup) {     /* the counters before this instance */
        marie_limit_sample_t s = sample(c, true);
        marie_limits_start(&c->lim.w, &s);
    }
}

static void breach(comp_t *c, const char *why)
{
    bool stop = c->cfg->limits.on_breach == MARIE_BREACH_STOP;
    c->lim.breaches++;
    am_event(c->am, MARIE_EVENT_T_SEV_WARN, "limit_exceeded", "%s (pid %d): %s: %s it", c->cfg->name, c->sv.pid, why,
             stop ? "stopping" : "restarting");
    marie_sv_state_t before = c->sv.st;
    marie_sv_action_t act;
    marie_sv_breach(&c->sv, stop, &act);
    am_comp_apply(c, before, &act);
    am_status_changed(c->am);
}

static void check(comp_t *c, bool exited)
{
    marie_limit_sample_t s = sample(c, exited);
    char why[300];
    if (marie_limits_check(&c->cfg->limits, c->lim.in_cgroup, &c->lim.w, &s, why, sizeof why))
        breach(c, why);
}

void am_limits_tick(am_t *am)
{
    int64_t now = am_now_us();
    for (size_t i = 0; i < am_ncomps(am); i++) {
        comp_t *c = am_comp_at(am, i);
        if (!c->sv.local || c->sv.pid <= 0 || !marie_limits_cfg_any(&c->cfg->limits) || now < c->lim.next_us ||
            (c->sv.st != MARIE_SV_RUNNING && c->sv.st != MARIE_SV_STARTING))
            continue;
        c->lim.next_us = now + SAMPLE_US;
        check(c, false);
    }
}

/* Its process has ended: the kernel may have killed it at its cgroup's memory limit. */
void am_limits_exited(comp_t *c)
{
    if (c->lim.in_cgroup && c->sv.st != MARIE_SV_STOPPING)
        check(c, true);
}

const char *am_limits_text(const comp_t *c, char *out, size_t len)
{
    char t[128];
    marie_limits_cfg_text(&c->cfg->limits, t, sizeof t);
    if (!t[0])
        out[0] = 0;
    else
        snprintf(out, len, "%s (%s)", t, c->lim.in_cgroup ? "cgroup" : c->cfg->limits.memory > 0 ||
                 c->cfg->limits.cpu > 0 ? "watched" : "rlimit");
    return out;
}

int am_limits_breaches(const comp_t *c) { return c->lim.breaches; }
