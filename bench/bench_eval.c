/* bench_eval: make bench's navigation table, marie-eval over every evaluation world with a fixed
 * seed (EVAL_GOALS goals each, 25 by default; the run is long: see docs/navigation.md). */
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

int main(void)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    const char *goals = getenv("EVAL_GOALS") ? getenv("EVAL_GOALS") : "25";
    char bin[512];
    snprintf(bin, sizeof bin, "%s/bin/marie-eval", b);
    fprintf(stderr, "bench_eval: %s --goals %s --seed 1 --tsv\n", bin, goals);
    execl(bin, bin, "--goals", goals, "--seed", "1", "--tsv", (char *)NULL);
    perror(bin);
    return 1;
}
