/* tts_child: one synthesis by an external synthesizer process (see tts_child.h). */
#include "adapters/tts/tts_child.h"

#include <errno.h>
#include <fcntl.h>
#include <stdbool.h>
#include <poll.h>
#include <signal.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>

#include "core/buf.h"
#include "hw/audio/wav.h"

#define MAX_OUTPUT (32u << 20)

struct tts_child {
    marie_loop_t *loop;
    pid_t pid;
    int fd;
    int err_fd;                 /* the synthesizer's stderr (a memfd), for why it failed */
    char why[160];
    uint8_t *buf;
    size_t len, cap;
    tts_child_done_cb_t cb;
    void *user;
};

/* `fallback` with the synthesizer's own words from the end of its stderr: its first line there
 * that says ERROR ("SIOD ERROR: ran out of storage"), else its last line. */
static const char *stderr_why(tts_child_t *t, const char *fallback)
{
    char buf[1024];
    off_t end = t->err_fd >= 0 ? lseek(t->err_fd, 0, SEEK_END) : -1;
    off_t from = end > (off_t)sizeof buf - 1 ? end - (off_t)sizeof buf + 1 : 0;
    ssize_t n = end > 0 ? pread(t->err_fd, buf, (size_t)(end - from), from) : -1;
    if (n <= 0)
        return fallback;
    buf[n] = '\0';
    char *line = NULL;
    for (char *save = NULL, *l = strtok_r(buf, "\r\n", &save); l; l = strtok_r(NULL, "\r\n", &save))
        if (!line || !strstr(line, "ERROR"))     /* an error line outranks what follows it */
            line = l;
    if (!line)
        return fallback;
    for (size_t len = strlen(line); len > 0 && (line[len - 1] == ' ' || line[len - 1] == '\t'); len--)
        line[len - 1] = '\0';
    snprintf(t->why, sizeof t->why, "%s (%s)", fallback, line);
    return t->why;
}

static void reap(tts_child_t *t, bool kill_it)
{
    if (t->fd >= 0) {
        marie_loop_remove_fd(t->loop, t->fd);
        close(t->fd);
        t->fd = -1;
    }
    if (t->pid > 0) {
        if (kill_it)
            kill(t->pid, SIGKILL);
        while (waitpid(t->pid, NULL, 0) < 0 && errno == EINTR)
            ;
        t->pid = 0;
    }
}

static void free_child(tts_child_t *t)
{
    if (t->err_fd >= 0)
        close(t->err_fd);
    free(t->buf);
    free(t);
}

static void finish(tts_child_t *t)
{
    reap(t, false);
    wav_info_t w;
    const char *why = "the synthesizer wrote nothing";
    int16_t *pcm = NULL;
    if (t->len && wav_parse(t->buf, t->len, &w, &why) == 0) {
        pcm = malloc(sizeof(int16_t) * (w.frames ? w.frames : 1));
        float *f = malloc(sizeof(float) * (w.frames ? w.frames : 1));
        if (pcm && f) {
            wav_channel_float(&w, 0, f);
            for (size_t i = 0; i < w.frames; i++)
                pcm[i] = (int16_t)(f[i] * 32768.0f);
            t->cb(pcm, w.frames, w.rate, NULL, t->user);
        } else {
            t->cb(NULL, 0, 0, "out of memory", t->user);
        }
        free(f);
    } else {
        t->cb(NULL, 0, 0, stderr_why(t, why), t->user);
    }
    free(pcm);
    free_child(t);
}

static void on_output(marie_loop_t *loop, int fd, short revents, void *user)
{
    tts_child_t *t = user;
    for (;;) {
        if (t->cap - t->len < 65536 &&
            (t->len + 65536 > MAX_OUTPUT || MARIE_GROW(t->buf, t->cap, t->len + 65536) < 0)) {
            reap(t, true);
            t->cb(NULL, 0, 0, "synthesizer output too long", t->user);
            free_child(t);
            return;
        }
        ssize_t r = read(fd, t->buf + t->len, t->cap - t->len);
        if (r > 0) {
            t->len += (size_t)r;
            continue;
        }
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0 && errno == EAGAIN)
            return;
        finish(t);      /* end of file, or an error: what arrived is all there is */
        return;
    }
}

int tts_split_command(char *line, char *argv[], int max)
{
    int n = 0;
    char *in = line, *out = line;
    for (;;) {
        while (*in == ' ' || *in == '\t')
            in++;
        if (!*in)
            break;
        if (n >= max - 1)
            return -1;
        argv[n++] = out;
        char quote = 0;
        for (; *in && (quote || (*in != ' ' && *in != '\t')); in++) {
            if (quote ? *in == quote : (*in == '\'' || *in == '"'))
                quote = quote ? 0 : *in;
            else
                *out++ = *in;
        }
        if (quote)
            return -1;
        if (*in)
            in++;
        *out++ = '\0';
    }
    argv[n] = NULL;
    return n;
}

tts_child_t *tts_child_start(marie_loop_t *loop, char *const argv[], const char *text,
                             tts_child_done_cb_t cb, void *user)
{
    int in[2] = { -1, -1 }, out[2] = { -1, -1 };
    tts_child_t *t = calloc(1, sizeof(*t));
    if (t) {
        t->fd = -1;
        t->err_fd = memfd_create("tts-stderr", MFD_CLOEXEC);     /* -1: stderr goes nowhere */
    }
    if (!t || pipe2(in, O_CLOEXEC) || pipe2(out, O_CLOEXEC))
        goto err;
    t->loop = loop;
    t->cb = cb;
    t->user = user;
    t->pid = fork();
    if (t->pid < 0)
        goto err;
    if (t->pid == 0) {
        dup2(in[0], 0);
        dup2(out[1], 1);
        int err = t->err_fd >= 0 ? t->err_fd : open("/dev/null", O_WRONLY);
        if (err >= 0)
            dup2(err, 2);
        execvp(argv[0], argv);
        dprintf(2, "cannot run %s: %s\n", argv[0], strerror(errno));
        _exit(127);
    }
    close(in[0]);
    close(out[1]);
    in[0] = out[1] = -1;
    /* A sentence is far smaller than a pipe's buffer: this write does not block. */
    size_t n = strlen(text);
    ssize_t w = write(in[1], text, n);
    (void)w;
    close(in[1]);
    t->fd = out[0];
    fcntl(t->fd, F_SETFL, fcntl(t->fd, F_GETFL) | O_NONBLOCK);
    if (marie_loop_add_fd(loop, t->fd, POLLIN, on_output, t)) {
        reap(t, true);
        free_child(t);
        return NULL;
    }
    return t;
err:;
    int e = errno;
    for (int i = 0; i < 2; i++) {
        if (in[i] >= 0)
            close(in[i]);
        if (out[i] >= 0)
            close(out[i]);
    }
    if (t)
        free_child(t);
    errno = e;
    return NULL;
}

void tts_child_cancel(tts_child_t *t)
{
    if (!t)
        return;
    reap(t, true);
    free_child(t);
}
