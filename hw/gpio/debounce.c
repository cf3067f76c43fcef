/* debounce: the e-stop's contact bounce filter and LED patterns, without any I/O. */
#include "hw/gpio/debounce.h"

void gpio_debounce_init(gpio_debounce_t *d, bool level, int64_t assert_us, int64_t release_us, int64_t now)
{
    *d = (gpio_debounce_t){
        .assert_us = assert_us < 0 ? 0 : assert_us,
        .release_us = release_us < 0 ? 0 : release_us,
        .state = level,
        .raw = level,
        .raw_since = now,
    };
}

bool gpio_debounce_update(gpio_debounce_t *d, int64_t now);

bool gpio_debounce_input(gpio_debounce_t *d, bool level, int64_t t)
{
    if (level == d->raw)
        return false;
    bool changed = gpio_debounce_update(d, t);
    d->edges++;
    /* A run away from the state that ends before it settled was a bounce. */
    if (d->raw != d->state)
        d->rejected++;
    d->raw = level;
    d->raw_since = t;
    return changed;
}

bool gpio_debounce_update(gpio_debounce_t *d, int64_t now)
{
    if (d->raw == d->state)
        return false;
    int64_t need = d->raw ? d->assert_us : d->release_us;
    if (now - d->raw_since < need)
        return false;
    d->state = d->raw;
    return true;
}

int64_t gpio_debounce_deadline(const gpio_debounce_t *d)
{
    if (d->raw == d->state)
        return INT64_MAX;
    return d->raw_since + (d->raw ? d->assert_us : d->release_us);
}

/* Durations in ms: on, off, on, off, ... ending with 0; the pattern repeats. */
static const int heartbeat[] = { 100, 900, 0 };
static const int fast[] = { 100, 100, 0 };
static const int dbl[] = { 100, 150, 100, 650, 0 };

bool gpio_led_level(gpio_led_pattern_t p, int64_t t_us)
{
    const int *seq;
    switch (p) {
    case GPIO_LED_OFF: return false;
    case GPIO_LED_ON: return true;
    case GPIO_LED_HEARTBEAT: seq = heartbeat; break;
    case GPIO_LED_FAST: seq = fast; break;
    case GPIO_LED_DOUBLE: seq = dbl; break;
    default: return false;
    }
    int64_t period = 0;
    for (const int *s = seq; *s; s++)
        period += *s;
    int64_t t = (t_us / 1000) % period;
    if (t < 0)
        t += period;
    bool on = true;
    for (const int *s = seq; *s; s++, on = !on) {
        if (t < *s)
            return on;
        t -= *s;
    }
    return false;
}

gpio_led_pattern_t gpio_led_pattern_for(int marie_state, bool estop_pressed, bool fault)
{
    if (fault || marie_state == 4 /* failed */)
        return GPIO_LED_DOUBLE;
    if (estop_pressed)
        return GPIO_LED_FAST;
    switch (marie_state) {
    case 2: return GPIO_LED_HEARTBEAT;      /* running */
    case 1: case 3: return GPIO_LED_ON;     /* ready, paused */
    default: return GPIO_LED_OFF;
    }
}
