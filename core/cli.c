/* cli: a program's options from one table (see cli.h). */
#include "core/cli.h"

#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* getopt_long returns these for the table's options: above any character it returns itself. */
#define OPT_HELP 256
#define OPT_FIRST 257

void marie_cli_usage(const char *prog, const marie_cli_opt_t *opts, FILE *out)
{
    fprintf(out, "usage: %s [OPTION VALUE]...\n", prog);
    for (const marie_cli_opt_t *o = opts; o->name; o++)
        fprintf(out, "  --%-18s %s\n", o->name, o->help ? o->help : "");
    fprintf(out, "  --%-18s this text\n", "help");
}

/* The option's value from text: 0, or -1 with the reason on stderr. */
static int store(const char *prog, const marie_cli_opt_t *o, const char *text)
{
    if (o->type == MARIE_CLI_STRING) {
        *(const char **)o->value = text;
        return 0;
    }
    if (o->type == MARIE_CLI_LIST) {
        marie_cli_list_t *l = o->value;
        if (l->n == MARIE_CLI_LIST_MAX) {
            fprintf(stderr, "%s: --%s: at most %d of them\n", prog, o->name, MARIE_CLI_LIST_MAX);
            return -1;
        }
        l->items[l->n++] = text;
        return 0;
    }
    char *end;
    errno = 0;
    double v = o->type == MARIE_CLI_INT ? (double)strtoll(text, &end, 0) : strtod(text, &end);
    if (!text[0] || *end || errno || !isfinite(v) || v < o->min || v > o->max) {
        fprintf(stderr, "%s: --%s: expected %s from %g to %g, got '%s'\n", prog, o->name,
                o->type == MARIE_CLI_INT ? "a whole number" : "a number", o->min, o->max, text);
        return -1;
    }
    if (o->type == MARIE_CLI_INT)
        *(int64_t *)o->value = (int64_t)v;
    else
        *(double *)o->value = v;
    return 0;
}

int marie_cli_parse(const char *prog, const marie_cli_opt_t *opts, int argc, char **argv)
{
    size_t n = 0;
    while (opts[n].name)
        n++;
    struct option *lo = calloc(n + 2, sizeof *lo);
    if (!lo) {
        fprintf(stderr, "%s: %s\n", prog, strerror(errno));
        return 1;
    }
    for (size_t i = 0; i < n; i++)
        lo[i] = (struct option){ opts[i].name, required_argument, NULL, OPT_FIRST + (int)i };
    lo[n] = (struct option){ "help", no_argument, NULL, OPT_HELP };
    int ch, rc = -1;
    optind = 1;
    while (rc < 0 && (ch = getopt_long(argc, argv, "", lo, NULL)) != -1) {
        if (ch == OPT_HELP) {
            marie_cli_usage(prog, opts, stdout);
            rc = 0;
        } else if (ch < OPT_FIRST || ch >= OPT_FIRST + (int)n || store(prog, &opts[ch - OPT_FIRST], optarg) < 0) {
            marie_cli_usage(prog, opts, stderr);
            rc = 2;
        }
    }
    free(lo);
    return rc;
}
