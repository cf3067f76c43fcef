/* test_vision_image: marie.image_t raw and JPEG frames decode to the right grey pixels, and
 * corrupt or inconsistent ones are refused with a reason instead of crashing. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "adapters/vision/vision_detect.h"
#include "camera/vision_image.h"
#include "camera/vision_render.h"
#include "tests/fails.h"

#define W 320
#define H 240
static uint8_t rgb[W * H * 3], gray[W * H];

static void make_pixels(void)
{
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            uint8_t *p = &rgb[(y * W + x) * 3];
            p[0] = (uint8_t)x;
            p[1] = (uint8_t)(y * 2);
            p[2] = (uint8_t)(x + y);
            gray[y * W + x] = (uint8_t)((x * 3 + y) & 0xff);
        }
}

static void test_raw_round_trips(void **state)
{
    make_pixels();
    vision_frame_t f = { 0 }, g = { 0 };
    marie_image_t img;
    assert_int_equal(vision_image_encode(gray, W, H, W, 1, MARIE_IMAGE_T_FORMAT_GRAY8, 0, 7, &img), 0);
    assert_int_equal(img.size, W * H);
    assert_int_equal(img.utime, 7);
    assert_int_equal(vision_image_decode(&img, &f, NULL), 0);
    assert_int_equal(f.width, W);
    assert_int_equal(f.height, H);
    assert_memory_equal(f.data, gray, W * H);
    free(img.data);
    /* RGB and BGR of the same pixels decode to the same grey. */
    assert_int_equal(vision_image_encode(rgb, W, H, W * 3, 3, MARIE_IMAGE_T_FORMAT_RGB8, 0, 0, &img), 0);
    assert_int_equal(vision_image_decode(&img, &f, NULL), 0);
    free(img.data);
    assert_int_equal(vision_image_encode(rgb, W, H, W * 3, 3, MARIE_IMAGE_T_FORMAT_BGR8, 0, 0, &img), 0);
    assert_int_equal(vision_image_decode(&img, &g, NULL), 0);
    assert_memory_equal(f.data, g.data, W * H);
    /* A red pixel is darker than a green one, as luma says. */
    assert_true(f.data[W * 10 + 200] < 255);
    free(img.data);
    /* Rows padded to a larger stride. */
    static uint8_t padded[(W + 16) * H];
    for (int y = 0; y < H; y++)
        memcpy(padded + y * (W + 16), gray + y * W, W);
    img = (marie_image_t){ .width = W, .height = H, .row_stride = W + 16, .format = MARIE_IMAGE_T_FORMAT_GRAY8,
                           .size = (W + 16) * (H - 1) + W, .data = padded };
    assert_int_equal(vision_image_decode(&img, &f, NULL), 0);
    assert_memory_equal(f.data, gray, W * H);
    vision_frame_free(&f);
    vision_frame_free(&g);
}

/* A tag survives JPEG at quality 75 and is still read. */
static void test_jpeg_keeps_tags_readable(void **state)
{
    vision_render_t *r = vision_render_create("tag36h11");
    vision_camera_t cam = { W, H, 250, 250, 159.5, 119.5 };
    vision_tag_t t = { .id = 77, .size = 0.16 };
    vision_pose_identity(&t.pose);
    t.pose.t[2] = 1.0;
    assert_int_equal(vision_render_frame(r, &cam, &t, 1, NULL, rgb, W * 3, 3), 1);
    marie_image_t img;
    assert_int_equal(vision_image_encode(rgb, W, H, W * 3, 3, MARIE_IMAGE_T_FORMAT_JPEG, 75, 0, &img), 0);
    assert_true(img.size < W * H / 4);
    vision_frame_t f = { 0 };
    assert_int_equal(vision_image_decode(&img, &f, NULL), 0);
    vision_detector_t *d = vision_detector_create(NULL, NULL, 0);
    vision_detection_t det[2];
    assert_int_equal(vision_detector_detect(d, f.data, f.width, f.height, f.stride, det, 2, NULL), 1);
    assert_int_equal(det[0].id, 77);
    vision_detector_destroy(d);
    vision_render_destroy(r);
    free(img.data);
    vision_frame_free(&f);
}

static void expect_bad(marie_image_t *img, const char *what)
{
    vision_frame_t f = { 0 };
    const char *why = NULL;
    assert_fails(vision_image_decode(img, &f, &why), EBADMSG);
    assert_non_null(why);
    if (!strstr(why, what))
        fail_msg("reason '%s' lacks '%s'", why, what);
    vision_frame_free(&f);
}

