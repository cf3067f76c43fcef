/* marie up, down, start/stop/restart/pause/resume, move, ps and logs. */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "core/buf.h"
#include "core/clear.h"
#include "core/config.h"
#include "core/expand.h"
#include "core/file.h"
#include "core/time.h"
#include "managers/am_settings.h"
#include "proto/am_proto.h"
#include "managers/marie_cli.h"
#include "managers/progcheck.h"

/* ---------------------------------------------------------------- commands */

#define MAX_FOLLOWED 256

/* Every component's program, on whichever host it runs, is checked here: the programs are
 * installed alike on every host (deploy/), and a bad entry must stop `up` before any start. */
static int check_programs(const marie_system_t *sys, marie_errors_t *errs)
{
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    self[n > 0 ? n : 0] = 0;
    char *slash = strrchr(self, '/');
    if (slash)
        *slash = 0;
    char *cache = marie_progcheck_default_cache();
    marie_progcheck_t *p = marie_progcheck_create(self[0] ? self : NULL, cache);
    free(cache);
    int rc = p ? marie_progcheck_system(p, sys, NULL, NULL, errs) : -1;
    marie_progcheck_destroy(p);
    return rc;
}

/* The file's text with the launch arguments (-a name=value) in its ${name}s; NULL after saying why. */
static char *read_with_args(const char *file, char **args, size_t nargs, size_t *len)
{
    char *text = marie_file_read(file, MARIE_AM_SYSTEM_MAX_BYTES, len), why[256];
    if (!text) {
        fprintf(stderr, "marie: %s: %s\n", file, strerror(errno));
        return NULL;
    }
    if (!nargs)
        return text;
    int *used = calloc(nargs, sizeof *used);
    char *filled = used ? marie_expand_args(text, args, nargs, used, why, sizeof why) : NULL;
    free(text);
    for (size_t i = 0; filled && i < nargs; i++)
        if (!used[i]) {
            snprintf(why, sizeof why, "launch argument '%.*s' is not used in %s (no ${%.*s} in it)",
                     (int)strcspn(args[i], "="), args[i], file, (int)strcspn(args[i], "="), args[i]);
            MARIE_CLEAR(filled, free);
        }
    free(used);
    if (!filled)
        fprintf(stderr, "marie: %s\n", why);
    *len = filled ? strlen(filled) : 0;
    return filled;
}

/* "NAME is up on N host(s)", then what each manager changed of a system already running. */
static void print_up(const cli_t *cli, const char *name)
{
    printf("%s is up on %d host(s)\n", name, cli->nreplies);
    for (int i = 0; i < cli->nreplies; i++)
        if (strcmp(cli->replies[i].reason, "ok") != 0)
            printf("  %s: %s\n", cli->replies[i].host, cli->replies[i].reason);
}

