/* bench: one row of `make bench`'s table, as scripts/run-bench.sh gathers them: bench, metric,
 * value, unit, baseline and value / baseline (a baseline that is NaN or <= 0 is none: "-").
 * Every benchmark prints through it; values keep 6 significant digits. */
#ifndef MARIE_BENCH_H
#define MARIE_BENCH_H

#include <math.h>
#include <stdio.h>

static inline void bench_row(const char *bench, const char *metric, double value, const char *unit, double baseline)
{
    if (baseline > 0)
        printf("%s\t%s\t%.6g\t%s\t%.6g\t%.3f\n", bench, metric, value, unit, baseline, value / baseline);
    else
        printf("%s\t%s\t%.6g\t%s\t-\t-\n", bench, metric, value, unit);
    fflush(stdout);
}

#endif
