/* test_sim_camera: the simulator's camera in the office world: door signs are read from the
 * corridor and placed where the world file put them, signs behind walls are not seen, and
 * mistakes in the world file's camera are located. Prints detection distance and pose error. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "adapters/vision/vision_detect.h"
#include "camera/vision_image.h"
#include "camera/vision_simcam.h"
#include "sim/camera.h"

#define WORLD "sim/worlds/office.yaml"

typedef struct {
    vision_simcam_t *cam;
    vision_detector_t *det;
    vision_tag_t *tags;
    size_t n;
    vision_frame_t f;
} fix_t;

static void fix_open(fix_t *x, double decimate)
{
    marie_errors_t errs = { 0 };
    marie_doc_t *doc = marie_doc_load(WORLD, &errs);
    assert_non_null(doc);
    vision_simcam_opts_t o;
    vision_simcam_opts_default(&o);
    const marie_node_t *root = marie_doc_root(doc);
    assert_int_equal(vision_simcam_parse(marie_node_get(root, "camera"), marie_node_get(root, "tags"), &o, &x->tags,
                                         &x->n, &errs), 0);
    char err[256];
    x->cam = vision_simcam_create(&o, x->tags, x->n, err, sizeof err);
    assert_non_null(x->cam);
    marie_doc_destroy(doc);
    occmap_t *m = occmap_load(WORLD, &errs);
    assert_non_null(m);
    assert_int_equal(vision_simcam_set_walls(x->cam, m), 0);
    occmap_destroy(m);
    vision_detector_opts_t d;
    vision_detector_opts_default(&d);
    d.decimate = decimate;
    x->det = vision_detector_create(&d, err, sizeof err);
    assert_non_null(x->det);
    assert_int_equal(vision_detector_set_camera(x->det, &vision_simcam_opts(x->cam)->cam, 0.2, NULL), 0);
}

static void fix_close(fix_t *x)
{
    vision_simcam_destroy(x->cam);
    vision_detector_destroy(x->det);
    vision_frame_free(&x->f);
    free(x->tags);
}

/* Renders with the robot at (rx, ry, rt) and detects; returns the detection of tag `id`
 * (NULL if not found) with *err the distance between its map position and the truth. */
static const vision_detection_t *see(fix_t *x, double rx, double ry, double rt, int id, double *err, int *ndet)
{
    static vision_detection_t d[16];
    marie_image_t img;
    assert_true(vision_simcam_render(x->cam, rx, ry, rt, 1, &img) >= 0);
    assert_int_equal(vision_image_decode(&img, &x->f, NULL), 0);
    int n = vision_detector_detect(x->det, x->f.data, x->f.width, x->f.height, x->f.stride, d, 16, NULL);
    assert_true(n >= 0);
    if (ndet)
        *ndet = n;
    for (int i = 0; i < n && i < 16; i++) {
        if (d[i].id != id || !d[i].pose_valid)
            continue;
        vision_pose_t cam, tag;
        vision_simcam_camera_pose(x->cam, rx, ry, rt, &cam);
        vision_pose_compose(&cam, &d[i].pose, &tag);
        const double *t = x->tags[id - 1].pose.t;
        *err = sqrt(pow(tag.t[0] - t[0], 2) + pow(tag.t[1] - t[1], 2) + pow(tag.t[2] - t[2], 2));
        return &d[i];
    }
    return NULL;
}

/* Facing each of the 12 door signs squarely from 0.8 to 2.6 m: the right id, placed in the
 * map within 3% of the distance (the vision adapter's landmarks rest on this). */
static void test_signs_read_facing_them(void **state)
{
    fix_t x = { 0 };
    fix_open(&x, 2.0);
    assert_int_equal(x.n, 12);
    const double dist[] = { 0.8, 1.4, 2.0, 2.6 };
    int found = 0, total = 0, hidden = 0;
    double worst[4] = { 0 };
    for (size_t k = 0; k < x.n; k++) {
        const double *t = x.tags[k].pose.t;
        double side = t[1] < 15 ? 1 : -1;             /* south-wall signs face +y */
        for (int j = 0; j < 4; j++) {
            double err = 0;
            /* The camera sits 0.2 m ahead of the robot's origin. */
            double ry = t[1] + side * (dist[j] + 0.2), rt = side > 0 ? -M_PI / 2 : M_PI / 2;
            if (!vision_simcam_tag_visible(x.cam, k, t[0], ry, rt)) {
                hidden++;          /* the pillar at x 5.0-5.4 stands before signs A and G */
                assert_true(fabs(t[0] - 5.2) < 0.5);
                continue;
            }
            total++;
            if (see(&x, t[0], ry, rt, x.tags[k].id, &err, NULL)) {
                found++;
                worst[j] = fmax(worst[j], err);
                assert_true(err < 0.03 * dist[j] + 0.01);
            }
        }
    }
    printf("signs facing them: %d/%d read (%d views behind the pillar); worst map position error at 0.8/1.4/2.0/2.6 m: %.3f %.3f %.3f %.3f m\n",
           found, total, hidden, worst[0], worst[1], worst[2], worst[3]);
    assert_int_equal(found, total);
    assert_true(hidden <= 6);
    fix_close(&x);
}

