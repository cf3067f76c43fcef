/* marie-lms200: the SICK LMS200 driver as a component: publishes laser_scan_t on `scan`. */
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <stdlib.h>
#include <string.h>

#include "core/component.h"
#include "hw/lms200/driver.h"
#include "hw/lms200/lms200_params.h"
#include "lcmtypes/marie_laser_scan_t.h"

static const lms200_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }

typedef struct {
    marie_component_t *c;
    lms200_driver_t *drv;
    marie_timer_t *tick;
    marie_port_t *scan_port;
    float ranges[LMS200_MAX_VALUES];
    bool start_pending;         /* started before the simulated clock was known */
} lms_t;

/* The device's clock: monotonic on the robot, simulated time under `--clock sim`. */
static int64_t now_us(const lms_t *l) { return marie_loop_mono(marie_component_loop(l->c)); }

static const marie_port_spec_t ports[] = {
    { "scan", &marie_type_laser_scan_t, MARIE_OUT, MARIE_PUSH, "LASER" },
    { NULL },
};

static const marie_param_spec_t params[] = LMS200_PARAMS;

static void on_scan(void *user, const lms200_scan_t *s, int res_cdeg, int64_t mono_us)
{
    lms_t *l = user;
    marie_component_t *c = l->c;
    if (marie_component_state(c) != MARIE_STATE_RUNNING)
        return;     /* paused: the device keeps streaming, nothing is published */
    double range_max = lms200_value_m(LMS200_VALUE_ERROR_MIN - 1, s->unit);
    for (int i = 0; i < s->n; i++) {
        double m = lms200_value_m(s->values[i], s->unit);
        l->ranges[i] = (float)(isinf(m) ? range_max : m);
    }
    /* Stamp the scan when its telegram began to arrive, not when its last byte did. */
    int64_t wire_us = lms200_wire_us(lms200_scan_telegram_len(s->n), (int)params_of(l->c)->drv.baud);
    marie_laser_scan_t msg = {
        .utime = marie_component_now(c) - (now_us(l) - mono_us) - wire_us,
        .angle_min = (float)(-M_PI / 2),
        .angle_increment = (float)(res_cdeg / 100.0 * M_PI / 180.0),
        .range_min = 0.0f,
        .range_max = (float)range_max,
        .nranges = s->n,
        .ranges = l->ranges,
        .nintensities = 0,
        .intensities = NULL,
    };
    marie_port_publish(l->scan_port, &msg);
    marie_component_count(c, "scans", 1);
}

static void on_event(void *user, int severity, const char *kind, const char *text)
{
    lms_t *l = user;
    marie_component_event(l->c, severity, kind, "%s", text);
}

static void on_count(void *user, const char *counter, int64_t delta, bool bad_input)
{
    lms_t *l = user;
    if (!bad_input) {
        marie_component_count(l->c, counter, delta);
        return;
    }
    if (strcmp(counter, "garbage_bytes") == 0) {
        marie_component_count(l->c, counter, delta);
        marie_component_bad_input(l->c, "garbage", "%lld bytes between telegrams skipped", (long long)delta);
        return;
    }
    for (int64_t i = 0; i < delta; i++)
        marie_component_bad_input(l->c, counter, "LMS200 telegram dropped (%s)", counter);
}

static void on_health(void *user, bool degraded, const char *why)
{
    lms_t *l = user;
    marie_component_set_degraded(l->c, degraded, "%s", why);
    if (degraded)
        marie_component_event(l->c, MARIE_EVENT_T_SEV_WARN, "laser_degraded", "%s", why);
    else if (strcmp(why, "stopped") != 0)
        marie_component_event(l->c, MARIE_EVENT_T_SEV_INFO, "laser_recovered", "%s", why);
}

/* POLLOUT only while a command waits for room on the line. */
static void watch_events(lms_t *l)
{
    int fd = lms200_driver_fd(l->drv);
    if (fd >= 0)
        marie_loop_set_events(marie_component_loop(l->c), fd, lms200_driver_events(l->drv));
}

