/* test_gpio_debounce: the e-stop debounce filter and LED patterns, on synthetic edge timelines. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "hw/gpio/debounce.h"

#define MS 1000

static void test_clean_press_accepted_after_assert_time(void **state)
{
    gpio_debounce_t d;
    gpio_debounce_init(&d, false, 5 * MS, 50 * MS, 0);
    assert_false(gpio_debounce_input(&d, true, 100 * MS));
    assert_false(gpio_debounce_update(&d, 104 * MS));
    assert_int_equal(gpio_debounce_deadline(&d), 105 * MS);
    assert_true(gpio_debounce_update(&d, 105 * MS));
    assert_true(d.state);
    assert_false(gpio_debounce_update(&d, 200 * MS));      /* reported once */
    assert_int_equal(gpio_debounce_deadline(&d), INT64_MAX);
}

static void test_zero_assert_time_presses_at_once(void **state)
{
    gpio_debounce_t d;
    gpio_debounce_init(&d, false, 0, 50 * MS, 0);
    gpio_debounce_input(&d, true, 10 * MS);
    assert_true(gpio_debounce_update(&d, 10 * MS));
    assert_true(d.state);
}

static void test_bouncing_release_needs_quiet_contact(void **state)
{
    gpio_debounce_t d;
    gpio_debounce_init(&d, true, 0, 50 * MS, 0);
    /* The contact chatters for 30 ms: low/high every 3 ms, then stays low. */
    int64_t t = 1000 * MS;
    bool level = false;
    for (int i = 0; i < 10; i++, t += 3 * MS, level = !level) {
        assert_false(gpio_debounce_input(&d, level, t));
        assert_false(gpio_debounce_update(&d, t));
        assert_true(d.state);
    }
    /* The last bounce left the line high: now it goes low for good. */
    gpio_debounce_input(&d, false, t);
    assert_false(gpio_debounce_update(&d, t + 49 * MS));
    assert_true(gpio_debounce_update(&d, t + 50 * MS));
    assert_false(d.state);
    assert_true(d.rejected >= 5);
    assert_int_equal(d.edges, 11);
}

static void test_glitch_shorter_than_assert_time_ignored(void **state)
{
    gpio_debounce_t d;
    gpio_debounce_init(&d, false, 5 * MS, 50 * MS, 0);
    gpio_debounce_input(&d, true, 10 * MS);
    gpio_debounce_input(&d, false, 12 * MS);       /* 2 ms spike */
    assert_false(gpio_debounce_update(&d, 100 * MS));
    assert_false(d.state);
    assert_int_equal(d.rejected, 1);
}

static void test_settled_level_reported_by_next_input(void **state)
{
    /* No update() ran between a settled press and the release edge: input() reports it. */
    gpio_debounce_t d;
    gpio_debounce_init(&d, false, 5 * MS, 50 * MS, 0);
    gpio_debounce_input(&d, true, 10 * MS);
    assert_true(gpio_debounce_input(&d, false, 500 * MS));
    assert_true(d.state);
    assert_int_equal(d.rejected, 0);
    assert_true(gpio_debounce_update(&d, 550 * MS));
    assert_false(d.state);
}

static void test_led_patterns(void **state)
{
    /* heartbeat: on 100 ms of every 1000 */
    int on = 0;
    for (int64_t t = 0; t < 1000 * MS; t += MS)
        on += gpio_led_level(GPIO_LED_HEARTBEAT, t);
    assert_int_equal(on, 100);
    assert_true(gpio_led_level(GPIO_LED_HEARTBEAT, 5000 * MS + 50 * MS));
    assert_false(gpio_led_level(GPIO_LED_HEARTBEAT, 5000 * MS + 150 * MS));
    /* fast: 5 Hz, half on */
    on = 0;
    int flips = 0;
    bool prev = gpio_led_level(GPIO_LED_FAST, 0);
    for (int64_t t = 0; t < 1000 * MS; t += MS) {
        bool l = gpio_led_level(GPIO_LED_FAST, t);
        on += l;
        flips += l != prev;
        prev = l;
    }
    assert_int_equal(on, 500);
    assert_int_equal(flips, 9);
    /* double: two flashes per second */
    int rises = 0;
    prev = false;
    for (int64_t t = 0; t < 1000 * MS; t += MS) {
        bool l = gpio_led_level(GPIO_LED_DOUBLE, t);
        rises += l && !prev;
        prev = l;
    }
    assert_int_equal(rises, 2);
    assert_true(gpio_led_level(GPIO_LED_ON, 123));
    assert_false(gpio_led_level(GPIO_LED_OFF, 123));
}

static void test_led_pattern_follows_state(void **state)
{
    assert_int_equal(gpio_led_pattern_for(2, false, false), GPIO_LED_HEARTBEAT);
    assert_int_equal(gpio_led_pattern_for(2, true, false), GPIO_LED_FAST);
    assert_int_equal(gpio_led_pattern_for(1, false, false), GPIO_LED_ON);
    assert_int_equal(gpio_led_pattern_for(4, false, false), GPIO_LED_DOUBLE);
    assert_int_equal(gpio_led_pattern_for(2, true, true), GPIO_LED_DOUBLE);
    assert_int_equal(gpio_led_pattern_for(5, false, false), GPIO_LED_OFF);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_clean_press_accepted_after_assert_time),
        cmocka_unit_test(test_zero_assert_time_presses_at_once),
        cmocka_unit_test(test_bouncing_release_needs_quiet_contact),
        cmocka_unit_test(test_glitch_shorter_than_assert_time_ignored),
        cmocka_unit_test(test_settled_level_reported_by_next_input),
        cmocka_unit_test(test_led_patterns),
        cmocka_unit_test(test_led_pattern_follows_state),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
