/* cli: the options of a program that is not a component (an emulator, a tool), declared once in
 * a table: each a long option whose value is checked and stored where the table says, and the
 * usage text made from the same table. */
#ifndef MARIE_CLI_H
#define MARIE_CLI_H

#include <stdint.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { MARIE_CLI_STRING, MARIE_CLI_INT, MARIE_CLI_DOUBLE, MARIE_CLI_LIST } marie_cli_type_t;

/* A repeatable option (MARIE_CLI_LIST): each --name VALUE appends VALUE; more than
 * MARIE_CLI_LIST_MAX is refused like a bad value. */
#define MARIE_CLI_LIST_MAX 64
typedef struct {
    const char *items[MARIE_CLI_LIST_MAX];
    int n;
} marie_cli_list_t;

typedef struct {
    const char *name;           /* --name VALUE (or --name=VALUE) */
    marie_cli_type_t type;
    void *value;                /* where it goes: const char **, int64_t *, double *, marie_cli_list_t * */
    double min, max;            /* INT and DOUBLE: the range a value must lie in */
    const char *help;           /* the value's name, then what it is: "N the left drive's node id" */
} marie_cli_opt_t;

/* Reads argv's options into the table's values (the table ends with a NULL name; what is not
 * given keeps the value it had). Returns -1 to go on, with optind at the first operand; else the
 * exit status: 0 after --help (the usage on stdout), 2 after an unknown option or a bad value
 * ("PROG: --NAME: expected ..., got 'X'" and the usage on stderr). The strings stored point into
 * argv. */
int marie_cli_parse(const char *prog, const marie_cli_opt_t *opts, int argc, char **argv);
void marie_cli_usage(const char *prog, const marie_cli_opt_t *opts, FILE *out);

#ifdef __cplusplus
}
#endif
#endif
