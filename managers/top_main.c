/* marie-top: the live system in a terminal (managers' status and heartbeats), refreshed in
 * place; run as `marie top`. */
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ioctl.h>
#include <sys/signalfd.h>
#include <termios.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "core/buf.h"
#include "core/component.h"
#include "core/loop.h"
#include "core/time.h"
#include "core/typeinfo.h"
#include "proto/am_proto.h"
#include "managers/top.h"
#include "core/version.h"

typedef struct {
    top_t *model;
    lcm_t *lcm;
    marie_loop_t *loop;
    top_view_t view;
    bool once, color, interactive;
    bool on_screen;             /* the alternate screen is up and the tty is in raw mode */
    int64_t malformed;
    int rc;
    top_line_t *lines;
    int cap_lines;
    char *out;
    size_t cap_out;
} app_t;

static struct termios saved_tty;
static bool tty_saved;

static void write_all(const char *s, size_t n)
{
    while (n > 0) {
        ssize_t w = write(STDOUT_FILENO, s, n);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return;
        s += w;
        n -= (size_t)w;
    }
}

/* Alternate screen and raw keys on; off restores exactly what was there (also at exit). */
static void screen_leave(app_t *a)
{
    if (!a->on_screen)
        return;
    static const char seq[] = "\033[0m\033[?25h\033[?1049l";
    write_all(seq, sizeof seq - 1);
    if (tty_saved)
        tcsetattr(STDIN_FILENO, TCSAFLUSH, &saved_tty);
    a->on_screen = false;
}

static int screen_enter(app_t *a)
{
    if (tcgetattr(STDIN_FILENO, &saved_tty) < 0)
        return -1;
    tty_saved = true;
    struct termios raw = saved_tty;
    raw.c_lflag &= ~(tcflag_t)(ICANON | ECHO);   /* ISIG stays: ^C and ^Z work as usual */
    raw.c_cc[VMIN] = 1;
    raw.c_cc[VTIME] = 0;
    if (tcsetattr(STDIN_FILENO, TCSAFLUSH, &raw) < 0)
        return -1;
    static const char seq[] = "\033[?1049h\033[?25l\033[H\033[2J";
    write_all(seq, sizeof seq - 1);
    a->on_screen = true;
    return 0;
}

static app_t *exit_app;
static void restore_at_exit(void)
{
    if (exit_app)
        screen_leave(exit_app);
}

static void term_size(app_t *a)
{
    struct winsize ws;
    if (ioctl(STDOUT_FILENO, TIOCGWINSZ, &ws) == 0 && ws.ws_col > 0) {
        a->view.width = ws.ws_col;
        a->view.height = a->once ? 0 : ws.ws_row > 0 ? ws.ws_row : 24;   /* some ptys report no rows */
    } else {
        a->view.width = TOP_LINE_MAX - 1;   /* not a terminal: nothing to cut */
        a->view.height = 0;
    }
}

static const char *color_of(top_line_kind_t k)
{
    switch (k) {
    case TOP_LINE_TITLE: return "\033[1m";
    case TOP_LINE_HOST_LOST: return "\033[1;31m";
    case TOP_LINE_HEADER: return "\033[7m";
    case TOP_LINE_ROW_WARN: return "\033[33m";
    case TOP_LINE_ROW_BAD: return "\033[31m";
    case TOP_LINE_MORE: return "\033[2m";
    default: return "";
    }
}

static int out_add(app_t *a, size_t *pos, const char *s)
{
    size_t n = strlen(s);
    if (MARIE_GROW(a->out, a->cap_out, *pos + n + 1) < 0)
        return -1;
    memcpy(a->out + *pos, s, n + 1);
    *pos += n;
    return 0;
}

/* One frame written at once. On screen each line is placed by cursor address and never ends
 * with a newline, so the terminal never scrolls; off screen (--once) lines end with '\n'. */
static void draw(app_t *a)
{
    /* stopped by ^Z, or resumed before SIGCONT is read: a frame now would land on the shell's
     * screen and come back when marie top quits */
    if (a->interactive && !a->on_screen)
        return;
    int64_t now = marie_mono_us();
    int need = a->view.height > 0 ? a->view.height : top_frame_lines(a->model, now);
    if (need > a->cap_lines) {
        top_line_t *l = realloc(a->lines, (size_t)need * sizeof *l);
        if (!l)
            return;
        a->lines = l;
        a->cap_lines = need;
    }
    a->view.malformed = a->malformed;
    int n = top_frame(a->model, &a->view, now, a->lines, need);
    size_t pos = 0;
    char addr[32];
    for (int i = 0; i < n; i++) {
        const char *c = a->color ? color_of(a->lines[i].kind) : "";
        if (a->on_screen) {
            snprintf(addr, sizeof addr, "\033[%d;1H", i + 1);
            out_add(a, &pos, addr);
        }
        out_add(a, &pos, c);
        out_add(a, &pos, a->lines[i].text);
        if (*c)
            out_add(a, &pos, "\033[0m");
        out_add(a, &pos, a->on_screen ? "\033[K" : "\n");
    }
    if (a->on_screen)
        out_add(a, &pos, "\033[J");
    write_all(a->out, pos);
}

