/* marie-gpio: the e-stop input (debounced edge events) published as estop_t on change and
 * periodically, and the status LED blinking the component's state. */
#include <errno.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>

#include "core/component.h"
#include "hw/gpio/debounce.h"
#include "hw/gpio/gpio.h"
#include "hw/gpio/gpio_params.h"
#include "lcmtypes/marie_estop_t.h"

static const gpio_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }

typedef struct {
    marie_component_t *c;
    gpio_in_t *in;
    gpio_out_t *led;
    gpio_debounce_t deb;
    marie_port_t *port;
    marie_timer_t *led_timer, *settle;
    bool led_on, fault;
} gp_t;

static const marie_port_spec_t ports[] = {
    { "estop", &marie_type_estop_t, MARIE_OUT, MARIE_PUSH, "ESTOP" },
    { NULL },
};

static const marie_param_spec_t params[] = GPIO_PARAMS;

static void publish(gp_t *g)
{
    if (marie_component_state(g->c) != MARIE_STATE_RUNNING)
        return;
    marie_estop_t m = {
        .utime = marie_component_now(g->c),
        .pressed = g->deb.state,
        .source = (char *)marie_component_name(g->c),
    };
    marie_port_publish(g->port, &m);
}

static void changed(gp_t *g)
{
    if (g->deb.state) {
        marie_component_count(g->c, "presses", 1);
        marie_component_event(g->c, MARIE_EVENT_T_SEV_WARN, "estop_pressed", "e-stop pressed");
    } else {
        marie_component_event(g->c, MARIE_EVENT_T_SEV_INFO, "estop_released", "e-stop released");
    }
    publish(g);
}

static void arm_settle(gp_t *g);

static void on_settle(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    gp_t *g = user;
    g->settle = NULL;       /* a one-shot is freed by the loop after it fires */
    if (gpio_debounce_update(&g->deb, marie_mono_us()))
        changed(g);
    arm_settle(g);
}

static void arm_settle(gp_t *g)
{
    int64_t dl = gpio_debounce_deadline(&g->deb);
    if (dl == INT64_MAX || g->settle)
        return;
    int64_t delay = dl - marie_mono_us();
    g->settle = marie_loop_add_wall_oneshot(marie_component_loop(g->c), delay > 0 ? delay : 0, on_settle, g);
}

static void on_edge(void *user, bool active, int64_t t)
{
    gp_t *g = user;
    if (gpio_debounce_input(&g->deb, active, t))
        changed(g);
}

static void on_readable(marie_loop_t *loop, int fd, short revents, void *user)
{
    gp_t *g = user;
    int n = gpio_in_read(g->in, on_edge, g);
    if (n < 0) {
        if (!g->fault)
            marie_component_event(g->c, MARIE_EVENT_T_SEV_ERROR, "estop_read_failed",
                                  "reading e-stop events: %s", strerror(errno));
        g->fault = true;
        marie_component_count(g->c, "read_errors", 1);
        return;
    }
    g->fault = false;
    marie_component_count(g->c, "edges", n);
    if (gpio_debounce_update(&g->deb, marie_mono_us()))
        changed(g);
    arm_settle(g);
}

static void on_led(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    gp_t *g = user;
    if (!g->led)
        return;
    gpio_led_pattern_t p = gpio_led_pattern_for((int)marie_component_state(g->c), g->deb.state, g->fault);
    bool on = gpio_led_level(p, marie_mono_us());
    if (on != g->led_on && gpio_out_set(g->led, on) == 0)
        g->led_on = on;
}

static void on_tick(marie_component_t *c, int64_t overruns)
{
    gp_t *g = marie_component_user(c);
    if (g)
        publish(g);
}

/* The component owns fixed-rate timers for its whole life: make one, even across re-inits. */
static marie_timer_t *periodic;

static void cleanup(gp_t *g)
{
    marie_loop_t *loop = marie_component_loop(g->c);
    if (g->in)
        marie_loop_remove_fd(loop, gpio_in_fd(g->in));
    marie_loop_remove_timer(loop, g->settle);
    marie_loop_remove_timer(loop, g->led_timer);
    gpio_in_close(g->in);
    gpio_out_close(g->led);
    free(g);
}

static int on_init(marie_component_t *c)
{
    gp_t *g = calloc(1, sizeof *g);
    if (!g) {
        marie_component_fail_reason(c, "out of memory");
        return -1;
    }
    g->c = c;
    g->port = marie_port(c, "estop");
    const char *chip = params_of(c)->chip;
    int64_t line = params_of(c)->estop_line, led = params_of(c)->led_line;
    int bias = gpio_bias_parse(params_of(c)->estop_bias);
    double hz = params_of(c)->publish_hz;
    if (bias < 0 || line < 0 || hz <= 0) {
        marie_component_fail_reason(c, "estop_bias must be as-is/disable/pull-up/pull-down, estop_line >= 0, "
                                    "publish_hz > 0");
        free(g);
        return -1;
    }
    g->in = gpio_in_open(chip, (unsigned)line, params_of(c)->estop_active_low, (gpio_bias_t)bias, "marie-estop");
    if (!g->in) {
        marie_component_fail_reason(c, "cannot request e-stop line %lld on %s: %s", (long long)line, chip, strerror(errno));
        free(g);
        return -1;
    }
    int v = gpio_in_value(g->in);
    if (v < 0) {
        marie_component_fail_reason(c, "cannot read e-stop line %lld on %s: %s", (long long)line, chip, strerror(errno));
        gpio_in_close(g->in);
        free(g);
        return -1;
    }
    gpio_debounce_init(&g->deb, v == 1, params_of(c)->press_ms * 1000,
                       params_of(c)->release_ms * 1000, marie_mono_us());
    if (led >= 0) {
        g->led = gpio_out_open(chip, (unsigned)led, params_of(c)->led_active_low, false, "marie-status");
        if (!g->led) {
            marie_component_fail_reason(c, "cannot request LED line %lld on %s: %s", (long long)led, chip, strerror(errno));
            gpio_in_close(g->in);
            free(g);
            return -1;
        }
    }
    marie_loop_t *loop = marie_component_loop(c);
    g->led_timer = marie_loop_add_wall_timer(loop, 50000, on_led, g);
    if (!periodic)
        periodic = marie_component_every(c, hz, on_tick);
    if (marie_loop_add_fd(loop, gpio_in_fd(g->in), POLLIN, on_readable, g) < 0 || !g->led_timer || !periodic) {
        marie_component_fail_reason(c, "cannot set up the loop: %s", strerror(errno));
        cleanup(g);
        return -1;
    }
    marie_component_set_user(c, g);
    return 0;
}

static void on_started(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    gp_t *g = marie_component_user(user);
    if (g)
        publish(g);
}

static int on_start(marie_component_t *c)
{
    /* The state becomes running when this returns: publish the current level right after,
     * rather than half a period later. */
    marie_loop_add_wall_oneshot(marie_component_loop(c), 0, on_started, c);
    return 0;
}

static void on_quit(marie_component_t *c)
{
    gp_t *g = marie_component_user(c);
    if (g)
        cleanup(g);
    marie_component_set_user(c, NULL);
}

static const marie_component_def_t def = {
    .kind = "gpio",
    .ports = ports,
    .params = params, .params_size = sizeof(gpio_params_t),
    .on_init = on_init,
    .on_start = on_start,
    .on_quit = on_quit,
};

int main(int argc, char **argv)
{
    return marie_main(&def, argc, argv, NULL);
}
