/* test_balance: automatic placement without I/O: the `balance:` section, the election and its
 * terms, overload moves with hysteresis and cooldown, failover, and duplicates after a heal. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "managers/balance.h"

#define S 1000000LL

static const char *SYSTEM =
    "system: t\n"
    "hosts: [a, b, c]\n"
    "components:\n"
    "  hog: {exec: x, host: b}\n"
    "  planner: {exec: x, host: b}\n"
    "  mission: {exec: x, host: b}\n"
    "  drives: {exec: x, host: b}\n"
    "balance:\n"
    "  window: 10\n"
    "  high: 0.8\n"
    "  low: 0.6\n"
    "  cooldown: 30\n"
    "  host_lost: 2\n"
    "  movable: [planner, mission]\n"
    "  capacity: {a: 2, b: 2, c: 2}\n"
    "%s";

static balance_cfg_t cfg;

static marie_system_t *load(const char *extra, marie_errors_t *errs)
{
    char path[] = "/tmp/test_balance_XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    FILE *f = fdopen(fd, "w");
    fprintf(f, SYSTEM, extra);
    fclose(f);
    marie_system_t *sys = marie_system_load(path, NULL, errs);
    unlink(path);
    if (sys && balance_read_cfg(sys, &cfg, errs) < 0) {
        marie_system_destroy(sys);
        return NULL;
    }
    return sys;
}

/* One status round from `host` at `t`: cpu per component in the order hog, planner, mission,
 * drives (negative: not running there). */
static void status(balance_t *b, const char *host, int64_t term, int64_t t, double hog, double planner,
                   double mission, double drives)
{
    balance_heard(b, host, term, false, 2, t);
    const char *names[] = {"hog", "planner", "mission", "drives"};
    double cpu[] = {hog, planner, mission, drives};
    for (int i = 0; i < 4; i++)
        if (cpu[i] >= 0)
            balance_sample(b, host, names[i], cpu[i], true, t);
}

static void test_config_errors_have_positions(void **state)
{
    marie_errors_t errs = {0};
    assert_null(load("  prefer: {planner: [z]}\n", &errs));
    assert_non_null(strstr(errs.msgs[0], "unknown host 'z'"));
    assert_non_null(strstr(errs.msgs[0], ":16:"));     /* file:line of the prefer entry */
    marie_errors_clear(&errs);

    char bad[] = "system: t\ncomponents: {p: {exec: x, host: a}}\nbalance: {high: 0.5, low: 0.7}\n";
    char path[] = "/tmp/test_balance_XXXXXX";
    int fd = mkstemp(path);
    assert_int_equal(write(fd, bad, strlen(bad)), (int)strlen(bad));
    close(fd);
    marie_system_t *sys = marie_system_load(path, NULL, &errs);
    assert_non_null(sys);
    assert_int_equal(balance_read_cfg(sys, &cfg, &errs), -1);
    marie_system_destroy(sys);
    unlink(path);
    assert_non_null(strstr(errs.msgs[0], "low < high"));
    assert_non_null(strstr(errs.msgs[0], ":3:"));
    marie_errors_clear(&errs);

    assert_null(load("  prefer: {nobody: [a]}\n", &errs));
    assert_non_null(strstr(errs.msgs[0], "unknown component 'nobody'"));
    marie_errors_clear(&errs);

    sys = load("", &errs);
    assert_non_null(sys);
    assert_true(cfg.enabled);
    assert_true(cfg.high == 0.8 && cfg.low == 0.6 && cfg.window_s == 10);
    marie_system_destroy(sys);
}

static void test_smallest_live_name_leads_after_settling(void **state)
{
    marie_errors_t errs = {0};
    marie_system_t *sys = load("", &errs);
    balance_t *b = balance_create("b", sys, &cfg);
    int64_t t = 100 * S;
    status(b, "a", 3, t, -1, -1, -1, -1);
    assert_string_equal(balance_leader(b, t), "a");
    assert_false(balance_acting(b, t));
    /* a falls silent: b leads with a term above every one heard, and acts only 2 s later */
    t += 2500000;
    assert_string_equal(balance_leader(b, t), "b");
    assert_false(balance_acting(b, t));
    assert_int_equal(balance_term(b), 4);
    assert_false(balance_acting(b, t + 1 * S));
    assert_true(balance_acting(b, t + 2 * S));
    /* a is back: b steps down at once */
    status(b, "a", 4, t + 3 * S, -1, -1, -1, -1);
    assert_false(balance_acting(b, t + 3 * S));
    balance_destroy(b);
    marie_system_destroy(sys);
}

