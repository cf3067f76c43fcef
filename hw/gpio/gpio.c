/* gpio: thin libgpiod 1.6 wrapper; the debounce and LED logic live in debounce.c. */
#include "hw/gpio/gpio.h"

#include <errno.h>
#include <gpiod.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "core/err.h"

struct gpio_in {
    struct gpiod_chip *chip;
    struct gpiod_line *line;
    bool active_low;
};

struct gpio_out {
    struct gpiod_chip *chip;
    struct gpiod_line *line;
    bool active_low;
};

int gpio_bias_parse(const char *s)
{
    if (!strcmp(s, "as-is")) return GPIO_BIAS_AS_IS;
    if (!strcmp(s, "disable")) return GPIO_BIAS_DISABLE;
    if (!strcmp(s, "pull-up")) return GPIO_BIAS_PULL_UP;
    if (!strcmp(s, "pull-down")) return GPIO_BIAS_PULL_DOWN;
    return -1;
}

static int bias_flags(gpio_bias_t b)
{
    switch (b) {
    case GPIO_BIAS_DISABLE: return GPIOD_LINE_REQUEST_FLAG_BIAS_DISABLE;
    case GPIO_BIAS_PULL_UP: return GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_UP;
    case GPIO_BIAS_PULL_DOWN: return GPIOD_LINE_REQUEST_FLAG_BIAS_PULL_DOWN;
    default: return 0;
    }
}

static int64_t mono_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000 + ts.tv_nsec / 1000;
}

gpio_in_t *gpio_in_open(const char *chip, unsigned line, bool active_low, gpio_bias_t bias, const char *consumer)
{
    gpio_in_t *in = calloc(1, sizeof *in);
    if (!in)
        return NULL;
    in->active_low = active_low;
    in->chip = gpiod_chip_open_lookup(chip);
    if (!in->chip)
        goto err_chip;
    in->line = gpiod_chip_get_line(in->chip, line);
    if (!in->line)
        goto err_line;
    /* Inversion is done here rather than by the kernel so that edge types always mean
     * physical rising/falling, whatever the kernel's uAPI version does with active-low. */
    if (gpiod_line_request_both_edges_events_flags(in->line, consumer, bias_flags(bias)) < 0)
        goto err_line;
    return in;
err_line:
    MARIE_KEEP_ERRNO(gpiod_chip_close(in->chip));
err_chip:
    free(in);
    return NULL;
}

void gpio_in_close(gpio_in_t *in)
{
    if (!in)
        return;
    gpiod_line_release(in->line);
    gpiod_chip_close(in->chip);
    free(in);
}

int gpio_in_fd(const gpio_in_t *in)
{
    return gpiod_line_event_get_fd(in->line);
}

int gpio_in_value(gpio_in_t *in)
{
    int v = gpiod_line_get_value(in->line);
    if (v < 0)
        return -1;
    return (v != 0) != in->active_low;
}

int gpio_in_read(gpio_in_t *in, gpio_edge_cb_t cb, void *user)
{
    struct gpiod_line_event ev[16];
    int n = gpiod_line_event_read_fd_multiple(gpio_in_fd(in), ev, 16);
    if (n < 0)
        return errno == EAGAIN ? 0 : -1;
    int64_t now = mono_us();
    for (int i = 0; i < n; i++) {
        bool high = ev[i].event_type == GPIOD_LINE_EVENT_RISING_EDGE;
        int64_t t = (int64_t)ev[i].ts.tv_sec * 1000000 + ev[i].ts.tv_nsec / 1000;
        /* Kernels before 5.7 stamp events with the wall clock: fall back to now then. */
        if (t > now || now - t > 10 * 1000000)
            t = now;
        cb(user, high != in->active_low, t);
    }
    return n;
}

gpio_out_t *gpio_out_open(const char *chip, unsigned line, bool active_low, bool on, const char *consumer)
{
    gpio_out_t *out = calloc(1, sizeof *out);
    if (!out)
        return NULL;
    out->active_low = active_low;
    out->chip = gpiod_chip_open_lookup(chip);
    if (!out->chip)
        goto err_chip;
    out->line = gpiod_chip_get_line(out->chip, line);
    if (!out->line || gpiod_line_request_output(out->line, consumer, on != active_low) < 0)
        goto err_line;
    return out;
err_line:
    MARIE_KEEP_ERRNO(gpiod_chip_close(out->chip));
err_chip:
    free(out);
    return NULL;
}

void gpio_out_close(gpio_out_t *out)
{
    if (!out)
        return;
    gpiod_line_set_value(out->line, out->active_low);
    gpiod_line_release(out->line);
    gpiod_chip_close(out->chip);
    free(out);
}

int gpio_out_set(gpio_out_t *out, bool on)
{
    return gpiod_line_set_value(out->line, on != out->active_low) < 0 ? -1 : 0;
}