/* Driving down the corridor's middle, looking ahead: how far ahead a sign on the side wall is
 * first read (it is seen obliquely: 1.5 m to the side). */
static void test_signs_read_while_driving(void **state)
{
    for (int pass = 0; pass < 2; pass++) {
        double dec = pass ? 1.0 : 2.0;
        fix_t x = { 0 };
        fix_open(&x, dec);
        const double *t = x.tags[1].pose.t;            /* room B, south wall, x 12.25 */
        double first = -1, worst = 0;
        int seen = 0;
        for (double ahead = 6.0; ahead >= 0.6; ahead -= 0.2) {
            double err;
            if (see(&x, t[0] - ahead - 0.2, 15.0, 0.0, 2, &err, NULL)) {
                if (first < 0)
                    first = ahead;
                seen++;
                worst = fmax(worst, err);
            }
        }
        printf("driving by sign B (1.5 m aside), decimate %.0f: first read %.1f m ahead, read in %d of 28 frames, "
               "worst position error %.3f m\n", dec, first, seen, worst);
        assert_true(first >= 2.0);
        assert_true(worst < 0.15);
        fix_close(&x);
    }
}

/* From inside room B, facing the wall whose corridor side carries sign B: not visible, not
 * detected; the same sign from the corridor is visible. */
static void test_sign_behind_a_wall_is_not_seen(void **state)
{
    fix_t x = { 0 };
    fix_open(&x, 2.0);
    const double *t = x.tags[1].pose.t;
    assert_false(vision_simcam_tag_visible(x.cam, 1, t[0], t[1] - 1.5, M_PI / 2));
    double err;
    int ndet = -1;
    assert_null(see(&x, t[0], t[1] - 1.5, M_PI / 2, 2, &err, &ndet));
    assert_int_equal(ndet, 0);
    assert_true(vision_simcam_tag_visible(x.cam, 1, t[0], t[1] + 1.5, -M_PI / 2));
    /* Facing away: not in view. */
    assert_false(vision_simcam_tag_visible(x.cam, 1, t[0], t[1] + 1.5, M_PI / 2));
    fix_close(&x);
}

/* The simulator's wrapper: a 320x240 camera scales the intrinsics, frames fall at camera_hz,
 * and mistakes in the world file are reported with their place. */
static void test_sim_camera_config(void **state)
{
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load(WORLD, &errs);
    assert_non_null(m);
    char why[512];
    sim_camera_cfg_t cfg = { .hz = 10, .step = 0.005, .width = 320, .height = 240 };
    sim_camera_t *c = sim_camera_create(WORLD, m, &cfg, why, sizeof why);
    assert_non_null(c);
    assert_int_equal(sim_camera_tags(c), 12);
    marie_image_t img;
    int frames = 0;
    for (int k = 0; k < 200; k++) {       /* 1 s of 5 ms steps */
        int rc = sim_camera_step(c, k, 12.25, 15.2, -M_PI / 2, k * 5000, &img);
        assert_true(rc >= 0);
        if (rc == 1) {
            frames++;
            assert_int_equal(img.width, 320);
            assert_int_equal(img.height, 240);
        }
    }
    assert_int_equal(frames, 10);
    /* The last frame, half size with fx 250: sign B is read 1.5 m ahead. */
    vision_frame_t f = { 0 };
    assert_int_equal(vision_image_decode(&img, &f, NULL), 0);
    char err[128];
    vision_detector_t *det = vision_detector_create(NULL, err, sizeof err);
    vision_camera_t k = { 320, 240, 250, 250, 159.5, 119.5 };
    vision_detector_set_camera(det, &k, 0.2, NULL);
    vision_detection_t d[4];
    assert_int_equal(vision_detector_detect(det, f.data, f.width, f.height, f.stride, d, 4, NULL), 1);
    assert_int_equal(d[0].id, 2);
    assert_true(fabs(d[0].pose.t[2] - 1.5) < 0.05);
    vision_detector_destroy(det);
    vision_frame_free(&f);
    sim_camera_destroy(c);

    /* A mistake in the world file: its file:line. */
    const char *bad = "/tmp/test_sim_camera_bad.yaml";
    FILE *fp = fopen(bad, "w");
    assert_non_null(fp);
    fprintf(fp, "image: office.pgm\nresolution: 0.05\ncamera: {width: 640, fx: -3}\n");
    fclose(fp);
    assert_null(sim_camera_create(bad, m, &cfg, why, sizeof why));
    assert_non_null(strstr(why, "test_sim_camera_bad.yaml:3"));
    fp = fopen(bad, "w");
    fprintf(fp, "image: office.pgm\ntags:\n  - {id: 1, x: 2, y: 3, colour: red}\n");
    fclose(fp);
    assert_null(sim_camera_create(bad, m, &cfg, why, sizeof why));
    assert_non_null(strstr(why, ":3:"));
    assert_non_null(strstr(why, "colour"));
    cfg.hz = 0;
    assert_null(sim_camera_create(WORLD, m, &cfg, why, sizeof why));
    assert_non_null(strstr(why, "camera_hz"));
    remove(bad);
    occmap_destroy(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_signs_read_facing_them),
        cmocka_unit_test(test_signs_read_while_driving),
        cmocka_unit_test(test_sign_behind_a_wall_is_not_seen),
        cmocka_unit_test(test_sim_camera_config),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