static void test_overload_moves_the_busiest_movable_component_once(void **state)
{
    marie_errors_t errs = {0};
    marie_system_t *sys = load("", &errs);
    int64_t t = 100 * S;
    balance_t *b = balance_create("a", sys, &cfg);
    balance_move_t m;
    int moves = 0;
    /* b at (120 + 50 + 5 + 2) / 200 = 0.89 > high; nothing before the window is covered */
    for (int i = 0; i < 60; i++, t += S / 2) {
        /* each manager reports the planner where it is placed */
        bool moved = strcmp(balance_placement(b, "planner"), "c") == 0;
        status(b, "b", 0, t, 120, moved ? -1 : 50, 5, 2);
        status(b, "c", 0, t, -1, moved ? 50 : -1, -1, -1);
        if (i < 20)
            assert_int_equal(balance_step(b, t, &m), 0);
        else if (balance_step(b, t, &m)) {
            moves++;
            assert_int_equal(m.why, BALANCE_OVERLOAD);
            assert_string_equal(m.component, "planner");  /* the hog and drives are pinned */
            assert_string_equal(m.from, "b");
            assert_string_equal(m.to, "c");
            assert_non_null(strstr(m.reason, "planner"));
            balance_placed(b, m.component, m.to, t);
        }
    }
    assert_int_equal(moves, 1);
    assert_string_equal(balance_placement(b, "planner"), "c");
    balance_destroy(b);
    marie_system_destroy(sys);
}

static void test_no_move_when_no_host_stays_under_low(void **state)
{
    marie_errors_t errs = {0};
    marie_system_t *sys = load("", &errs);
    int64_t t = 100 * S;
    balance_t *b = balance_create("a", sys, &cfg);
    balance_move_t m;
    for (int i = 0; i < 60; i++, t += S / 2) {
        status(b, "b", 0, t, 120, 50, 5, 2);
        /* a and c are busy too (0.59 of 2 cores each): even the mission would push them over low */
        balance_heard(b, "c", 0, false, 2, t);
        balance_sample(b, "c", "someone", 118, true, t);
        balance_heard(b, "a", 0, false, 2, t);
        balance_sample(b, "a", "someone", 118, true, t);
        assert_int_equal(balance_step(b, t, &m), 0);
    }
    balance_destroy(b);
    marie_system_destroy(sys);
}

/* Two loads that alternate between hosts every 20 s for 5 minutes: the cooldown, the fresh
 * window after a move and the gap between low and high keep the moves few. */
static void test_competing_loads_do_not_flap(void **state)
{
    marie_errors_t errs = {0};
    marie_system_t *sys = load("", &errs);
    int64_t t = 100 * S;
    balance_t *b = balance_create("a", sys, &cfg);
    balance_move_t m;
    int moves = 0;
    for (int i = 0; i < 600; i++, t += S / 2) {
        bool phase = (i / 40) % 2;
        const char *pl = balance_placement(b, "planner"), *mi = balance_placement(b, "mission");
        /* the hog (pinned on b) is busy in one phase; whichever host runs planner and
         * mission reports them at 40 % each */
        balance_heard(b, "b", 0, false, 2, t);
        balance_heard(b, "c", 0, false, 2, t);
        balance_sample(b, "b", "hog", phase ? 130 : 10, true, t);
        balance_sample(b, pl, "planner", 40, true, t);
        balance_sample(b, mi, "mission", 40, true, t);
        if (balance_step(b, t, &m)) {
            moves++;
            balance_placed(b, m.component, m.to, t);
        }
    }
    assert_true(moves >= 1);
    assert_true(moves <= 3);
    balance_destroy(b);
    marie_system_destroy(sys);
}

