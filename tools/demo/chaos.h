/* chaos: which component marie-demo --chaos kills next, drawn from a seed so that a run can be
 * repeated (--seed) and a run without one draws afresh. */
#ifndef MARIE_DEMO_CHAOS_H
#define MARIE_DEMO_CHAOS_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    uint64_t seed;
    uint64_t state;     /* private */
} demo_chaos_t;

/* A seed no earlier run used (the kernel's random source; the clock if it fails). */
uint64_t demo_chaos_fresh_seed(void);
void demo_chaos_init(demo_chaos_t *c, uint64_t seed);
/* The next victim among n candidates (n > 0): an index below n, the same sequence for the
 * same seed and the same n. */
size_t demo_chaos_pick(demo_chaos_t *c, size_t n);

#ifdef __cplusplus
}
#endif
#endif
