/* debounce: pure time-based debouncing of one digital input, and status LED blink patterns. */
#ifndef MARIE_HW_GPIO_DEBOUNCE_H
#define MARIE_HW_GPIO_DEBOUNCE_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* A level is accepted once it has held for its settle time. The two directions have their
 * own times so that an e-stop can be taken as pressed at once and as released only after
 * the contact has been quiet for a while. Times are microseconds on one monotonic clock. */
typedef struct {
    int64_t assert_us;          /* settle time to go active (false -> true) */
    int64_t release_us;         /* settle time to go inactive (true -> false) */
    bool state;                 /* the debounced level */
    bool raw;                   /* the last raw level seen */
    int64_t raw_since;          /* when raw last changed */
    uint64_t edges;             /* raw changes seen */
    uint64_t rejected;          /* raw changes that never became a state change (bounces) */
} gpio_debounce_t;

void gpio_debounce_init(gpio_debounce_t *d, bool level, int64_t assert_us, int64_t release_us, int64_t now);
/* A raw level read or reported by an edge event at time t (t never goes backwards).
 * Returns true when the level held before it had settled by t, i.e. the debounced state
 * changed (to the old raw level) just before this input. */
bool gpio_debounce_input(gpio_debounce_t *d, bool level, int64_t t);
/* Advance to now; returns true when the debounced state changed. */
bool gpio_debounce_update(gpio_debounce_t *d, int64_t now);
/* When update() next has something to decide, or INT64_MAX. */
int64_t gpio_debounce_deadline(const gpio_debounce_t *d);

/* Status LED patterns: a repeating list of on/off durations. */
typedef enum {
    GPIO_LED_OFF = 0,
    GPIO_LED_ON,                /* ready, not running */
    GPIO_LED_HEARTBEAT,         /* running, all well: a short flash every second */
    GPIO_LED_FAST,              /* e-stop pressed: 5 Hz */
    GPIO_LED_DOUBLE,            /* fault: two flashes every second */
} gpio_led_pattern_t;

/* The LED level for a pattern at time t (any monotonic origin). */
bool gpio_led_level(gpio_led_pattern_t p, int64_t t_us);
/* The pattern for a component state (core/component.h's marie_state_t values) and e-stop. */
gpio_led_pattern_t gpio_led_pattern_for(int marie_state, bool estop_pressed, bool fault);

#ifdef __cplusplus
}
#endif
#endif
