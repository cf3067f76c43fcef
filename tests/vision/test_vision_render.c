/* test_vision_render: tags rendered from the family's codes at known poses, with blur and
 * noise, are detected at the stated rate and with the stated pose accuracy. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include <apriltag/apriltag.h>

#include "adapters/vision/vision_detect.h"
#include "camera/vision_family.h"
#include "camera/vision_render.h"
#include "tests/fails.h"

#define W 640
#define H 480
static const vision_camera_t cam = { W, H, 500.0, 500.0, 319.5, 239.5 };
static uint8_t img[W * H];

static uint64_t rng_state;
static double urand(double lo, double hi)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return lo + (hi - lo) * (double)(rng_state >> 11) / (double)(1ull << 53);
}

/* A tag of `size` at a random distance and tilt whose corners all fall inside the image. */
static void random_tag(vision_tag_t *t, int id, double size, double zmin, double zmax, double tilt)
{
    for (;;) {
        t->id = id;
        t->size = size;
        double z = urand(zmin, zmax);
        double u = urand(0.15 * W, 0.85 * W), v = urand(0.15 * H, 0.85 * H);
        vision_rot_rpy(urand(-tilt, tilt), urand(-tilt, tilt), urand(-M_PI, M_PI), t->pose.R);
        t->pose.t[0] = (u - cam.cx) * z / cam.fx;
        t->pose.t[1] = (v - cam.cy) * z / cam.fy;
        t->pose.t[2] = z;
        double px[4][2];
        bool ok = vision_project_tag(&cam, &t->pose, size * 1.25, px);
        for (int k = 0; ok && k < 4; k++)
            ok = px[k][0] > 2 && px[k][0] < W - 3 && px[k][1] > 2 && px[k][1] < H - 3;
        if (ok)
            return;
    }
}

static void cells_match(const char *family)
{
    vision_render_t *r = vision_render_create(family);
    apriltag_family_t *f = vision_family_create(family);
    assert_non_null(r);
    assert_non_null(f);
    int T = vision_render_total_cells(r), bad = 0;
    assert_int_equal(T, f->total_width);
    uint8_t cells[64 * 64];
    for (uint32_t id = 0; id < f->ncodes; id++) {
        assert_int_equal(vision_render_tag_cells(r, (int)id, cells, 64), 0);
        image_u8_t *im = apriltag_to_image(f, (int)id);
        for (int y = 0; y < T; y++)
            for (int x = 0; x < T; x++)
                bad += cells[y * 64 + x] != im->buf[y * im->stride + x];
        image_u8_destroy(im);
    }
    assert_int_equal(bad, 0);
    vision_family_destroy(f);
    vision_render_destroy(r);
}

/* Our drawing of every code matches libapriltag's own reference image, cell for cell. */
static void test_cells_match_library(void **state)
{
    cells_match("tag36h11");
    cells_match("tag25h9");
    cells_match("tag16h5");
    cells_match("tagStandard41h12");
    cells_match("tagCircle21h7");
}

typedef struct {
    int frames, detected, wrong_id;
    double terr[64], rerr[64];      /* relative translation error, rotation error (deg) */
    double cerr[64];                /* mean corner error, px */
} stats_t;

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double percentile(double *v, int n, double p)
{
    qsort(v, n, sizeof *v, cmp_double);
    int i = (int)ceil(p * n) - 1;
    return v[i < 0 ? 0 : i];
}