static void test_bad_images_refused(void **state)
{
    make_pixels();
    marie_image_t jpg;
    assert_int_equal(vision_image_encode(gray, W, H, W, 1, MARIE_IMAGE_T_FORMAT_JPEG, 90, 0, &jpg), 0);
    marie_image_t b = jpg;
    b.size = jpg.size / 2;
    expect_bad(&b, "Premature end");
    b = jpg;
    b.width = 640;
    expect_bad(&b, "decodes to 320x240 but the message says 640x240");
    b = jpg;
    b.data = gray;
    expect_bad(&b, "no start-of-image");
    b = jpg;
    b.size = 2;
    expect_bad(&b, "only 2 bytes");
    /* Scrambled entropy-coded data between valid markers. */
    uint8_t *scr = malloc(jpg.size);
    memcpy(scr, jpg.data, jpg.size);
    for (int i = 0; i < 40; i++)
        scr[i] = 0xff;
    scr[0] = 0xff;
    scr[1] = 0xd8;
    b = jpg;
    b.data = scr;
    expect_bad(&b, "JPEG");
    free(scr);

    marie_image_t raw = { .width = W, .height = H, .row_stride = W, .format = MARIE_IMAGE_T_FORMAT_GRAY8,
                          .size = W * H, .data = gray };
    b = raw;
    b.size = W * H - 1;
    expect_bad(&b, "needs");
    b = raw;
    b.row_stride = W - 1;
    expect_bad(&b, "row_stride");
    b = raw;
    b.format = MARIE_IMAGE_T_FORMAT_RGB8;
    expect_bad(&b, "row_stride");
    b = raw;
    b.format = 12;
    expect_bad(&b, "unknown format 12");
    b = raw;
    b.height = 0;
    expect_bad(&b, "bad size");
    b = raw;
    b.width = VISION_IMAGE_MAX_SIDE + 1;
    expect_bad(&b, "bad size");
    b = raw;
    b.size = -5;
    expect_bad(&b, "size -5");
    b = raw;
    b.data = NULL;
    expect_bad(&b, "without data");

    assert_fails(vision_image_encode(gray, W, H, W - 1, 1, MARIE_IMAGE_T_FORMAT_GRAY8, 0, 0, &b), EINVAL);
    assert_fails(vision_image_encode(gray, W, H, W, 1, MARIE_IMAGE_T_FORMAT_RGB8, 0, 0, &b), EINVAL);
    assert_fails(vision_image_encode(gray, W, H, W, 1, 9, 0, 0, &b), EINVAL);
    assert_fails(vision_image_encode(NULL, W, H, W, 1, MARIE_IMAGE_T_FORMAT_GRAY8, 0, 0, &b), EINVAL);
    free(jpg.data);
}

/* Bounded random corruption of a real JPEG: every outcome is a frame or EBADMSG. */
static void test_mutated_jpegs(void **state)
{
    make_pixels();
    marie_image_t jpg;
    assert_int_equal(vision_image_encode(gray, W, H, W, 1, MARIE_IMAGE_T_FORMAT_JPEG, 80, 0, &jpg), 0);
    uint8_t *m = malloc(jpg.size);
    vision_frame_t f = { 0 };
    uint32_t s = 12345;
    int ok = 0, refused = 0;
    for (int it = 0; it < 300; it++) {
        memcpy(m, jpg.data, jpg.size);
        int flips = 1 + it % 8;
        for (int k = 0; k < flips; k++) {
            s = s * 1103515245u + 12345u;
            m[(s >> 8) % jpg.size] ^= (uint8_t)(1u << (s % 8));
        }
        marie_image_t b = jpg;
        b.data = m;
        const char *why = NULL;
        int rc = vision_image_decode(&b, &f, &why);
        assert_true(rc == 0 || errno == EBADMSG);
        if (rc == 0) {
            /* A frame that decodes is whole: a sane size (a flipped header bit may change it),
             * every pixel inside the buffer. */
            assert_true(f.width > 0 && f.width <= 65535 && f.height > 0 && f.height <= 65535);
            assert_true(f.stride >= f.width && f.data != NULL);
            assert_true((size_t)f.stride * (size_t)f.height <= f.cap);
            ok++;
        } else {
            assert_non_null(why);
            assert_true(why[0] != '\0');
            refused++;
        }
    }
    /* Both outcomes occur, so the corruption really reaches the refusal path. */
    assert_true(ok > 0);
    assert_true(refused > 0);
    free(m);
    free(jpg.data);
    vision_frame_free(&f);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_raw_round_trips),
        cmocka_unit_test(test_jpeg_keeps_tags_readable),
        cmocka_unit_test(test_bad_images_refused),
        cmocka_unit_test(test_mutated_jpegs),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
