/* test_odometry_gyro: marie-odometry takes its heading from the encoders while the gyro driver
 * has not learned the gyro's bias (bias_valid false), and from the gyro once it has. A robot
 * standing still with an uncalibrated gyro reading 0.2 rad/s must not turn on the map. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#include <cmocka.h>
#include <lcm/lcm.h>

#include "core/time.h"
#include "lcmtypes/marie_types.h"
#include "tests/proc.h"

static double heading = NAN;
static int heard;

static void on_odometry(const lcm_recv_buf_t *rb, const char *ch, const marie_odometry_t *m, void *user)
{
    heading = m->pose.theta;
    heard++;
}

/* Feeds the standing robot's encoders and a gyro reading `rate` for `secs` at 50 Hz; the
 * heading of the last odometry heard after it. */
static double feed(lcm_t *lcm, int64_t *t, double secs, double rate, int bias_valid)
{
    for (int i = 0; i < (int)(secs * 50); i++) {
        *t += 20000;
        marie_wheel_encoders_t e = {.utime = *t, .ticks_per_rev = 4096};
        marie_gyro_t g = {.utime = *t, .yaw_rate = rate, .bias = 0.01, .bias_valid = (int8_t)bias_valid};
        marie_gyro_t_publish(lcm, "GYRO", &g);
        marie_wheel_encoders_t_publish(lcm, "WHEEL_ENCODERS", &e);
        usleep(20000);
        while (lcm_handle_timeout(lcm, 0) > 0)
            ;
    }
    int64_t until = marie_mono_us() + 300000;   /* the last 10 Hz message */
    while (marie_mono_us() < until)
        lcm_handle_timeout(lcm, 50);
    return heading;
}

static void test_heading_from_the_encoders_until_the_gyro_is_calibrated(void **state)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    char bin[512];
    snprintf(bin, sizeof bin, "%s/bin/marie-odometry", b);
    char *argv[] = {bin, "--name", "odometry", NULL};
    pid_t pid = test_spawn(argv, "/dev/null");
    assert_true(pid > 0);
    lcm_t *lcm = lcm_create(NULL);
    assert_non_null(lcm);
    marie_odometry_t_subscription_t *sub = marie_odometry_t_subscribe(lcm, "ODOMETRY", on_odometry, NULL);
    int64_t start = marie_mono_us();
    while (!heard && marie_mono_us() - start < 10000000) {   /* until it runs: a bound, not a timing check */
        marie_wheel_encoders_t e = {.utime = marie_wall_us(), .ticks_per_rev = 4096};
        marie_wheel_encoders_t_publish(lcm, "WHEEL_ENCODERS", &e);
        lcm_handle_timeout(lcm, 100);
    }
    assert_true(heard > 0);
    int64_t t = marie_wall_us();
    double uncal = feed(lcm, &t, 2.0, 0.2, 0);
    double cal = feed(lcm, &t, 1.0, 0.2, 1);
    print_message("heading after 2 s of an uncalibrated gyro at 0.2 rad/s: %.3f rad; then 1 s calibrated: %.3f rad\n",
                  uncal, cal);
    assert_true(fabs(uncal) < 0.01);            /* 0.4 rad had the rate been taken */
    assert_true(cal - uncal > 0.1);             /* the calibrated rate turns it (0.2 rad) */
    marie_odometry_t_unsubscribe(lcm, sub);
    lcm_destroy(lcm);
    test_stop(pid);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_heading_from_the_encoders_until_the_gyro_is_calibrated),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
