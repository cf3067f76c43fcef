/* bench: one row of `make bench`'s table, as scripts/run-bench.sh gathers them: bench, metric,
 * value, unit, baseline and value / baseline (a baseline that is NaN or <= 0 is none: "-").
 * Every benchmark prints through it; values keep 6 significant digits. */
#ifndef MARIE_BENCH_H
#define MARIE_BENCH_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

static inline void bench_row(const char *bench, const char *metric, double value, const char *unit, double baseline)
{
    if (baseline > 0)
        printf("%s\t%s\t%.6g\t%s\t%.6g\t%.3f\n", bench, metric, value, unit, baseline, value / baseline);
    else
        printf("%s\t%s\t%.6g\t%s\t-\t-\n", bench, metric, value, unit);
    fflush(stdout);
}

static inline int bench_cmp_i64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return x < y ? -1 : x > y;
}

/* The p-quantile (0..1) of n samples, nearest rank; sorts v in place. NaN when n is 0. */
static inline double bench_percentile(int64_t *v, int n, double p)
{
    if (n <= 0)
        return NAN;
    qsort(v, (size_t)n, sizeof *v, bench_cmp_i64);
    return (double)v[(int)(p * (n - 1) + 0.5)];
}

#endif