int cmd_up(cli_t *cli, int argc, char **argv)
{
    static const struct option opts[] = {{"profile", required_argument, 0, 'p'}, {"no-wait", no_argument, 0, 'n'},
                                         {"wait-timeout", required_argument, 0, 'w'}, {"arg", required_argument, 0, 'a'},
                                         {0, 0, 0, 0}};
    const char *profile = NULL;
    bool wait = true;
    double wait_s = 30;
    char **args = calloc((size_t)argc + 1, sizeof *args);
    size_t nargs = 0;
    int opt;
    optind = 1;
    while (args && (opt = getopt_long(argc, argv, "p:a:", opts, NULL)) != -1) {
        if (opt == 'p') profile = optarg;
        else if (opt == 'n') wait = false;
        else if (opt == 'w') wait_s = atof(optarg);
        else if (opt == 'a') args[nargs++] = optarg;
        else { free(args); return MARIE_EXIT_USAGE; }
    }
    if (!args || optind != argc - 1) {
        fprintf(stderr, "usage: marie up FILE [--profile P] [-a NAME=VALUE]... [--no-wait]\n");
        free(args);
        return MARIE_EXIT_USAGE;
    }
    const char *file = argv[optind];
    size_t text_len;
    char *text = read_with_args(file, args, nargs, &text_len);
    free(args);
    if (!text)
        return MARIE_EXIT_USAGE;
    /* Validate here first: a bad file never reaches a manager. */
    marie_errors_t errs = {0};
    marie_system_t *sys = marie_system_load_text(file, text, text_len, profile, &errs);
    marie_am_settings_t set;
    if (sys && (marie_am_check_system(sys, &set, &errs) < 0 || check_programs(sys, &errs) < 0)) {
        MARIE_CLEAR(sys, marie_system_destroy);
    }
    if (!sys) {
        marie_errors_print(&errs, stderr);
        marie_errors_clear(&errs);
        free(text);
        return interrupted ? interrupted_status() : MARIE_EXIT_USAGE;
    }
    for (size_t i = 0; i < sys->nhosts; i++)
        expect_host(cli, sys->hosts[i]);
    char *abs = realpath(file, NULL);
    int rc = text ? cli_open(cli) : -1;
    if (rc == 0)
        rc = send_order(cli, MARIE_AM_ORDER_T_OP_UP, NULL, 0, profile, abs ? abs : file, text);
    else
        rc = MARIE_EXIT_FAIL;
    if (rc == MARIE_EXIT_OK && wait)
        rc = wait_states(cli, NULL, 0, true, wait_s);
    if (cli->json)
        print_replies_json(cli, rc);
    else if (rc == MARIE_EXIT_OK)
        print_up(cli, sys->name ? sys->name : file);
    free(abs);
    free(text);
    marie_system_destroy(sys);
    return rc;
}

int cmd_simple(cli_t *cli, int op, int argc, char **argv)
{
    static const struct option opts[] = {{"wait", no_argument, 0, 'w'}, {"no-wait", no_argument, 0, 'n'},
                                         {"wait-timeout", required_argument, 0, 't'}, {0, 0, 0, 0}};
    bool wait = op == MARIE_AM_ORDER_T_OP_DOWN;
    double wait_s = 30;
    int opt;
    optind = 1;
    while ((opt = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        if (opt == 'w') wait = true;
        else if (opt == 'n') wait = false;
        else if (opt == 't') wait_s = atof(optarg);
        else return MARIE_EXIT_USAGE;
    }
    char **targets = argv + optind;
    int ntargets = argc - optind;
    if ((op == MARIE_AM_ORDER_T_OP_DOWN) != (ntargets == 0)) {
        fprintf(stderr, op == MARIE_AM_ORDER_T_OP_DOWN ? "usage: marie down\n"
                                                       : "usage: marie %s NAME|GROUP...\n", marie_am_op_name(op));
        return MARIE_EXIT_USAGE;
    }
    if (cli_open(cli) < 0)
        return MARIE_EXIT_FAIL;
    int rc = send_order(cli, op, targets, ntargets, NULL, NULL, NULL);
    if (rc == MARIE_EXIT_OK && wait) {
        bool running = op == MARIE_AM_ORDER_T_OP_START || op == MARIE_AM_ORDER_T_OP_RESTART ||
                       op == MARIE_AM_ORDER_T_OP_RESUME;
        if (op == MARIE_AM_ORDER_T_OP_RESTART)
            pump(cli, 0.1, NULL);    /* let the old process go before waiting for running */
        rc = wait_states(cli, targets, ntargets, running, wait_s);
    }
    int affected = 0;
    for (int i = 0; i < cli->nreplies; i++)
        affected += cli->replies[i].affected;
    if (cli->json)
        print_replies_json(cli, rc);
    else if (rc == MARIE_EXIT_OK)
        printf("%s: %d component(s)\n", marie_am_op_name(op), affected);
    return rc;
}

int cmd_move(cli_t *cli, int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: marie move NAME HOST\n");
        return MARIE_EXIT_USAGE;
    }
    if (cli_open(cli) < 0)
        return MARIE_EXIT_FAIL;
    int rc = send_order(cli, MARIE_AM_ORDER_T_OP_MOVE, &argv[1], 1, argv[2], NULL, NULL);
    if (cli->json)
        print_replies_json(cli, rc);
    else if (rc == MARIE_EXIT_OK)
        printf("%s moves to %s\n", argv[1], argv[2]);
    return rc;
}