static void run_poses(stats_t *s, int frames, double noise, double blur, vision_bg_t bg, double zmax, double tilt)
{
    vision_render_t *r = vision_render_create("tag36h11");
    vision_detector_t *d = vision_detector_create(NULL, NULL, 0);
    assert_non_null(r);
    assert_non_null(d);
    assert_int_equal(vision_detector_set_camera(d, &cam, 0.16, NULL), 0);
    vision_render_opts_t o;
    vision_render_opts_default(&o);
    o.noise_sigma = noise;
    o.blur_sigma = blur;
    o.background = bg;
    memset(s, 0, sizeof *s);
    for (int i = 0; i < frames && i < 64; i++) {
        vision_tag_t t;
        int id = (int)urand(0, 587);
        random_tag(&t, id, 0.16, 0.5, zmax, tilt);
        o.seed = 1000 + i;
        assert_int_equal(vision_render_frame(r, &cam, &t, 1, &o, img, W, 1), 1);
        vision_detection_t det[8];
        int n = vision_detector_detect(d, img, W, H, W, det, 8, NULL);
        s->frames++;
        for (int k = 0; k < n && k < 8; k++) {
            if (det[k].id != id) {
                s->wrong_id++;
                continue;
            }
            double dt = 0;
            for (int j = 0; j < 3; j++)
                dt += (det[k].pose.t[j] - t.pose.t[j]) * (det[k].pose.t[j] - t.pose.t[j]);
            s->terr[s->detected] = sqrt(dt) / t.pose.t[2];
            s->rerr[s->detected] = vision_rot_angle_between(det[k].pose.R, t.pose.R) * 180 / M_PI;
            double px[4][2], ce = 0;
            vision_project_tag(&cam, &t.pose, t.size, px);
            for (int j = 0; j < 4; j++)
                ce += hypot(det[k].corners[j][0] - px[j][0], det[k].corners[j][1] - px[j][1]) / 4;
            s->cerr[s->detected] = ce;
            s->detected++;
        }
    }
    vision_detector_destroy(d);
    vision_render_destroy(r);
    if (s->detected)
        print_message("frames %d detected %d wrong %d  t-err p50 %.4f p95 %.4f  r-err p50 %.2f p95 %.2f deg"
                      "  corner p50 %.2f p95 %.2f px\n",
                      s->frames, s->detected, s->wrong_id, percentile(s->terr, s->detected, 0.5),
                      percentile(s->terr, s->detected, 0.95), percentile(s->rerr, s->detected, 0.5),
                      percentile(s->rerr, s->detected, 0.95), percentile(s->cerr, s->detected, 0.5),
                      percentile(s->cerr, s->detected, 0.95));
}

/* Moderate noise (sigma 4 grey levels) and blur (sigma 0.8 px), 0.16 m tags at 0.5-3 m,
 * tilted up to 40 degrees: >= 95% detected, no wrong ids, translation error <= 2% of the
 * distance and rotation error <= 5 degrees for 90% of the detections, and corners within
 * 0.3 px of their projection for half of them (a half-pixel convention slip shows here). */
static void test_detect_known_poses(void **state)
{
    stats_t s;
    rng_state = 0x1234567;
    run_poses(&s, 60, 4.0, 0.8, VISION_BG_FLAT, 3.0, 40 * M_PI / 180);
    assert_true(s.detected >= 0.95 * s.frames);
    assert_int_equal(s.wrong_id, 0);
    assert_true(percentile(s.terr, s.detected, 0.9) <= 0.02);
    assert_true(percentile(s.rerr, s.detected, 0.9) <= 5.0);
    assert_true(percentile(s.cerr, s.detected, 0.5) <= 0.3);
}

/* Heavy noise (sigma 10) and blur (sigma 1.5 px) over clutter, up to 2 m: >= 85% detected,
 * no wrong ids, translation error <= 4% of the distance for 90%. */
static void test_detect_heavy_noise_blur(void **state)
{
    stats_t s;
    rng_state = 0x7654321;
    run_poses(&s, 40, 10.0, 1.5, VISION_BG_CLUTTER, 2.0, 30 * M_PI / 180);
    assert_true(s.detected >= 0.85 * s.frames);
    assert_int_equal(s.wrong_id, 0);
    assert_true(percentile(s.terr, s.detected, 0.9) <= 0.04);
}

