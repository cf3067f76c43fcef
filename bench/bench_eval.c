/* bench_eval: make bench-full's navigation table: marie-eval over the evaluation set with a fixed
 * seed: the eight evaluation worlds, maps no one here drew (nav2's depot, warehouse and TurtleBot3
 * sandbox), and the kinds of world that are not the map: boxes and wall segments the map lacks,
 * the robot carried away, maps at 0.2 m cells. EVAL_GOALS goals per world (25 by default) on the
 * first three runs, EVAL_KIND_GOALS (10) on the others; the run is long: see docs/navigation.md. */
#include <signal.h>
#include <spawn.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

extern char **environ;

/* A signal for this bench is for the marie-eval it runs (which stops its programs). */
static volatile pid_t child;
static volatile sig_atomic_t stop;

static void forward(int signo)
{
    stop = 1;
    if (child > 0)
        kill(child, signo);
}

#define DEPOT "tests/data/nav2/depot.yaml"
#define NAV2 DEPOT ",tests/data/nav2/warehouse.yaml"
#define TB3 "tests/data/nav2/tb3_sandbox.yaml", "--radius", "0.12", "--clearance", "0.05", "--track", "0.16", \
    "--wheel", "0.033"

int main(void)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    const char *g = getenv("EVAL_GOALS") ? getenv("EVAL_GOALS") : "25";
    const char *k = getenv("EVAL_KIND_GOALS") ? getenv("EVAL_KIND_GOALS") : "10";
    char bin[512];
    snprintf(bin, sizeof bin, "%s/bin/marie-eval", b);
    /* Each run: its options, NULL-terminated; "G" and "K" stand for the goal counts. */
    static const char *const runs[][16] = {
        { "G", NULL },
        { "G", "--map", NAV2, NULL },
        { "G", "--map", TB3, NULL },
        { "K", "--world", "office,cluttered", "--map", DEPOT, "--boxes", "6", NULL },
        { "K", "--world", "office,warehouse", "--map", DEPOT, "--walls", "4", NULL },
        { "K", "--world", "office,cluttered", "--map", DEPOT, "--kidnap", "2", NULL },
        { "K", "--world", "office,warehouse,hall", "--map", DEPOT, "--coarse", "0.2", NULL },
    };
    int status = 0;
    signal(SIGTERM, forward);
    signal(SIGINT, forward);
    for (size_t r = 0; r < sizeof runs / sizeof runs[0] && !stop; r++) {
        const char *argv[32] = { bin, "--goals", runs[r][0][0] == 'G' ? g : k, "--seed", "1", "--format", "tsv" };
        int n = 7;
        for (int i = 1; runs[r][i]; i++)
            argv[n++] = runs[r][i];
        argv[n] = NULL;
        fprintf(stderr, "bench_eval:");
        for (int i = 0; i < n; i++)
            fprintf(stderr, " %s", argv[i]);
        fprintf(stderr, "\n");
        fflush(stdout);
        pid_t pid;
        int st = 0;
        int rc = posix_spawn(&pid, bin, NULL, NULL, (char *const *)argv, environ);
        child = rc == 0 ? pid : -1;
        while (rc == 0 && waitpid(pid, &st, 0) < 0 && errno == EINTR)
            ;
        child = -1;
        if (rc != 0 || !WIFEXITED(st) || WEXITSTATUS(st) != 0) {
            fprintf(stderr, "bench_eval: run %zu failed\n", r + 1);
            status = 1;
        }
    }
    return status;
}