static void fmt_uptime(int64_t us, char *buf, size_t len)
{
    int64_t s = us / 1000000;
    if (us <= 0)
        snprintf(buf, len, "-");
    else if (s < 60)
        snprintf(buf, len, "%llds", (long long)s);
    else if (s < 3600)
        snprintf(buf, len, "%lldm%02llds", (long long)(s / 60), (long long)(s % 60));
    else
        snprintf(buf, len, "%lldh%02lldm", (long long)(s / 3600), (long long)(s / 60 % 60));
}

static void fmt_bytes(int64_t b, char *buf, size_t len)
{
    if (b <= 0)
        snprintf(buf, len, "-");
    else if (b < 10 << 20)
        snprintf(buf, len, "%.1fM", (double)b / (1 << 20));
    else
        snprintf(buf, len, "%lldM", (long long)(b >> 20));
}

/* Automatic placement: who leads, and each manager's last decision. */
static void print_placement(cli_t *cli, int64_t lost_us)
{
    int64_t now = marie_mono_us();
    bool head = false;
    for (int i = 0; i < cli->nexpect; i++) {
        host_t *h = host_get(cli, cli->expect[i], false);
        if (!h || !h->st || now - h->recv_mono > lost_us || !h->st->balance_leader[0])
            continue;
        if (!head)
            printf("\nplacement: %s leads (term %lld)\n", h->st->balance_leader, (long long)h->st->balance_term);
        head = true;
        if (h->st->balance_last[0])
            printf("  last decision by %s: %s\n", h->name, h->st->balance_last);
    }
}

