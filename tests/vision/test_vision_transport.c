/* test_vision_transport: 640x480 RGB frames at 30 Hz cross the default marie bus between two
 * processes without loss and bit-exact, thanks to the URL's receive buffer. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include <lcm/lcm.h>

#include "core/config.h"
#include "core/time.h"
#include "lcmtypes/marie_image_t.h"

#define W 640
#define H 480
#define N 30

static int received, intact;

static uint8_t pixel(int frame, size_t i)
{
    return (uint8_t)(i * 31 + frame * 7 + (i >> 11));
}

static void on_img(const lcm_recv_buf_t *rb, const char *ch, const marie_image_t *m, void *u)
{
    received++;
    int f = (int)m->utime;
    bool ok = m->width == W && m->height == H && m->size == W * H * 3;
    for (size_t i = 0; ok && i < (size_t)m->size; i += 997)
        ok = m->data[i] == pixel(f, i);
    intact += ok;
}

static void test_rgb_640x480_at_30hz_no_loss(void **state)
{
    const char *url = marie_default_url();
    assert_non_null(strstr(url, "recv_buf_size="));
    lcm_t *rx = lcm_create(url);
    assert_non_null(rx);
    marie_image_t_subscription_t *sub = marie_image_t_subscribe(rx, "TEST_IMAGE", on_img, NULL);
    pid_t pid = fork();
    if (pid == 0) {
        lcm_t *tx = lcm_create(url);
        static uint8_t buf[W * H * 3];
        usleep(100000);
        int64_t next = marie_mono_us();
        for (int f = 0; f < N; f++) {
            for (size_t i = 0; i < sizeof buf; i++)
                buf[i] = pixel(f, i);
            marie_image_t img = { .utime = f, .width = W, .height = H, .row_stride = W * 3,
                                  .format = MARIE_IMAGE_T_FORMAT_RGB8, .size = sizeof buf, .data = buf };
            next += 1000000 / 30;
            int64_t wait = next - marie_mono_us();
            if (wait > 0)
                usleep((useconds_t)wait);
            marie_image_t_publish(tx, "TEST_IMAGE", &img);
        }
        lcm_destroy(tx);
        _exit(0);
    }
    /* Bounded: the frames take one second; allow ten. */
    int64_t end = marie_mono_us() + 10000000;
    while (received < N && marie_mono_us() < end)
        lcm_handle_timeout(rx, 100);
    int status;
    waitpid(pid, &status, 0);
    assert_true(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    while (lcm_handle_timeout(rx, 200) > 0)
        ;
    marie_image_t_unsubscribe(rx, sub);
    lcm_destroy(rx);
    assert_int_equal(received, N);
    assert_int_equal(intact, N);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rgb_640x480_at_30hz_no_loss),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