/* Checked decoding: liblcm's decoders trust lengths from the wire. */
static void on_status(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    app_t *a = user;
    marie_am_status_t m;
    (void)channel;
    if (marie_decode_checked(&marie_type_am_status_t, rbuf->data, rbuf->data_size, &m) < 0) {
        a->malformed++;
        return;
    }
    top_on_status(a->model, &m, marie_mono_us());
    marie_am_status_t_decode_cleanup(&m);
}

static void on_heartbeat(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    app_t *a = user;
    marie_heartbeat_t m;
    (void)channel;
    if (marie_decode_checked(&marie_type_heartbeat_t, rbuf->data, rbuf->data_size, &m) < 0) {
        a->malformed++;
        return;
    }
    top_on_heartbeat(a->model, &m, marie_mono_us());
    marie_heartbeat_t_decode_cleanup(&m);
}

static void on_tick(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    app_t *a = user;
    (void)t, (void)overruns;
    draw(a);
    if (a->once) {
        /* a snapshot is complete only if some manager answered and none is lost */
        const top_host_t *h;
        size_t nh = top_hosts(a->model, marie_mono_us(), &h);
        a->rc = nh == 0 ? MARIE_EXIT_TIMEOUT : MARIE_EXIT_OK;
        for (size_t i = 0; i < nh; i++)
            if (h[i].lost)
                a->rc = MARIE_EXIT_TIMEOUT;
        marie_loop_quit(loop);
    }
}

static void on_key(marie_loop_t *loop, int fd, short revents, void *user)
{
    app_t *a = user;
    char buf[64];
    ssize_t n = read(fd, buf, sizeof buf);
    if (n <= 0 && !(n < 0 && (errno == EINTR || errno == EAGAIN))) {
        marie_loop_remove_fd(loop, fd);     /* the terminal went away */
        marie_loop_quit(loop);
        return;
    }
    (void)revents;
    for (ssize_t i = 0; i < n; i++) {
        switch (buf[i]) {
        case 'c': case 'C': a->view.sort = TOP_SORT_CPU; break;
        case 'm': case 'M': a->view.sort = TOP_SORT_MEM; break;
        case 'n': case 'N': a->view.sort = TOP_SORT_NAME; break;
        case 'h': case 'H': a->view.sort = TOP_SORT_HOST; break;
        case 'q': case 'Q': marie_loop_quit(loop); return;
        default: break;
        }
    }
    draw(a);
}

static void on_signal(marie_loop_t *loop, int fd, short revents, void *user)
{
    app_t *a = user;
    struct signalfd_siginfo si[8];
    ssize_t n = read(fd, si, sizeof si);
    (void)revents;
    for (ssize_t i = 0; n > 0 && i < n / (ssize_t)sizeof si[0]; i++) {
        int s = (int)si[i].ssi_signo;
        if (s == SIGWINCH) {
            term_size(a);
            draw(a);
        } else if (s == SIGTSTP) {
            /* ^Z: give the terminal back as it was, stop, and come back on SIGCONT */
            screen_leave(a);
            kill(getpid(), SIGSTOP);
        } else if (s == SIGCONT) {
            if (a->interactive && !a->on_screen && screen_enter(a) == 0) {
                term_size(a);
                draw(a);
            }
        } else {
            marie_loop_quit(loop);
        }
    }
}

static void usage(FILE *f)
{
    fprintf(f, "usage: marie top [--url URL] [--interval S] [--once] [--no-color] [--sort cpu|mem|name|host]\n"
               "  the managers' and components' live status, refreshed every interval (default 1 s);\n"
               "  keys: c sort by CPU, m by memory, n by name, h by host, q quit\n"
               "  --once: wait one interval, print one snapshot and exit (3 if no manager was heard or one is lost)\n");
}