/* Print the table; a host not heard from for lost_us (or never) is lost. Returns how many. */
static int print_ps(cli_t *cli, int64_t lost_us)
{
    for (int i = 0; i < cli->nhosts; i++)
        expect_host(cli, cli->hosts[i].name);
    int64_t now = marie_mono_us();
    int lost = 0;
    if (cli->json)
        printf("{\"hosts\":[");
    else
        printf("%-12s %-20s %-9s %7s %8s %4s %6s %7s  %s\n", "HOST", "COMPONENT", "STATE", "PID", "UPTIME",
               "RST", "CPU%", "RSS", "LIMITS");
    for (int i = 0; i < cli->nexpect; i++) {
        host_t *h = host_get(cli, cli->expect[i], false);
        bool is_lost = !h || !h->st || now - h->recv_mono > lost_us;
        lost += is_lost;
        if (cli->json) {
            printf("%s{\"host\":", i ? "," : "");
            marie_json_fputs(stdout, cli->expect[i]);
            if (is_lost) {
                printf(",\"lost\":true,\"components\":[]}");
                continue;
            }
            marie_am_status_t *st = h->st;
            printf(",\"lost\":false,\"system\":");
            marie_json_fputs(stdout, st->system);
            printf(",\"profile\":");
            marie_json_fputs(stdout, st->profile);
            printf(",\"load\":[%.2f,%.2f,%.2f],\"ncpu\":%d,\"am_pid\":%d,\"am_cpu\":%.2f,\"am_rss\":%lld,"
                   "\"orders_refused\":%lld,\"clock_offset_us\":%lld,",
                   st->load1, st->load5, st->load15, st->ncpu, st->pid, st->am_cpu, (long long)st->am_rss,
                   (long long)st->orders_refused, (long long)(st->utime - h->recv_wall));
            printf("\"balance_term\":%lld,\"balance_leader\":", (long long)st->balance_term);
            marie_json_fputs(stdout, st->balance_leader);
            printf(",\"balance_last\":");
            marie_json_fputs(stdout, st->balance_last);
            printf(",\"components\":[");
            for (int k = 0; k < st->ncomponents; k++) {
                marie_am_component_status_t *c = &st->components[k];
                printf("%s{\"name\":", k ? "," : "");
                marie_json_fputs(stdout, c->name);
                printf(",\"group\":");
                marie_json_fputs(stdout, c->group);
                printf(",\"state\":");
                marie_json_fputs(stdout, c->state);
                printf(",\"comp_state\":%d,\"pid\":%d,\"uptime_us\":%lld,\"restarts\":%d,\"last_exit\":%d,"
                       "\"cpu\":%.2f,\"rss\":%lld,\"heartbeat_age_us\":%lld,\"log_drops\":%lld,\"config_hash\":",
                       c->comp_state, c->pid, (long long)c->uptime_us, c->restarts, c->last_exit, c->cpu,
                       (long long)c->rss, (long long)c->heartbeat_age_us, (long long)c->log_drops);
                marie_json_fputs(stdout, c->config_hash);
                printf(",\"limits\":");
                marie_json_fputs(stdout, c->limits);
                printf(",\"limit_breaches\":%d}", c->limit_breaches);
            }
            printf("]}");
            continue;
        }
        if (is_lost) {
            printf("%-12s %-20s %-9s\n", cli->expect[i], "-", "lost");
            continue;
        }
        marie_am_status_t *st = h->st;
        if (st->ncomponents == 0)
            printf("%-12s %-20s %-9s\n", st->host, "-", st->system[0] ? "idle" : "no-system");
        for (int k = 0; k < st->ncomponents; k++) {
            marie_am_component_status_t *c = &st->components[k];
            char up[32], rss[32], pid[16], cpu[16];
            fmt_uptime(c->uptime_us, up, sizeof up);
            fmt_bytes(c->rss, rss, sizeof rss);
            snprintf(pid, sizeof pid, c->pid ? "%d" : "-", c->pid);
            snprintf(cpu, sizeof cpu, c->pid ? "%.1f" : "-", c->cpu);
            char lim[200] = "";
            if (c->limits[0])
                snprintf(lim, sizeof lim, "  %s%s", c->limits, c->limit_breaches ? ", breached " : "");
            if (c->limit_breaches)
                snprintf(lim + strlen(lim), sizeof lim - strlen(lim), "%d", c->limit_breaches);
            printf("%-12s %-20s %-9s %7s %8s %4d %6s %7s%s\n", st->host, c->name, c->state, pid, up, c->restarts,
                   cpu, rss, lim);
        }
    }
    if (cli->json) {
        printf("]}\n");
    } else if (cli->nexpect > 0) {
        printf("\n%-12s %-6s %-7s %-7s %-8s %s\n", "HOST", "LOAD", "AM-CPU%", "AM-RSS", "REFUSED", "SYSTEM");
        for (int i = 0; i < cli->nexpect; i++) {
            host_t *h = host_get(cli, cli->expect[i], false);
            if (!h || !h->st || now - h->recv_mono > lost_us) {
                printf("%-12s %-6s\n", cli->expect[i], "lost");
                continue;
            }
            char rss[32];
            fmt_bytes(h->st->am_rss, rss, sizeof rss);
            printf("%-12s %-6.2f %-7.1f %-7s %-8lld %s%s%s%s\n", h->name, h->st->load1, h->st->am_cpu, rss,
                   (long long)h->st->orders_refused, h->st->system[0] ? h->st->system : "-",
                   h->st->profile[0] ? " (" : "", h->st->profile, h->st->profile[0] ? ")" : "");
        }
        print_placement(cli, lost_us);
    }
    fflush(stdout);
    return lost;
}

