/* bench_config: system file loading speed (MB/s) on a generated 10 MB file against a 1 MB one;
 * loading is linear when the ratio stays near 1. Process CPU time, not wall time: the figure is
 * the loader's work, not how busy the machine was (on a quiet machine the two agree). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "bench/bench.h"
#include "core/config.h"

/* Components that each depend on the one before, with ports and parameters: every lookup the
 * loader does (keys, components by name, dependencies) scales with the file. */
static char *generate(size_t bytes, size_t *len)
{
    size_t cap = bytes + 4096;
    char *t = malloc(cap);
    if (!t)
        return NULL;
    *len = (size_t)snprintf(t, cap, "system: big\nhosts: [h1]\ncomponents:\n  c0: {exec: marie-example-producer}\n");
    for (int i = 1; *len < bytes; i++)
        *len += (size_t)snprintf(t + *len, cap - *len,
                                 "  c%d:\n    exec: marie-example-producer\n    host: h1\n    depends: [c%d]\n"
                                 "    ports: {out: CH_%d}\n    params: {rate_hz: 10, label: comp%d}\n",
                                 i, i - 1, i, i);
    return t;
}

static double cpu_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* Best of `runs` loads of a `mb` MB file, in MB/s; -1 on failure. */
static double load_rate(double mb, int runs)
{
    size_t len;
    char *text = generate((size_t)(mb * 1e6), &len);
    char path[] = "/tmp/marie-bench-config.XXXXXX";
    int fd = text ? mkstemp(path) : -1;
    if (fd < 0 || write(fd, text, len) != (ssize_t)len) {
        free(text);
        return -1;
    }
    close(fd);
    free(text);
    double best = 1e9;
    for (int i = 0; i < runs; i++) {
        marie_errors_t e = {0};
        double t0 = cpu_s();
        marie_system_t *sys = marie_system_load(path, NULL, &e);
        double dt = cpu_s() - t0;
        if (!sys) {
            marie_errors_print(&e, stderr);
            marie_errors_clear(&e);
            unlink(path);
            return -1;
        }
        marie_system_destroy(sys);
        best = dt < best ? dt : best;
    }
    unlink(path);
    return len / 1e6 / best;
}

int main(void)
{
    double base = load_rate(1, 3), big = load_rate(10, 2);     /* the best of a few runs each */
    if (base <= 0 || big <= 0)
        return 1;
    bench_row("bench_config", "load_1MB", base, "MB/s-cpu", NAN);
    bench_row("bench_config", "load_10MB", big, "MB/s-cpu", base);
    return 0;
}
