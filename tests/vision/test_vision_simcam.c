/* test_vision_simcam: the simulator's camera: tags placed in the world from YAML are seen
 * where they should be as the robot moves and turns; config mistakes are located. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "adapters/vision/vision_detect.h"
#include "camera/vision_image.h"
#include "camera/vision_simcam.h"
#include "tests/fails.h"

static const char *yaml =
    "camera: {width: 640, height: 480, fx: 500, fy: 500, mount_x: 0, mount_z: 0.5, noise: 3, blur: 0.6,\n"
    "         format: jpeg, background: gradient}\n"
    "tags:\n"
    "  - {id: 3, x: 3.0, y: 0.2, z: 0.5, yaw: 3.14159265, size: 0.2}\n"
    "  - {id: 9, x: -3.0, y: 0.0, yaw: 0.0, size: 0.2}\n";

typedef struct {
    vision_simcam_t *cam;
    vision_detector_t *det;
    vision_frame_t f;
} fix_t;

static int see(fix_t *x, double rx, double ry, double rt, vision_detection_t *d, int max)
{
    marie_image_t img;
    int drawn = vision_simcam_render(x->cam, rx, ry, rt, 123, &img);
    assert_true(drawn >= 0);
    assert_int_equal(img.format, MARIE_IMAGE_T_FORMAT_JPEG);
    assert_int_equal(img.utime, 123);
    assert_int_equal(vision_image_decode(&img, &x->f, NULL), 0);
    return vision_detector_detect(x->det, x->f.data, x->f.width, x->f.height, x->f.stride, d, max, NULL);
}

static void test_world_tags_seen_from_robot_poses(void **state)
{
    marie_errors_t errs = { 0 };
    marie_doc_t *doc = marie_doc_parse("world.yaml", yaml, strlen(yaml), &errs);
    assert_non_null(doc);
    const marie_node_t *root = marie_doc_root(doc);
    vision_simcam_opts_t o;
    vision_simcam_opts_default(&o);
    vision_tag_t *tags;
    size_t n;
    assert_int_equal(vision_simcam_parse(marie_node_get(root, "camera"), marie_node_get(root, "tags"), &o, &tags, &n, &errs), 0);
    assert_int_equal(n, 2);
    char err[128];
    fix_t x = { 0 };
    x.cam = vision_simcam_create(&o, tags, n, err, sizeof err);
    assert_non_null(x.cam);
    free(tags);
    marie_doc_destroy(doc);     /* the simcam keeps copies */
    x.det = vision_detector_create(NULL, err, sizeof err);
    vision_detector_set_camera(x.det, &o.cam, 0.2, NULL);

    vision_detection_t d[4];
    /* At the origin facing +x: tag 3 three metres ahead, 0.2 m to the left (x right in the image). */
    assert_int_equal(see(&x, 0, 0, 0, d, 4), 1);
    assert_int_equal(d[0].id, 3);
    assert_true(fabs(d[0].pose.t[0] + 0.2) < 0.02 && fabs(d[0].pose.t[1]) < 0.02 && fabs(d[0].pose.t[2] - 3.0) < 0.05);
    /* A metre closer. */
    assert_int_equal(see(&x, 1.0, 0, 0, d, 4), 1);
    assert_true(fabs(d[0].pose.t[2] - 2.0) < 0.04);
    /* Turned around: tag 9, not 3. */
    assert_int_equal(see(&x, 0, 0, M_PI, d, 4), 1);
    assert_int_equal(d[0].id, 9);
    assert_true(fabs(d[0].pose.t[0]) < 0.02 && fabs(d[0].pose.t[2] - 3.0) < 0.05);
    /* Facing +y: nothing in view. */
    assert_int_equal(see(&x, 0, 0, M_PI / 2, d, 4), 0);
    /* Behind tag 3 looking at its back: blank. */
    assert_int_equal(see(&x, 4.0, 0.2, M_PI, d, 4), 0);
    vision_frame_free(&x.f);
    vision_detector_destroy(x.det);
    vision_simcam_destroy(x.cam);
}

static void expect_error(const char *text, const char *what)
{
    marie_errors_t errs = { 0 };
    marie_doc_t *doc = marie_doc_parse("world.yaml", text, strlen(text), &errs);
    assert_non_null(doc);
    const marie_node_t *root = marie_doc_root(doc);
    vision_simcam_opts_t o;
    vision_simcam_opts_default(&o);
    vision_tag_t *tags;
    size_t n;
    assert_fails(vision_simcam_parse(marie_node_get(root, "camera"), marie_node_get(root, "tags"), &o, &tags, &n, &errs), EINVAL);
    assert_null(tags);
    bool found = false;
    for (size_t i = 0; i < errs.n; i++)
        found |= strstr(errs.msgs[i], "world.yaml:") && strstr(errs.msgs[i], what);
    if (!found) {
        marie_errors_print(&errs, stderr);
        fail_msg("no error saying '%s'", what);
    }
    marie_errors_clear(&errs);
    marie_doc_destroy(doc);
}

static void test_config_mistakes(void **state)
{
    expect_error("camera: {lens: fisheye}\n", "lens");
    expect_error("camera: {format: png}\n", "format");
    expect_error("camera: {cx: 900}\n", "principal point");
    expect_error("camera: {fx: -1}\n", "focal");
    expect_error("tags: [{x: 1, y: 2}]\n", "needs id, x and y");
    expect_error("tags: [{id: 1, x: 1, y: 2, size: 0}]\n", "size > 0");
    expect_error("tags: {id: 1}\n", "expected a list");
    vision_simcam_opts_t o;
    vision_simcam_opts_default(&o);
    vision_tag_t t = { .id = 600, .size = 0.1 };
    char err[128];
    assert_null(vision_simcam_create(&o, &t, 1, err, sizeof err));
    assert_non_null(strstr(err, "not in tag36h11"));
    o.family = "tag13h1";
    assert_null(vision_simcam_create(&o, NULL, 0, err, sizeof err));
    assert_non_null(strstr(err, "unknown tag family"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_world_tags_seen_from_robot_poses),
        cmocka_unit_test(test_config_mistakes),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
