/* hw_vm_check: the LCM side of the VM test: waits for marie-drives to report the drives
 * enabled, commands v = 0.5 m/s, omega = 0.4 rad/s for a while and prints what the drivers
 * published (key=value lines) for the test script to compare with candump's view. */
#include <lcm/lcm.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/config.h"
#include "core/time.h"
#include "lcmtypes/marie_gyro_t.h"
#include "lcmtypes/marie_motor_command_t.h"
#include "lcmtypes/marie_wheel_encoders_t.h"

static marie_wheel_encoders_t enc;
static int nenc, ngyro;
static double yaw, bias;
static int64_t gyro_utime;
static int bias_valid;

static void on_enc(const lcm_recv_buf_t *rb, const char *ch, const marie_wheel_encoders_t *m, void *u)
{
    enc = *m;
    nenc++;
}

static void on_gyro(const lcm_recv_buf_t *rb, const char *ch, const marie_gyro_t *m, void *u)
{
    yaw = m->yaw_rate;
    gyro_utime = m->utime;
    bias = m->bias;
    bias_valid = m->bias_valid;
    ngyro++;
}

int main(int argc, char **argv)
{
    double seconds = argc > 1 ? atof(argv[1]) : 3;
    lcm_t *lcm = lcm_create(marie_default_url());
    if (!lcm) {
        fprintf(stderr, "hw_vm_check: no LCM\n");
        return 1;
    }
    marie_wheel_encoders_t_subscription_t *se = marie_wheel_encoders_t_subscribe(lcm, "WHEEL_ENCODERS", on_enc, NULL);
    marie_gyro_t_subscription_t *sg = marie_gyro_t_subscribe(lcm, "GYRO", on_gyro, NULL);
    int64_t t0 = marie_mono_us(), last = 0, moving_since = 0;
    int enabled = 0;
    while (marie_mono_us() - t0 < 60000000) {
        lcm_handle_timeout(lcm, 20);
        int64_t now = marie_mono_us();
        if (!enabled && nenc && enc.status == MARIE_WHEEL_ENCODERS_T_STATUS_OK) {
            enabled = 1;
            moving_since = now;
            printf("enabled_after_s=%.2f\n", (now - t0) / 1e6);
        }
        if (enabled && now - last >= 100000) {
            marie_motor_command_t m = { .utime = marie_wall_us(), .v = 0.5, .omega = 0.4, .source = "vm" };
            marie_motor_command_t_publish(lcm, "MOTOR_COMMAND", &m);
            last = now;
        }
        if (enabled && now - moving_since > (int64_t)(seconds * 1e6))
            break;
    }
    printf("encoders=%d\ngyro=%d\nstatus=%d\n", nenc, ngyro, enc.status);
    printf("left_velocity=%.4f\nright_velocity=%.4f\nleft_ticks=%d\nright_ticks=%d\n", enc.left_velocity,
           enc.right_velocity, enc.left_ticks, enc.right_ticks);
    printf("yaw_rate=%.4f\nbias=%.4f\nbias_valid=%d\n", yaw, bias, bias_valid);
    /* when the drivers published these (wall clock), to find the frames behind them */
    printf("enc_time=%.6f\ngyro_time=%.6f\n", enc.utime / 1e6, gyro_utime / 1e6);
    marie_wheel_encoders_t_unsubscribe(lcm, se);
    marie_gyro_t_unsubscribe(lcm, sg);
    lcm_destroy(lcm);
    int ok = enabled && fabs(enc.left_velocity - 4.0) < 0.05 && fabs(enc.right_velocity - 6.0) < 0.05 &&
             ngyro > 0 && fabs(yaw + bias - 0.41) < 0.03;
    return ok ? 0 : 1;
}
