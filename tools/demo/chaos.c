/* chaos: marie-demo's victim draw (splitmix64: the same numbers on every platform, which
 * std::uniform_int_distribution does not promise). */
#include "tools/demo/chaos.h"

#include <sys/random.h>

#include "core/time.h"

uint64_t demo_chaos_fresh_seed(void)
{
    uint64_t s;
    if (getrandom(&s, sizeof s, GRND_NONBLOCK) == (ssize_t)sizeof s)
        return s;
    return (uint64_t)marie_mono_us() ^ (uint64_t)marie_wall_us() << 20;
}

void demo_chaos_init(demo_chaos_t *c, uint64_t seed) { *c = (demo_chaos_t){ .seed = seed, .state = seed }; }

static uint64_t next(demo_chaos_t *c)
{
    uint64_t z = (c->state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

size_t demo_chaos_pick(demo_chaos_t *c, size_t n)
{
    /* rejection keeps every index equally likely */
    uint64_t limit = UINT64_MAX - UINT64_MAX % n, r;
    do
        r = next(c);
    while (r >= limit);
    return (size_t)(r % n);
}
