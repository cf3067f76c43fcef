/* version: marie's version, printed by every program's --version (and in marie.pc). */
#ifndef MARIE_VERSION_H
#define MARIE_VERSION_H

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MARIE_VERSION "0.1.0"

/* A program's first line: `PROG --version` prints "NAME (marie VERSION)" and exits 0. */
static inline void marie_version_exit(const char *name, int argc, char **argv)
{
    if (argc > 1 && strcmp(argv[1], "--version") == 0) {
        printf("%s (marie %s)\n", name, MARIE_VERSION);
        exit(0);
    }
}

#endif