static void test_failover_moves_movable_components_of_a_lost_host(void **state)
{
    marie_errors_t errs = {0};
    marie_system_t *sys = load("  prefer: {mission: [a]}\n", &errs);
    assert_non_null(sys);
    int64_t t = 100 * S;
    balance_t *b = balance_create("a", sys, &cfg);
    balance_move_t m;
    for (int i = 0; i < 10; i++, t += S / 2) {
        status(b, "b", 0, t, 10, 10, 10, 1);
        status(b, "c", 0, t, -1, -1, -1, -1);
        assert_int_equal(balance_step(b, t, &m), 0);
    }
    /* b falls silent; 2 s later its planner and mission go, the hog and drives stay */
    int64_t lost = t;
    const char *to[2] = {0};
    for (int i = 0; i < 20; i++, t += S / 4) {
        status(b, "c", 0, t, -1, -1, -1, -1);
        while (balance_step(b, t, &m)) {
            assert_int_equal(m.why, BALANCE_FAILOVER);
            assert_true(t - lost > 2 * S - S / 2);
            assert_true(t - lost <= 3 * S);
            if (strcmp(m.component, "planner") == 0)
                to[0] = "x";
            else {
                assert_string_equal(m.component, "mission");
                assert_string_equal(m.to, "a");      /* its preference */
                to[1] = "x";
            }
            balance_placed(b, m.component, m.to, t);
        }
    }
    assert_non_null(to[0]);
    assert_non_null(to[1]);
    assert_string_equal(balance_placement(b, "drives"), "b");
    balance_destroy(b);
    marie_system_destroy(sys);
}

static void test_healed_partition_keeps_one_copy(void **state)
{
    marie_errors_t errs = {0};
    marie_system_t *sys = load("", &errs);
    int64_t t = 100 * S;
    balance_t *b = balance_create("a", sys, &cfg);
    balance_move_t m;
    for (int i = 0; i < 10; i++, t += S / 2) {
        status(b, "b", 0, t, 10, 10, 10, 1);
        status(b, "c", 0, t, -1, -1, -1, -1);
    }
    /* the other side had moved planner to c while we could not hear it: both run it */
    int i;
    memset(&m, 0, sizeof m);
    for (i = 0; i < 10; i++, t += S / 2) {
        status(b, "b", 0, t, 10, 10, 10, 1);
        status(b, "c", 0, t, -1, 10, -1, -1);
        if (balance_step(b, t, &m))
            break;
    }
    assert_true(i < 10);
    assert_int_equal(m.why, BALANCE_DUPLICATE);
    assert_string_equal(m.component, "planner");
    assert_string_equal(m.to, "b");
    assert_string_equal(m.from, "c");
    balance_destroy(b);
    marie_system_destroy(sys);
}

/* Two leaders from the two sides of a partition, then the heal: at no instant do both act. */
static void test_two_never_act_at_once_after_a_heal(void **state)
{
    marie_errors_t errs = {0};
    marie_system_t *sys = load("", &errs);
    balance_t *a = balance_create("a", sys, &cfg), *c = balance_create("c", sys, &cfg);
    int64_t t = 100 * S;
    /* partition: a with b on one side, c alone on the other; both lead their side */
    for (int i = 0; i < 20; i++, t += S / 2) {
        status(a, "b", balance_term(a), t, -1, -1, -1, -1);
        balance_acting(a, t);
        balance_acting(c, t);
    }
    assert_true(balance_acting(a, t));
    assert_true(balance_acting(c, t));
    /* heal: each hears the other's status (with its term) every half second, a little apart */
    for (int i = 0; i < 40; i++, t += S / 2) {
        balance_heard(a, "c", balance_term(c), balance_leads(c), 2, t);
        status(a, "b", balance_term(a), t, -1, -1, -1, -1);
        bool aa = balance_acting(a, t);
        balance_heard(c, "a", balance_term(a), balance_leads(a), 2, t + 1000);
        status(c, "b", balance_term(a), t + 1000, -1, -1, -1, -1);
        bool ca = balance_acting(c, t + 1000);
        assert_false(aa && ca);
        if (i == 0)
            assert_false(aa);    /* a heard a term as high as its own: it settles first */
    }
    assert_true(balance_acting(a, t));
    assert_false(balance_acting(c, t));
    assert_true(balance_term(a) > 1);
    balance_destroy(a);
    balance_destroy(c);
    marie_system_destroy(sys);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_config_errors_have_positions),
        cmocka_unit_test(test_smallest_live_name_leads_after_settling),
        cmocka_unit_test(test_overload_moves_the_busiest_movable_component_once),
        cmocka_unit_test(test_no_move_when_no_host_stays_under_low),
        cmocka_unit_test(test_competing_loads_do_not_flap),
        cmocka_unit_test(test_failover_moves_movable_components_of_a_lost_host),
        cmocka_unit_test(test_healed_partition_keeps_one_copy),
        cmocka_unit_test(test_two_never_act_at_once_after_a_heal),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
