/* ca_test: process and bus helpers shared by the CA tests and benchmarks. */
#include "tests/ca/ca_test.h"

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "core/config.h"
#include "core/time.h"

pid_t cat_spawn(const char *const *args)
{
    char prog[512];
    const char *b = getenv("B");
    snprintf(prog, sizeof prog, "%s/bin/marie-ca", b && *b ? b : "build");
    const char *argv[64];
    int n = 0;
    argv[n++] = prog;
    for (int i = 0; args[i] && n < 63; i++)
        argv[n++] = args[i];
    argv[n] = NULL;
    pid_t pid = fork();
    if (pid == 0) {
        execv(prog, (char *const *)argv);
        perror(prog);
        _exit(127);
    }
    return pid;
}

int cat_stop(pid_t pid, int sig)
{
    int st = 0;
    if (pid <= 0)
        return -1;
    kill(pid, sig);
    while (waitpid(pid, &st, 0) < 0 && errno == EINTR)
        ;
    return st;
}

bool cat_alive(pid_t pid)
{
    int st;
    return waitpid(pid, &st, WNOHANG) == 0;
}

#define MAXC 16
typedef struct {
    char name[64];
    marie_heartbeat_t *hb;
    int64_t count;
} seen_t;

struct cat_bus {
    lcm_t *lcm;
    marie_heartbeat_t_subscription_t *sub;
    seen_t seen[MAXC];
    int n;
};

static void on_hb(const lcm_recv_buf_t *rbuf, const char *channel, const marie_heartbeat_t *msg, void *user)
{
    cat_bus_t *b = user;
    seen_t *s = NULL;
    for (int i = 0; i < b->n && !s; i++)
        if (strcmp(b->seen[i].name, msg->component) == 0)
            s = &b->seen[i];
    if (!s) {
        if (b->n == MAXC)
            return;
        s = &b->seen[b->n++];
        snprintf(s->name, sizeof s->name, "%s", msg->component);
    }
    if (s->hb)
        marie_heartbeat_t_destroy(s->hb);
    s->hb = marie_heartbeat_t_copy(msg);
    s->count++;
}

cat_bus_t *cat_bus_create(void)
{
    cat_bus_t *b = calloc(1, sizeof *b);
    b->lcm = lcm_create(marie_default_url());
    if (!b->lcm) {
        free(b);
        return NULL;
    }
    b->sub = marie_heartbeat_t_subscribe(b->lcm, "MARIE_HEARTBEAT", on_hb, b);
    return b;
}

void cat_bus_destroy(cat_bus_t *b)
{
    if (!b)
        return;
    for (int i = 0; i < b->n; i++)
        if (b->seen[i].hb)
            marie_heartbeat_t_destroy(b->seen[i].hb);
    marie_heartbeat_t_unsubscribe(b->lcm, b->sub);
    lcm_destroy(b->lcm);
    free(b);
}

lcm_t *cat_lcm(cat_bus_t *b) { return b->lcm; }

bool cat_spin(cat_bus_t *b, int ms, bool (*done)(void *user), void *user)
{
    int64_t end = marie_mono_us() + (int64_t)ms * 1000;
    for (;;) {
        if (done && done(user))
            return true;
        int64_t left = end - marie_mono_us();
        if (left <= 0)
            return false;
        lcm_handle_timeout(b->lcm, (int)((left + 999) / 1000));
    }
}

static seen_t *find(cat_bus_t *b, const char *name)
{
    for (int i = 0; i < b->n; i++)
        if (strcmp(b->seen[i].name, name) == 0)
            return &b->seen[i];
    return NULL;
}

int64_t cat_heartbeats(cat_bus_t *b, const char *name)
{
    seen_t *s = find(b, name);
    return s ? s->count : 0;
}

typedef struct {
    cat_bus_t *b;
    const char *name, *counter;
    int64_t value, seen, after;
} wait_t;

static bool in_state(void *user)
{
    wait_t *w = user;
    seen_t *s = find(w->b, w->name);
    return s && s->count > w->after && s->hb->state == w->value;
}

bool cat_wait_running(cat_bus_t *b, const char *name, int ms)
{
    wait_t w = { b, name, NULL, 2, 0, cat_heartbeats(b, name) };
    return cat_spin(b, ms, in_state, &w);
}

bool cat_wait_state(cat_bus_t *b, const char *name, int state, int ms, char *reason, size_t cap)
{
    wait_t w = { b, name, NULL, state, 0, 0 };
    bool ok = cat_spin(b, ms, in_state, &w);
    if (ok && reason)
        snprintf(reason, cap, "%s", find(b, name)->hb->reason);
    return ok;
}

static bool counter_reached(void *user)
{
    wait_t *w = user;
    seen_t *s = find(w->b, w->name);
    if (!s)
        return false;
    const marie_heartbeat_t *hb = s->hb;
    int64_t v = 0;
    if (strcmp(w->counter, "bad_input") == 0)
        v = hb->bad_input;
    else if (strcmp(w->counter, "drops") == 0)
        v = hb->drops;
    else
        for (int i = 0; i < hb->ncounters; i++)
            if (strcmp(hb->counters[i].name, w->counter) == 0)
                v = hb->counters[i].value;
    w->seen = v;
    return v >= w->value;
}

bool cat_wait_counter(cat_bus_t *b, const char *name, const char *counter, int64_t value,
                      int ms, int64_t *seen)
{
    wait_t w = { b, name, counter, value, 0, 0 };
    bool ok = cat_spin(b, ms, counter_reached, &w);
    if (seen)
        *seen = w.seen;
    return ok;
}

void cat_tmpdir(char *out, size_t cap)
{
    snprintf(out, cap, "/tmp/marie-ca-test-XXXXXX");
    if (!mkdtemp(out))
        out[0] = 0;
}

void cat_rmdir(const char *dir)
{
    char cmd[600];
    if (!dir[0])
        return;
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0)
        fprintf(stderr, "cannot remove %s\n", dir);
}