/* Three tags in one frame, the nearest partly covering another: every visible id is read. */
static void test_several_tags_and_occlusion(void **state)
{
    vision_render_t *r = vision_render_create("tag36h11");
    vision_detector_t *d = vision_detector_create(NULL, NULL, 0);
    vision_tag_t t[4];
    for (int i = 0; i < 4; i++) {
        t[i].id = 10 * i + 1;
        t[i].size = 0.16;
        vision_pose_identity(&t[i].pose);
        t[i].pose.t[2] = 1.5;
    }
    t[0].pose.t[0] = -0.6;
    t[1].pose.t[0] = 0.0;
    t[2].pose.t[0] = 0.6;
    /* id 31 sits in front of id 11 and hides it completely. */
    t[3].pose.t[2] = 0.8;
    t[3].size = 0.2;
    vision_render_opts_t o;
    vision_render_opts_default(&o);
    o.noise_sigma = 3;
    assert_int_equal(vision_render_frame(r, &cam, t, 4, &o, img, W, 1), 4);
    vision_detection_t det[8];
    int n = vision_detector_detect(d, img, W, H, W, det, 8, NULL);
    assert_int_equal(n, 3);
    assert_int_equal(det[0].id, 1);
    assert_int_equal(det[1].id, 21);
    assert_int_equal(det[2].id, 31);
    vision_detector_destroy(d);
    vision_render_destroy(r);
}

/* A tag on a wall 3 m ahead of a camera mounted 0.5 m up shows up 3 m along the optical
 * axis, upright; the renderer's world API is what the simulator calls. */
static void test_world_placement(void **state)
{
    vision_render_t *r = vision_render_create("tag36h11");
    vision_detector_t *d = vision_detector_create(NULL, NULL, 0);
    vision_detector_set_camera(d, &cam, 0.2, NULL);
    vision_pose_t camw;
    vision_pose_camera_in_world(1.0, 2.0, 0.5, M_PI / 2, 0.0, &camw);
    vision_tag_t t = { .id = 42, .size = 0.2 };
    vision_pose_tag_on_wall(1.0, 5.0, 0.5, -M_PI / 2, &t.pose);   /* faces the camera */
    vision_render_opts_t o;
    vision_render_opts_default(&o);
    assert_int_equal(vision_render_world(r, &cam, &camw, &t, 1, &o, img, W, 1), 1);
    vision_detection_t det[2];
    assert_int_equal(vision_detector_detect(d, img, W, H, W, det, 2, NULL), 1);
    assert_int_equal(det[0].id, 42);
    assert_true(fabs(det[0].pose.t[0]) < 0.01 && fabs(det[0].pose.t[1]) < 0.01);
    assert_true(fabs(det[0].pose.t[2] - 3.0) < 0.03);
    double I[9] = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
    assert_true(vision_rot_angle_between(det[0].pose.R, I) < 3 * M_PI / 180);
    /* Turned away (printed face towards +y): its back is blank paper. */
    vision_pose_tag_on_wall(1.0, 5.0, 0.5, M_PI / 2, &t.pose);
    assert_int_equal(vision_render_world(r, &cam, &camw, &t, 1, &o, img, W, 1), 1);
    assert_int_equal(vision_detector_detect(d, img, W, H, W, det, 2, NULL), 0);
    vision_detector_destroy(d);
    vision_render_destroy(r);
}

/* Cluttered frames without tags yield no detections. */
static void test_no_false_positives(void **state)
{
    vision_render_t *r = vision_render_create("tag36h11");
    vision_detector_t *d = vision_detector_create(NULL, NULL, 0);
    vision_render_opts_t o;
    vision_render_opts_default(&o);
    o.background = VISION_BG_CLUTTER;
    o.noise_sigma = 6;
    int total = 0;
    for (int i = 0; i < 10; i++) {
        o.seed = 77 + i;
        assert_int_equal(vision_render_frame(r, &cam, NULL, 0, &o, img, W, 1), 0);
        total += vision_detector_detect(d, img, W, H, W, NULL, 0, NULL);
    }
    assert_int_equal(total, 0);
    vision_detector_destroy(d);
    vision_render_destroy(r);
}

