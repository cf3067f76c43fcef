/* vm_gpio_check: the LCM side of the GPIO VM test: drives a gpio-sim line's pull (the e-stop
 * contact, with bounce), watches what marie-gpio publishes on ESTOP and samples the LED line,
 * and prints key=value lines for tests/hw/vm_gpio_inner.sh to judge.
 *   vm_gpio_check PULL_FILE LED_VALUE_FILE */
#include <lcm/lcm.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "core/config.h"
#include "core/time.h"
#include "lcmtypes/marie_estop_t.h"
#include "lcmtypes/marie_heartbeat_t.h"

static lcm_t *lcm;
static const char *pull_file, *led_file;
static int nmsg = 0, pressed = -1, presses = 0, releases = 0;
static int64_t changed_at;          /* wall us of the last change, stamped by marie-gpio */
static int64_t edges = -1;

static void on_estop(const lcm_recv_buf_t *rb, const char *ch, const marie_estop_t *m, void *u)
{
    nmsg++;
    if (m->pressed != pressed) {
        if (pressed >= 0)
            m->pressed ? presses++ : releases++;
        pressed = m->pressed;
        changed_at = m->utime;
    }
}

static void on_hb(const lcm_recv_buf_t *rb, const char *ch, const marie_heartbeat_t *m, void *u)
{
    if (strcmp(m->component, "estop") != 0)
        return;
    for (int i = 0; i < m->ncounters; i++)
        if (!strcmp(m->counters[i].name, "edges"))
            edges = m->counters[i].value;
}

static void set_pull(const char *v)
{
    FILE *f = fopen(pull_file, "w");
    if (!f || fputs(v, f) < 0 || fclose(f) != 0) {
        perror(pull_file);
        exit(2);
    }
}

static int led(void)
{
    char c = '?';
    FILE *f = fopen(led_file, "r");
    if (f) {
        c = (char)fgetc(f);
        fclose(f);
    }
    return c == '1';
}

static void spin(int64_t us)
{
    int64_t end = marie_mono_us() + us;
    while (marie_mono_us() < end)
        lcm_handle_timeout(lcm, 1);
}

/* Wait up to `s` seconds for ESTOP to say `want`; 0 when it did. */
static int wait_pressed(int want, double s)
{
    int64_t end = marie_mono_us() + (int64_t)(s * 1e6);
    while (pressed != want && marie_mono_us() < end)
        lcm_handle_timeout(lcm, 5);
    return pressed == want ? 0 : -1;
}

/* Sample the LED for `s` seconds every 2 ms: rising edges and the share of time on. */
static void sample_led(const char *name, double s)
{
    int64_t t0 = marie_mono_us(), end = t0 + (int64_t)(s * 1e6), on_us = 0, last = t0;
    int prev = led(), rises = 0;
    while (marie_mono_us() < end) {
        lcm_handle_timeout(lcm, 2);
        int64_t now = marie_mono_us();
        int v = led();
        if (prev)
            on_us += now - last;
        if (v && !prev)
            rises++;
        prev = v;
        last = now;
    }
    printf("led_%s_hz=%.2f\nled_%s_on_pct=%.0f\n", name, rises / s, name, 100.0 * on_us / (end - t0));
}

/* The contact chattering for `n` cycles of `ms` each way, then resting at `first`; returns
 * the wall time of that last change. */
static int64_t bounce(const char *first, const char *other, int n, int ms)
{
    for (int i = 0; i < n; i++) {
        set_pull(first);
        spin(ms * 1000);
        set_pull(other);
        spin(ms * 1000);
    }
    int64_t last = marie_wall_us();
    set_pull(first);
    return last;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: vm_gpio_check PULL_FILE LED_VALUE_FILE\n");
        return 2;
    }
    pull_file = argv[1];
    led_file = argv[2];
    setvbuf(stdout, NULL, _IOLBF, 0);
    lcm = lcm_create(marie_default_url());
    if (!lcm)
        return 2;
    marie_estop_t_subscription_t *es = marie_estop_t_subscribe(lcm, "ESTOP", on_estop, NULL);
    marie_heartbeat_t_subscription_t *hb = marie_heartbeat_t_subscribe(lcm, "MARIE_HEARTBEAT", on_hb, NULL);
    int64_t end = marie_mono_us() + 30000000;
    while (nmsg == 0 && marie_mono_us() < end)
        lcm_handle_timeout(lcm, 50);
    printf("running=%d\n", nmsg > 0);
    /* The contact closes: released (the line's own pull-up held it high until now). */
    set_pull("pull-down");
    printf("released_initially=%d\n", wait_pressed(0, 5) == 0);
    spin(300000);
    sample_led("released", 4);

    int before = presses;
    int64_t t0 = marie_wall_us();
    bounce("pull-up", "pull-down", 4, 10);
    int r = wait_pressed(1, 5);
    printf("press_seen=%d\npress_latency_ms=%.1f\n", r == 0, (changed_at - t0) / 1e3);
    spin(300000);
    printf("presses_during_press_bounce=%d\n", presses - before);
    sample_led("pressed", 2);

    before = releases;
    int64_t last = bounce("pull-down", "pull-up", 4, 10);
    r = wait_pressed(0, 5);
    printf("release_seen=%d\nrelease_after_last_bounce_ms=%.1f\n", r == 0, (changed_at - last) / 1e3);
    spin(300000);
    printf("releases_during_release_bounce=%d\npresses_total=%d\n", releases - before, presses);
    spin(1200000);          /* one more heartbeat with the counters */
    printf("edges=%lld\n", (long long)edges);
    marie_estop_t_unsubscribe(lcm, es);
    marie_heartbeat_t_unsubscribe(lcm, hb);
    lcm_destroy(lcm);
    return 0;
}
