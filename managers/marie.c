/* marie: the command line that drives the application managers (marie-am) of every host. */
#include <errno.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "core/config.h"
#include "proto/am_proto.h"
#include "managers/marie_cli.h"
#include "core/auth.h"
#include "core/version.h"

volatile sig_atomic_t interrupted;      /* the signal that asked marie to stop */
static void on_sigint(int s) { interrupted = s; }
static int parse_interrupted(void) { return interrupted != 0; }
int interrupted_status(void) { return interrupted == SIGINT ? 130 : MARIE_EXIT_FAIL; }

static void usage(FILE *out)
{
    fprintf(out,
            "usage: marie [--json] [--url URL] [--key FILE] [--timeout S] COMMAND [ARGS]\n"
            "  up FILE [--profile P] [-a NAME=VALUE]... [--no-wait]\n"
            "                                      load a system on every host and start it;\n"
            "                                      -a fills ${NAME} in the file (launch arguments)\n"
            "  down [--no-wait]                    stop every component (reverse dependency order)\n"
            "  ps [--window S] [--watch]           components of every host (--watch: every second)\n"
            "  start|stop|restart NAME|GROUP... [--wait]\n"
            "  pause|resume NAME|GROUP...          lifecycle pause/resume\n"
            "  logs [-f] [-n N] NAME|GROUP...      last lines of components' output (-f: follow)\n"
            "  move NAME HOST                      run a component on another host\n"
            "  doctor                              check the bus: route, TTL, buffers, clock skew\n"
            "  hash FILE [--profile A|--base [--profile B|--base]]  configuration hashes; with\n"
            "                                      two, which components are configured the same\n"
            "                                      (--base: the file without a profile)\n"
            "  keygen FILE                         write a new order key (mode 0600)\n"
            "  topic list|echo|hz|pub ...          the bus's channels and messages (marie topic --help)\n"
            "  param list|get|set COMPONENT ...    a running component's parameters\n"
            "  X ...                               runs marie-X (next to marie, or on PATH)\n"
            "exit status: 0 ok, 1 failure, 2 usage or system file error, 3 timeout or host\n"
            "unreachable, 4 key problem or order refused as unauthenticated\n");
}


/* ---------------------------------------------------------------- dispatch */

static int run_external(const char *cmd, int argc, char **argv)
{
    char name[256];
    snprintf(name, sizeof name, "marie-%s", cmd);
    if (strchr(cmd, '/')) {
        fprintf(stderr, "marie: unknown command '%s'\n", cmd);
        return MARIE_EXIT_USAGE;
    }
    char self[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", self, sizeof self - 1);
    argv[0] = name;
    if (n > 0) {
        self[n] = 0;
        char *slash = strrchr(self, '/');
        if (slash) {
            char path[PATH_MAX + 256];
            snprintf(path, sizeof path, "%.*s/%s", (int)(slash - self), self, name);
            if (access(path, X_OK) == 0) {
                execv(path, argv);
                fprintf(stderr, "marie: %s: %s\n", path, strerror(errno));
                return MARIE_EXIT_FAIL;
            }
        }
    }
    execvp(name, argv);
    if (errno == ENOENT) {
        fprintf(stderr, "marie: unknown command '%s' (no %s next to marie or on PATH)\n", cmd, name);
        usage(stderr);
        return MARIE_EXIT_USAGE;
    }
    fprintf(stderr, "marie: %s: %s\n", name, strerror(errno));
    return MARIE_EXIT_FAIL;
}

int main(int argc, char **argv)
{
    marie_version_exit("marie", argc, argv);
    cli_t cli = {0};
    cli.timeout_s = 3;
    cli.url = getenv("LCM_DEFAULT_URL") ? getenv("LCM_DEFAULT_URL") : marie_default_url();
    int i = 1;
    for (; i < argc && argv[i][0] == '-'; i++) {
        const char *a = argv[i];
        if (strcmp(a, "--json") == 0) {
            cli.json = true;
        } else if (strcmp(a, "--url") == 0 && i + 1 < argc) {
            cli.url = argv[++i];
        } else if (strcmp(a, "--key") == 0 && i + 1 < argc) {
            cli.key_override = argv[++i];
        } else if (strcmp(a, "--timeout") == 0 && i + 1 < argc) {
            cli.timeout_s = atof(argv[++i]);
        } else if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            usage(stdout);
            return 0;
        } else {
            fprintf(stderr, "marie: unknown option %s\n", a);
            usage(stderr);
            return MARIE_EXIT_USAGE;
        }
    }
    if (i >= argc) {
        usage(stderr);
        return MARIE_EXIT_USAGE;
    }
    const char *cmd = argv[i];
    int sargc = argc - i;
    char **sargv = argv + i;
    /* --json may also follow the command (marie-X, run for `marie X`, reads its own) */
    bool own_json = strcmp(cmd, "logs") == 0 || strcmp(cmd, "topic") == 0 || strcmp(cmd, "param") == 0;
    for (int k = 1; k < sargc; k++)
        if (strcmp(sargv[k], "--json") == 0 && !own_json) {
            cli.json = true;
            memmove(&sargv[k], &sargv[k + 1], (size_t)(sargc - k) * sizeof *sargv);
            sargc--;
            k--;
        }
    marie_am_sender(cli.sender, sizeof cli.sender);
    struct sigaction sa = {.sa_handler = on_sigint};
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
    signal(SIGPIPE, SIG_IGN);
    marie_config_set_interrupt(parse_interrupted);

    int rc;
    if (strcmp(cmd, "help") == 0) {
        usage(stdout);
        return 0;
    } else if (strcmp(cmd, "up") == 0) {
        rc = cmd_up(&cli, sargc, sargv);
    } else if (strcmp(cmd, "down") == 0) {
        rc = cmd_simple(&cli, MARIE_AM_ORDER_T_OP_DOWN, sargc, sargv);
    } else if (strcmp(cmd, "ps") == 0) {
        rc = cmd_ps(&cli, sargc, sargv);
    } else if (marie_am_op_parse(cmd) >= MARIE_AM_ORDER_T_OP_START && marie_am_op_parse(cmd) <= MARIE_AM_ORDER_T_OP_RESUME) {
        rc = cmd_simple(&cli, marie_am_op_parse(cmd), sargc, sargv);
    } else if (strcmp(cmd, "logs") == 0) {
        rc = cmd_logs(&cli, sargc, sargv);
    } else if (strcmp(cmd, "move") == 0) {
        rc = cmd_move(&cli, sargc, sargv);
    } else if (strcmp(cmd, "doctor") == 0) {
        rc = cmd_doctor(&cli, sargc, sargv);
    } else if (strcmp(cmd, "hash") == 0) {
        rc = cmd_hash(&cli, sargc, sargv);
    } else if (strcmp(cmd, "keygen") == 0) {
        if (sargc != 2) {
            fprintf(stderr, "usage: marie keygen FILE\n");
            return MARIE_EXIT_USAGE;
        }
        int r = marie_auth_keygen(sargv[1]);
        if (r < 0)
            fprintf(stderr, "marie: keygen %s: %s\n", sargv[1], strerror(errno));
        rc = r < 0 ? MARIE_EXIT_FAIL : MARIE_EXIT_OK;
    } else {
        return run_external(cmd, sargc, sargv);
    }
    for (int k = 0; k < cli.nhosts; k++)
        if (cli.hosts[k].st)
            marie_am_status_t_destroy(cli.hosts[k].st);
    marie_auth_destroy(cli.auth);
    marie_loop_destroy(cli.loop);
    if (cli.lcm)
        marie_bus_destroy(cli.lcm);
    return rc;
}
