/* marie-am: an up order's programs checked in a child process (declared in am.h). Each
 * program not yet described answers --describe, up to 5 s; done in the manager itself, that
 * stopped its heartbeats, status and orders for as long. The child writes '0' (passed) or '1',
 * then the errors as text, on a pipe; the loop reads it and calls done at its end. Where every
 * description is cached already, the manager checks at once itself. */
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <unistd.h>

#include "core/buf.h"
#include "core/log.h"
#include "managers/am.h"

struct am_check {
    pid_t pid;
    int fd;
    marie_buf_t out;
    am_loading_t *loading;
    am_check_done_t done;
    void *user;
};

bool am_check_busy(const am_t *am) { return am->check != NULL; }

/* finish: the check is over (its pipe at its end, or cancelled): done runs once. */
static void finish(am_t *am, bool ok, const char *errors)
{
    struct am_check *k = am->check;
    am->check = NULL;
    marie_loop_remove_fd(am->env.loop, k->fd);
    close(k->fd);
    k->done(am, k->loading, ok, errors, k->user);
    marie_buf_free(&k->out);
    free(k);
}

static void on_check_out(marie_loop_t *loop, int fd, short revents, void *user)
{
    am_t *am = user;
    struct am_check *k = am->check;
    char chunk[4096];
    ssize_t n = read(fd, chunk, sizeof chunk);
    if (n < 0 && (errno == EINTR || errno == EAGAIN))
        return;
    if (n > 0) {
        marie_buf_put(&k->out, chunk, (size_t)n);
        return;
    }
    /* the child's end: its exit is reaped with the components' (am_reap_children) */
    if (k->out.len == 0)
        finish(am, false, "the programs' check ended without a verdict\n");
    else
        finish(am, k->out.data[0] == '0', k->out.data + 1);
}

/* Every description in the cache (a system brought up before, a manager restarted on its
 * state directory): checked here, with no child to fork and wait for (on busy cores, a wait for
 * a CPU before the first component starts). 0: done has run. */
static int check_cached(am_t *am, am_loading_t *l, am_check_done_t done, void *user)
{
    marie_errors_t errs = {0};
    bool must_run = true;
    int rc = am_loading_check_cached(am, l, &errs, &must_run);
    if (must_run) {
        marie_errors_clear(&errs);
        return -1;
    }
    char *text = NULL;
    size_t len = 0;
    FILE *m = open_memstream(&text, &len);
    if (m) {
        marie_errors_print(&errs, m);
        fclose(m);
    }
    marie_errors_clear(&errs);
    done(am, l, rc == 0, text ? text : "", user);
    free(text);
    return 0;
}

int am_check_start(am_t *am, am_loading_t *l, am_check_done_t done, void *user)
{
    if (!am->check && check_cached(am, l, done, user) == 0)
        return 0;
    int p[2];
    struct am_check *k = calloc(1, sizeof *k);
    if (am->check || !k || pipe2(p, O_CLOEXEC) < 0) {
        free(k);
        am_loading_free(l);
        return -1;
    }
    pid_t pid = fork();
    if (pid == 0) {
        /* its own group, with the programs it runs: a cancel ends them all */
        setpgid(0, 0);
        prctl(PR_SET_PDEATHSIG, SIGKILL);
        close(p[0]);
        marie_errors_t errs = {0};
        int rc = am_loading_check_programs(am, l, &errs);
        FILE *f = fdopen(p[1], "w");
        if (f) {
            fputc(rc == 0 ? '0' : '1', f);
            marie_errors_print(&errs, f);
            fclose(f);
        }
        _exit(0);
    }
    close(p[1]);
    k->pid = pid;
    k->fd = p[0];
    marie_buf_init(&k->out, 1 << 20);
    k->loading = l;
    k->done = done;
    k->user = user;
    if (pid < 0 || marie_loop_add_fd(am->env.loop, p[0], POLLIN, on_check_out, am) < 0) {
        if (pid > 0)
            kill(-pid, SIGKILL);
        close(p[0]);
        free(k);
        am_loading_free(l);
        return -1;
    }
    am->check = k;
    return 0;
}

void am_check_cancel(am_t *am, const char *why)
{
    if (!am->check)
        return;
    kill(-am->check->pid, SIGKILL);
    finish(am, false, why);
}