static int parse_args(app_t *a, int argc, char **argv, const char **url)
{
    static const struct option opts[] = {
        {"url", required_argument, 0, 'u'}, {"interval", required_argument, 0, 'i'}, {"once", no_argument, 0, 'o'},
        {"no-color", no_argument, 0, 'C'}, {"sort", required_argument, 0, 's'}, {"help", no_argument, 0, 'H'},
        {0, 0, 0, 0}};
    int opt;
    char *end;
    while ((opt = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        switch (opt) {
        case 'u': *url = optarg; break;
        case 'i':
            a->view.interval_s = strtod(optarg, &end);
            if (*end || !isfinite(a->view.interval_s) || a->view.interval_s < 0.05 || a->view.interval_s > 3600) {
                fprintf(stderr, "marie top: --interval %s: expected seconds between 0.05 and 3600\n", optarg);
                return -1;
            }
            break;
        case 'o': a->once = true; break;
        case 'C': a->color = false; break;
        case 's':
            if (top_sort_parse(optarg) < 0) {
                fprintf(stderr, "marie top: --sort %s: expected cpu, mem, name or host\n", optarg);
                return -1;
            }
            a->view.sort = (top_sort_t)top_sort_parse(optarg);
            break;
        case 'H': usage(stdout); exit(0);
        default: usage(stderr); return -1;
        }
    }
    if (optind != argc) {
        usage(stderr);
        return -1;
    }
    return 0;
}

static int watch_signals(app_t *a)
{
    sigset_t mask;
    sigemptyset(&mask);
    sigaddset(&mask, SIGINT);
    sigaddset(&mask, SIGTERM);
    sigaddset(&mask, SIGHUP);
    sigaddset(&mask, SIGWINCH);
    sigaddset(&mask, SIGTSTP);
    sigaddset(&mask, SIGCONT);
    sigprocmask(SIG_BLOCK, &mask, NULL);
    signal(SIGPIPE, SIG_IGN);
    int fd = signalfd(-1, &mask, SFD_CLOEXEC | SFD_NONBLOCK);
    if (fd < 0 || marie_loop_add_fd(a->loop, fd, POLLIN, on_signal, a) < 0) {
        fprintf(stderr, "marie top: signalfd: %s\n", strerror(errno));
        return -1;
    }
    return fd;
}

int main(int argc, char **argv)
{
    marie_version_exit("marie-top", argc, argv);
    app_t a = {.view = {.sort = TOP_SORT_CPU, .interval_s = 1.0}, .color = true, .rc = MARIE_EXIT_OK};
    const char *url = NULL;     /* NULL: liblcm takes LCM_DEFAULT_URL, else its default */
    if (parse_args(&a, argc, argv, &url) < 0)
        return MARIE_EXIT_USAGE;
    a.interactive = !a.once;
    if (a.interactive && (!isatty(STDIN_FILENO) || !isatty(STDOUT_FILENO))) {
        fprintf(stderr, "marie top: not a terminal (use --once for a snapshot)\n");
        return MARIE_EXIT_USAGE;
    }
    if (a.once && !isatty(STDOUT_FILENO))
        a.color = false;
    int sigfd = -1, rc = MARIE_EXIT_FAIL;
    a.model = top_create();
    a.loop = marie_loop_create();
    a.lcm = marie_bus_create(url);
    if (!a.model || !a.loop) {
        fprintf(stderr, "marie top: %s\n", strerror(errno));
        goto out;
    }
    if (!a.lcm) {
        fprintf(stderr, "marie top: cannot open the bus %s\n", url ? url : "(LCM_DEFAULT_URL or default)");
        goto out;
    }
    marie_bus_subscribe(a.lcm, MARIE_CH_AM_STATUS, on_status, &a);
    marie_bus_subscribe(a.lcm, MARIE_CH_HEARTBEAT, on_heartbeat, &a);
    int64_t period = (int64_t)llround(a.view.interval_s * 1e6);
    if ((sigfd = watch_signals(&a)) < 0 ||
        marie_loop_add_bus(a.loop, a.lcm, 1) < 0 ||
        !marie_loop_add_wall_timer(a.loop, period, on_tick, &a)) {
        fprintf(stderr, "marie top: %s\n", strerror(errno));
        goto out;
    }
    term_size(&a);
    if (a.interactive) {
        exit_app = &a;
        atexit(restore_at_exit);
        if (screen_enter(&a) < 0 || marie_loop_add_fd(a.loop, STDIN_FILENO, POLLIN, on_key, &a) < 0) {
            screen_leave(&a);
            fprintf(stderr, "marie top: terminal: %s\n", strerror(errno));
            goto out;
        }
        draw(&a);   /* at once, so the screen is never blank for an interval */
    }
    if (marie_loop_run(a.loop) < 0)
        a.rc = MARIE_EXIT_FAIL;
    screen_leave(&a);
    rc = a.rc;
out:
    exit_app = NULL;
    if (sigfd >= 0)
        close(sigfd);
    if (a.lcm)
        marie_bus_destroy(a.lcm);
    marie_loop_destroy(a.loop);
    top_destroy(a.model);
    free(a.lines);
    free(a.out);
    return rc;
}