int cmd_ps(cli_t *cli, int argc, char **argv)
{
    static const struct option opts[] = {{"window", required_argument, 0, 'w'}, {"watch", no_argument, 0, 'W'},
                                         {0, 0, 0, 0}};
    double window = 1.2;
    bool watch = false;
    int opt;
    optind = 1;
    while ((opt = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        if (opt == 'w') window = atof(optarg);
        else if (opt == 'W') watch = true;
        else return MARIE_EXIT_USAGE;
    }
    if (optind != argc) {
        fprintf(stderr, "usage: marie ps [--window S] [--watch]\n");
        return MARIE_EXIT_USAGE;
    }
    if (cli_open(cli) < 0 || request_status(cli) < 0)
        return MARIE_EXIT_FAIL;
    /* Every manager answers the request at once (or, past its rate limit or too old to know
     * it, reports within its 2 Hz period): a host silent for the whole window is lost. Once
     * every host a status names has reported, the table is complete. */
    pump(cli, window, watch ? NULL : all_hosts_heard);
    if (watch) {
        /* every second; a host silent for more than 2 s is lost */
        while (!interrupted) {
            if (!cli->json)
                printf("\033[H\033[J");
            print_ps(cli, 2000000);
            pump(cli, 1.0, NULL);
        }
        return MARIE_EXIT_OK;
    }
    int lost = print_ps(cli, INT64_MAX / 2);
    if (cli->nexpect == 0) {
        fprintf(stderr, "marie: no manager heard within %.1f s\n", window);
        return MARIE_EXIT_TIMEOUT;
    }
    return lost ? MARIE_EXIT_TIMEOUT : MARIE_EXIT_OK;
}

static bool logs_quiet(cli_t *cli)
{
    return all_replied(cli) && marie_mono_us() - cli->last_log_mono > 300000;
}

/* -f: the components the names and groups asked for stand for, from the managers' status. */
static int resolve_followed(cli_t *cli)
{
    if (!(cli->followed = calloc(MAX_FOLLOWED, sizeof *cli->followed)))
        return -1;
    if (request_status(cli) == 0)
        pump(cli, cli->timeout_s, all_hosts_heard);
    for (int k = 0; k < cli->nlog_names; k++) {
        bool found = false;
        for (int h = 0; h < cli->nhosts; h++)
            for (int i = 0; cli->hosts[h].st && i < cli->hosts[h].st->ncomponents; i++) {
                const marie_am_component_status_t *c = &cli->hosts[h].st->components[i];
                if ((strcmp(c->name, cli->log_names[k]) == 0 || strcmp(c->group, cli->log_names[k]) == 0) &&
                    cli->nfollowed < MAX_FOLLOWED) {
                    snprintf(cli->followed[cli->nfollowed++], sizeof *cli->followed, "%s", c->name);
                    found = true;
                }
            }
        if (!found && cli->nfollowed < MAX_FOLLOWED)   /* not running yet: its own name */
            snprintf(cli->followed[cli->nfollowed++], sizeof *cli->followed, "%s", cli->log_names[k]);
    }
    return 0;
}

int cmd_logs(cli_t *cli, int argc, char **argv)
{
    int n = 20, opt;
    bool n_given = false;
    optind = 1;
    while ((opt = getopt(argc, argv, "fn:")) != -1) {
        if (opt == 'f') cli->follow = true;
        else if (opt == 'n') { n = atoi(optarg); n_given = true; }
        else return MARIE_EXIT_USAGE;
    }
    if (optind >= argc) {
        fprintf(stderr, "usage: marie logs [-f] [-n N] NAME|GROUP...\n");
        return MARIE_EXIT_USAGE;
    }
    cli->log_names = argv + optind;
    cli->nlog_names = argc - optind;
    if (cli_open(cli) < 0 || (cli->follow && resolve_followed(cli) < 0))
        return MARIE_EXIT_FAIL;
    int rc = MARIE_EXIT_OK;
    if (n > 0) {
        char arg[32];
        snprintf(arg, sizeof arg, "%d", n);
        if (load_key(cli) < 0) {
            fprintf(stderr, "marie: the last lines are read by the managers, and asking them is an order signed "
                            "with the key (--key FILE, MARIE_KEY or the system file's auth.key_file)%s\n",
                    cli->follow ? "; following new lines only" : n_given ? "" : "; marie logs -f NAME follows new lines without one");
            if (!cli->follow)
                return MARIE_EXIT_AUTH;
        } else {
            /* the answers carry the order's seq (on_log matches it) */
            cli->last_log_mono = marie_mono_us();
            rc = send_order(cli, MARIE_AM_ORDER_T_OP_TAIL, cli->log_names, cli->nlog_names, arg, NULL, NULL);
            pump(cli, 0.5, logs_quiet);
        }
    }
    if (cli->follow && rc == MARIE_EXIT_OK) {
        while (!interrupted)
            marie_loop_run_once(cli->loop, 200);
    }
    free(cli->followed);
    return rc;
}