static void on_readable(marie_loop_t *loop, int fd, short revents, void *user)
{
    lms_t *l = user;
    lms200_driver_io(l->drv, revents, now_us(l));
    watch_events(l);
}

static void on_fd(void *user, int old_fd, int new_fd)
{
    lms_t *l = user;
    marie_loop_t *loop = marie_component_loop(l->c);
    if (old_fd >= 0)
        marie_loop_remove_fd(loop, old_fd);
    if (new_fd >= 0 && marie_loop_add_fd(loop, new_fd, POLLIN, on_readable, l) < 0)
        marie_error("cannot watch the laser fd: %s", strerror(errno));
}

/* Device timeouts follow the component's clock: monotonic on the robot, simulated time under
 * `--clock sim`, where the virtual LMS200 streams on simulated time. */
static void on_tick(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    lms_t *l = user;
    if (l->start_pending) {
        l->start_pending = false;
        lms200_driver_start(l->drv, now_us(l));
    }
    lms200_driver_tick(l->drv, now_us(l));
    watch_events(l);
}

static const lms200_driver_ops_t driver_ops = {
    .on_scan = on_scan, .on_event = on_event, .on_count = on_count, .on_fd = on_fd, .on_health = on_health,
};

static int on_init(marie_component_t *c)
{
    lms_t *l = calloc(1, sizeof *l);
    if (!l) {
        marie_component_fail_reason(c, "out of memory");
        return -1;
    }
    l->c = c;
    const lms200_driver_cfg_t *cfg = &params_of(c)->drv;
    l->drv = lms200_driver_create(cfg, &driver_ops, l);
    if (!l->drv && errno == EINVAL) {
        marie_component_fail_reason(c, "resolution must be 0.5 or 1, baud 9600/19200/38400/500000, address 0..127, "
                                    "timeouts and retries above 0 (got %g, %lld, %lld)", cfg->resolution,
                                    (long long)cfg->baud, (long long)cfg->address);
        free(l);
        return -1;
    }
    l->tick = marie_loop_add_timer(marie_component_loop(c), 20000, on_tick, l);
    l->scan_port = marie_port(c, "scan");
    if (!l->drv || !l->tick) {
        marie_component_fail_reason(c, "cannot create the driver: %s", strerror(errno));
        marie_loop_remove_timer(marie_component_loop(c), l->tick);
        lms200_driver_destroy(l->drv);
        free(l);
        return -1;
    }
    marie_component_set_user(c, l);
    return 0;
}

static int on_start(marie_component_t *c)
{
    lms_t *l = marie_component_user(c);
    /* On the sim clock, reply deadlines taken before the first clock message would expire at
     * it: the first tick after it starts the driver. */
    if (!marie_loop_clock_known(marie_component_loop(c)))
        l->start_pending = true;
    else
        lms200_driver_start(l->drv, now_us(l));
    watch_events(l);
    return 0;
}

static int on_stop(marie_component_t *c)
{
    lms_t *l = marie_component_user(c);
    l->start_pending = false;
    lms200_driver_stop(l->drv);
    return 0;
}

static void on_abort(marie_component_t *c)
{
    lms_t *l = marie_component_user(c);
    if (l)
        lms200_driver_stop(l->drv);
}

static void on_quit(marie_component_t *c)
{
    lms_t *l = marie_component_user(c);
    if (!l)
        return;
    lms200_driver_stop(l->drv);
    marie_loop_remove_timer(marie_component_loop(c), l->tick);
    lms200_driver_destroy(l->drv);
    free(l);
    marie_component_set_user(c, NULL);
}

static const marie_component_def_t def = {
    .kind = "lms200",
    .ports = ports,
    .params = params, .params_size = sizeof(lms200_params_t),
    .on_init = on_init,
    .on_start = on_start,
    .on_stop = on_stop,
    .on_abort = on_abort,
    .on_quit = on_quit,
};

int main(int argc, char **argv)
{
    return marie_main(&def, argc, argv, NULL);
}
