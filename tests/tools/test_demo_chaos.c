/* test_demo_chaos: marie-demo --chaos draws its victims from a seed: a run without --seed
 * draws afresh (the same order every run hid every order but one), a run with the seed of
 * an earlier one draws the same victims, and every candidate can be drawn. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <string.h>
#include <cmocka.h>

#include "tools/demo/chaos.h"

#define DRAWS 12
#define CANDIDATES 9        /* the demo's components other than the simulator */

static void draw(uint64_t seed, size_t *out)
{
    demo_chaos_t c;
    demo_chaos_init(&c, seed);
    for (int i = 0; i < DRAWS; i++)
        out[i] = demo_chaos_pick(&c, CANDIDATES);
}

static void runs_without_a_seed_draw_different_victims(void **state)
{
    size_t a[DRAWS], b[DRAWS];
    uint64_t s1 = demo_chaos_fresh_seed(), s2 = demo_chaos_fresh_seed();
    assert_true(s1 != s2);
    draw(s1, a);
    draw(s2, b);
    /* 9^12 orders: two runs alike by chance once in 2.8e11 */
    assert_memory_not_equal(a, b, sizeof a);
}

static void the_same_seed_draws_the_same_victims(void **state)
{
    size_t a[DRAWS], b[DRAWS];
    uint64_t s = demo_chaos_fresh_seed();
    draw(s, a);
    draw(s, b);
    assert_memory_equal(a, b, sizeof a);
    /* splitmix64's published first output for seed 0 is 0xE220A8397B1DCDAF: the draw is the
     * same on every platform (std::uniform_int_distribution's is not) */
    demo_chaos_t c;
    demo_chaos_init(&c, 0);
    assert_int_equal(demo_chaos_pick(&c, 1u << 16), 0xCDAF);
}

static void every_candidate_is_drawn_about_as_often(void **state)
{
    demo_chaos_t c;
    demo_chaos_init(&c, demo_chaos_fresh_seed());
    int seen[CANDIDATES] = { 0 };
    for (int i = 0; i < 9000; i++) {
        size_t k = demo_chaos_pick(&c, CANDIDATES);
        assert_true(k < CANDIDATES);
        seen[k]++;
    }
    for (int k = 0; k < CANDIDATES; k++)
        assert_in_range(seen[k], 800, 1200);
    assert_int_equal(demo_chaos_pick(&c, 1), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(runs_without_a_seed_draw_different_victims),
        cmocka_unit_test(the_same_seed_draws_the_same_victims),
        cmocka_unit_test(every_candidate_is_drawn_about_as_often),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
