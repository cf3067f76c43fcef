/* gpio: one debounced-input line with edge events and one output line, over libgpiod 1.6. */
#ifndef MARIE_HW_GPIO_H
#define MARIE_HW_GPIO_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { GPIO_BIAS_AS_IS = 0, GPIO_BIAS_DISABLE, GPIO_BIAS_PULL_UP, GPIO_BIAS_PULL_DOWN } gpio_bias_t;
/* "as-is", "disable", "pull-up", "pull-down"; -1 when unknown. */
int gpio_bias_parse(const char *s);

typedef struct gpio_in gpio_in_t;
typedef struct gpio_out gpio_out_t;

/* chip: a name (gpiochip0), a path, a label or a number, as gpiod_chip_open_lookup takes.
 * active_low inverts the line in software, so edges and values are always "active" levels.
 * NULL with errno on failure. */
gpio_in_t *gpio_in_open(const char *chip, unsigned line, bool active_low, gpio_bias_t bias, const char *consumer);
void gpio_in_close(gpio_in_t *in);                       /* NULL is a no-op */
int gpio_in_fd(const gpio_in_t *in);                     /* watch it for POLLIN: edge events */
int gpio_in_value(gpio_in_t *in);                        /* 1 active, 0 inactive, -1 with errno */
/* Read the pending edge events; cb gets each one's active level and time on
 * CLOCK_MONOTONIC (us). Returns the number of events, or -1 with errno. */
typedef void (*gpio_edge_cb_t)(void *user, bool active, int64_t mono_us);
int gpio_in_read(gpio_in_t *in, gpio_edge_cb_t cb, void *user);

gpio_out_t *gpio_out_open(const char *chip, unsigned line, bool active_low, bool on, const char *consumer);
void gpio_out_close(gpio_out_t *out);                    /* leaves the line off; NULL is a no-op */
int gpio_out_set(gpio_out_t *out, bool on);              /* 0, or -1 with errno */

#ifdef __cplusplus
}
#endif
#endif
