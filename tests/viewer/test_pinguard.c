/* test_pinguard: the web pages' PIN guard on a made-up clock: waits that double after each
 * wrong PIN, a lockout after five from one address and after twenty from all, nothing compared
 * meanwhile (not even the right PIN), and what the fastest guesser from a hundred addresses gets
 * in a day. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "tools/webcommon/pinguard.h"

#define S(x) ((int64_t)((x) * 1e6))

static pinguard_t *guard(void)
{
    pinguard_t *g = pinguard_create("482913", NULL);
    assert_non_null(g);
    return g;
}

static void test_waits_double_then_lock_out(void **state)
{
    pinguard_t *g = guard();
    int64_t t = S(100);
    assert_int_equal(pinguard_check(g, "10.0.0.1", "482913", t).verdict, PINGUARD_OK);
    double waits[] = { 1, 2, 4, 8 };
    for (int i = 0; i < 4; i++) {
        pinguard_result_t r = pinguard_check(g, "10.0.0.1", "000000", t);
        assert_int_equal(r.verdict, PINGUARD_WRONG);
        assert_int_equal(r.failures, i + 1);
        assert_float_equal(r.retry_s, waits[i], 1e-6);
        /* during the wait nothing is compared, not even the right PIN */
        r = pinguard_check(g, "10.0.0.1", "482913", t + S(waits[i] - 0.01));
        assert_int_equal(r.verdict, PINGUARD_WAIT);
        t += S(waits[i]);
    }
    pinguard_result_t r = pinguard_check(g, "10.0.0.1", "000000", t);
    assert_int_equal(r.verdict, PINGUARD_WRONG);
    assert_true(r.locked_now);
    assert_false(r.everyone);
    assert_float_equal(r.retry_s, 60, 1e-6);
    assert_int_equal(pinguard_check(g, "10.0.0.1", "482913", t + S(59)).verdict, PINGUARD_LOCKED);
    /* another address is not locked out (it waits out the short shared delay only) */
    assert_int_equal(pinguard_check(g, "10.0.0.2", "482913", t + S(2)).verdict, PINGUARD_OK);
    t += S(60);
    /* the second lockout of the same address lasts twice as long */
    for (int i = 0; i < 5; i++) {
        r = pinguard_check(g, "10.0.0.1", "111111", t);
        assert_int_equal(r.verdict, PINGUARD_WRONG);
        t += S(r.retry_s) + 1;
    }
    assert_true(r.locked_now);
    assert_float_equal(r.retry_s, 120, 1e-6);
    /* the right PIN, in time, clears the address */
    assert_int_equal(pinguard_check(g, "10.0.0.1", "482913", t).verdict, PINGUARD_OK);
    r = pinguard_check(g, "10.0.0.1", "000000", t);
    assert_float_equal(r.retry_s, 1, 1e-6);
    pinguard_stats_t st = pinguard_stats(g);
    assert_int_equal(st.lockouts, 2);
    assert_int_equal(st.wrong, 11);
    pinguard_destroy(g);
}

static void test_many_addresses_lock_everyone_out(void **state)
{
    pinguard_t *g = guard();
    int64_t t = S(10);
    pinguard_result_t r = {0};
    char addr[32];
    for (int i = 0; i < 20; i++) {
        t += S(r.retry_s) + 1;
        snprintf(addr, sizeof addr, "10.1.0.%d", i);
        r = pinguard_check(g, addr, "123456", t);
        assert_int_equal(r.verdict, PINGUARD_WRONG);
    }
    assert_true(r.locked_now);
    assert_true(r.everyone);
    r = pinguard_check(g, "10.9.9.9", "482913", t + S(1));
    assert_int_equal(r.verdict, PINGUARD_LOCKED);
    assert_true(r.everyone);
    assert_int_equal(pinguard_check(g, "10.9.9.9", "482913", t + S(61)).verdict, PINGUARD_OK);
    pinguard_destroy(g);
}

static void test_prefix_and_long_input_are_wrong(void **state)
{
    pinguard_t *g = guard();
    char huge[5000];
    memset(huge, '4', sizeof huge - 1);
    huge[sizeof huge - 1] = 0;
    assert_int_equal(pinguard_check(g, "a", "48291", S(1)).verdict, PINGUARD_WRONG);
    assert_int_equal(pinguard_check(g, "b", "4829130", S(10)).verdict, PINGUARD_WRONG);
    assert_int_equal(pinguard_check(g, "c", huge, S(20)).verdict, PINGUARD_WRONG);
    assert_int_equal(pinguard_check(g, "d", "", S(30)).verdict, PINGUARD_WRONG);
    assert_int_equal(pinguard_check(g, "e", NULL, S(40)).verdict, PINGUARD_WRONG);
    assert_null(pinguard_create("123", NULL));
    pinguard_destroy(g);
    pinguard_destroy(NULL);
}

/* A guesser once found a 6-digit PIN in 1.9 s (357,500 guesses). The fastest guesser now, from a
 * hundred addresses (five times what locks them all out), each trying again as soon as it may:
 * what it gets compared in a day, against the figure the docs give. */
static void test_a_day_of_guessing(void **state)
{
    pinguard_t *g = pinguard_create("999999", NULL);
    pinguard_cfg_t cfg;
    pinguard_cfg_defaults(&cfg);
    enum { ADDRS = 100 };
    int64_t t = S(1000), end = t + S(86400), next[ADDRS] = {0};
    int64_t compared = 0, guess = 0;
    char addr[32];
    while (t < end) {
        int64_t soonest = end;
        for (int a = 0; a < ADDRS; a++) {
            if (next[a] > t) {
                soonest = next[a] < soonest ? next[a] : soonest;
                continue;
            }
            snprintf(addr, sizeof addr, "10.2.%d.%d", a / 256, a % 256);
            char pin[8];
            snprintf(pin, sizeof pin, "%06lld", (long long)(guess % 999999));
            pinguard_result_t r = pinguard_check(g, addr, pin, t);
            assert_int_not_equal(r.verdict, PINGUARD_OK);
            if (r.verdict == PINGUARD_WRONG)
                compared++, guess++;
            next[a] = t + (r.retry_s > 0.001 ? S(r.retry_s) : S(0.001));
            soonest = next[a] < soonest ? next[a] : soonest;
        }
        t = soonest > t ? soonest : t + S(0.001);
    }
    char line[256];
    pinguard_strength(&cfg, 6, line, sizeof line);
    double bound = 0;
    sscanf(line, "at most %lf", &bound);
    printf("a day from %d addresses: %lld PINs compared (the docs say: %s)\n", ADDRS, (long long)compared, line);
    assert_true(compared <= bound + cfg.max_failures_all);
    assert_true(compared < 1000);     /* 0.1% of the 6-digit PINs */
    pinguard_destroy(g);
}

static void test_random_pins(void **state)
{
    char a[16], b[16];
    assert_int_equal(pinguard_random_pin(6, a, sizeof a), 0);
    assert_int_equal(pinguard_random_pin(6, b, sizeof b), 0);
    assert_int_equal(strlen(a), 6);
    assert_int_equal(strspn(a, "0123456789"), 6);
    assert_int_equal(pinguard_random_pin(3, a, sizeof a), -1);
    assert_int_equal(pinguard_random_pin(12, a, 12), -1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_waits_double_then_lock_out),
        cmocka_unit_test(test_many_addresses_lock_everyone_out),
        cmocka_unit_test(test_prefix_and_long_input_are_wrong),
        cmocka_unit_test(test_a_day_of_guessing),
        cmocka_unit_test(test_random_pins),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