/* Bad arguments are refused with -1 (errno EINVAL) or NULL and a reason, never a crash. */
static void test_bad_arguments(void **state)
{
    assert_null(vision_render_create("tag99h99"));
    vision_render_t *r = vision_render_create("tag36h11");
    vision_tag_t t = { .id = 587, .size = 0.1 };
    vision_pose_identity(&t.pose);
    t.pose.t[2] = 1;
    assert_fails(vision_render_frame(r, &cam, &t, 1, NULL, img, W, 1), EINVAL);
    t.id = 0;
    vision_camera_t bad = cam;
    bad.fx = 0;
    assert_fails(vision_render_frame(r, &bad, &t, 1, NULL, img, W, 1), EINVAL);
    assert_fails(vision_render_frame(r, &cam, &t, 1, NULL, img, W - 1, 1), EINVAL);
    assert_fails(vision_render_frame(r, &cam, &t, 1, NULL, img, W, 2), EINVAL);
    /* Behind the camera: drawn nowhere. */
    t.pose.t[2] = -1;
    assert_int_equal(vision_render_frame(r, &cam, &t, 1, NULL, img, W, 1), 0);
    assert_fails(vision_render_tag_cells(r, -1, img, 64), EINVAL);
    vision_render_destroy(r);

    char err[256] = "";
    vision_detector_opts_t o;
    vision_detector_opts_default(&o);
    o.family = "tag37h12";
    assert_null(vision_detector_create(&o, err, sizeof err));
    assert_non_null(strstr(err, "unknown tag family 'tag37h12'"));
    vision_detector_opts_default(&o);
    o.decimate = 0.5;
    assert_null(vision_detector_create(&o, err, sizeof err));
    assert_non_null(strstr(err, "decimate"));

    /* Wrong intrinsics: refused with a reason; a frame of another size gets no pose. */
    vision_detector_t *d = vision_detector_create(NULL, err, sizeof err);
    const char *why = NULL;
    bad = cam;
    bad.cx = 900;
    assert_fails(vision_detector_set_camera(d, &bad, 0.16, &why), EINVAL);
    assert_non_null(strstr(why, "principal point"));
    bad = cam;
    bad.fy = NAN;
    assert_fails(vision_detector_set_camera(d, &bad, 0.16, &why), EINVAL);
    assert_fails(vision_detector_set_camera(d, &cam, -1, &why), EINVAL);
    assert_non_null(strstr(why, "tag_size"));
    assert_int_equal(vision_detector_set_camera(d, &cam, 0.16, &why), 0);
    vision_render_t *rr = vision_render_create("tag36h11");
    vision_camera_t small = { 320, 240, 250, 250, 159.5, 119.5 };
    t.pose.t[2] = 1;
    assert_int_equal(vision_render_frame(rr, &small, &t, 1, NULL, img, 320, 1), 1);
    vision_detection_t det[2];
    bool skipped = false;
    assert_int_equal(vision_detector_detect(d, img, 320, 240, 320, det, 2, &skipped), 1);
    assert_true(skipped);
    assert_false(det[0].pose_valid);
    assert_fails(vision_detector_detect(d, img, 0, 240, 320, det, 2, NULL), EINVAL);
    assert_fails(vision_detector_detect(d, img, 320, 240, 100, det, 2, NULL), EINVAL);
    vision_render_destroy(rr);
    vision_detector_destroy(d);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cells_match_library),
        cmocka_unit_test(test_detect_known_poses),
        cmocka_unit_test(test_detect_heavy_noise_blur),
        cmocka_unit_test(test_several_tags_and_occlusion),
        cmocka_unit_test(test_world_placement),
        cmocka_unit_test(test_no_false_positives),
        cmocka_unit_test(test_bad_arguments),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
