/* test_vision_sim: marie-vision reading the simulator's camera on a real bus (this test's
 * namespace): door signs of the office world become landmarks at the world file's place,
 * from the robot's pose at the image time, and signs listed in `messages` raise events. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include <lcm/lcm.h>

#include "core/time.h"
#include "lcmtypes/marie_types.h"
#include "tests/proc.h"

#define WALL_LIMIT_US 30000000      /* a bound on every wait, not a timing assertion */

static struct {
    int landmarks, sign_b, other;
    double worst, sum;
    double last_range;
    int events_b;
    int images;
} rx;

static void on_landmarks(const lcm_recv_buf_t *rb, const char *ch, const marie_landmarks_t *m, void *u)
{
    for (int i = 0; i < m->count; i++) {
        const marie_landmark_t *l = &m->landmarks[i];
        rx.landmarks++;
        if (l->id != 2) {
            rx.other++;
            continue;
        }
        /* Sign B per sim/worlds/office.yaml: (12.00, 13.51, 0.5), facing +y. */
        double e = sqrt(pow(l->x - 12.00, 2) + pow(l->y - 13.51, 2) + pow(l->z - 0.5, 2));
        rx.sign_b++;
        rx.sum += e;
        rx.worst = fmax(rx.worst, e);
        rx.last_range = l->range;
        assert_true(fabs(remainder(l->yaw - M_PI / 2, 2 * M_PI)) < 0.15);
        assert_string_equal(l->message, "room B");
    }
}

static void on_event(const lcm_recv_buf_t *rb, const char *ch, const marie_event_t *m, void *u)
{
    if (strcmp(m->kind, "sign") == 0 && strcmp(m->text, "room B") == 0)
        rx.events_b++;
}

static void on_image(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    rx.images++;
}

static const char *bin(const char *name)
{
    static char buf[4][256];
    static int k;
    const char *b = getenv("B") ? getenv("B") : "build";
    char *out = buf[k++ % 4];
    snprintf(out, 256, "%s/bin/%s", b, name);
    return out;
}

static void run(const char *start_y, const char *pose_channel, int want_landmarks)
{
    memset(&rx, 0, sizeof rx);
    lcm_t *lcm = lcm_create(NULL);
    assert_non_null(lcm);
    marie_landmarks_t_subscription_t *lm = marie_landmarks_t_subscribe(lcm, "LANDMARKS", on_landmarks, NULL);
    marie_event_t_subscription_t *ev = marie_event_t_subscribe(lcm, "MARIE_EVENT", on_event, NULL);
    lcm_subscribe(lcm, "CAMERA_IMAGE", on_image, NULL);
    char pose_port[64];
    snprintf(pose_port, sizeof pose_port, "pose=%s", pose_channel);
    const char *sim[] = { bin("marie-sim"), "--world", "office", "--speed", "2", "--param", "camera=true",
                          "--param", "camera_size=320x240", "--param", "start_x=12.00", "--param", start_y,
                          "--param", "start_theta=-1.5708", NULL };
    const char *vis[] = { bin("marie-vision"), "--port", pose_port, "--param", "width=320", "--param", "height=240",
                          "--param", "fx=250", "--param", "fy=250", "--param", "cx=159.5", "--param", "cy=119.5",
                          "--param", "tag_size=0.2", "--param", "decimate=1",
                          "--param", "messages=[{id: 2, message: room B, kind: sign}]", NULL };
    pid_t v = test_spawn((char *const *)vis, "/dev/null");
    pid_t s = test_spawn((char *const *)sim, "/dev/null");
    assert_true(v > 0 && s > 0);
    int64_t end = marie_mono_us() + WALL_LIMIT_US;
    while (marie_mono_us() < end && ((want_landmarks ? rx.sign_b < 20 : rx.images < 30) || rx.events_b < 1))
        lcm_handle_timeout(lcm, 100);
    test_stop(s);
    test_stop(v);
    marie_landmarks_t_unsubscribe(lcm, lm);
    marie_event_t_unsubscribe(lcm, ev);
    lcm_destroy(lcm);
}

/* The robot stands 1.5 m (camera) before sign B, the localizer's place taken by the truth. */
static void test_sign_b_becomes_a_landmark_and_an_event(void **state)
{
    run("start_y=15.2", "SIM_TRUTH", 1);
    printf("camera frames %d, sign B placed %d times at %.2f m: mean error %.3f m, worst %.3f m; other tags %d\n",
           rx.images, rx.sign_b, rx.last_range, rx.sign_b ? rx.sum / rx.sign_b : -1, rx.worst, rx.other);
    assert_true(rx.images >= 20);
    assert_true(rx.sign_b >= 20);
    assert_true(rx.worst < 0.05);
    assert_true(fabs(rx.last_range - 1.49) < 0.05);
    assert_int_equal(rx.events_b, 1);       /* read once per appearance, not per frame */
}

/* Without a robot pose, detections are published but nothing is placed in the map. */
static void test_no_pose_no_landmarks(void **state)
{
    run("start_y=15.2", "NO_POSE_HERE", 0);
    assert_int_equal(rx.landmarks, 0);
    assert_true(rx.images >= 10);
    assert_int_equal(rx.events_b, 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sign_b_becomes_a_landmark_and_an_event),
        cmocka_unit_test(test_no_pose_no_landmarks),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
