/* test_vision_track: tags keep one track id while in view, get a new one after being lost,
 * are confirmed after min_hits frames, and their smoothed pose follows the measurements. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "adapters/vision/vision_track.h"

typedef struct {
    int news, confirmed, lost;
    int last_tag;
} counts_t;

static void on_ev(void *user, const vision_track_t *t, vision_track_event_t ev)
{
    counts_t *c = user;
    c->last_tag = t->tag_id;
    if (ev == VISION_TRACK_NEW) c->news++;
    if (ev == VISION_TRACK_CONFIRMED) c->confirmed++;
    if (ev == VISION_TRACK_LOST) c->lost++;
}

static vision_detection_t det(int id, double z)
{
    vision_detection_t d;
    memset(&d, 0, sizeof d);
    d.id = id;
    d.pose_valid = true;
    vision_pose_identity(&d.pose);
    d.pose.t[2] = z;
    return d;
}

static void test_ids_hits_and_loss(void **state)
{
    vision_tracker_opts_t o = { 0.5, 300000, 3 };
    vision_tracker_t *t = vision_tracker_create(&o);
    counts_t c = { 0 };
    const vision_track_t *out[2];
    vision_detection_t d[2] = { det(4, 1.0), det(9, 2.0) };
    int first = 0;
    for (int f = 0; f < 5; f++) {
        assert_int_equal(vision_tracker_update(t, 1000000 + f * 100000, d, 2, out, on_ev, &c), 0);
        if (f == 0)
            first = out[0]->track_id;
        assert_int_equal(out[0]->track_id, first);
        assert_int_not_equal(out[1]->track_id, first);
        assert_int_equal(out[0]->hits, f + 1);
        assert_int_equal(out[0]->first_seen_us, 1000000);
        assert_int_equal(out[0]->last_seen_us, 1000000 + f * 100000);
        assert_int_equal(out[0]->confirmed, f >= 2);
    }
    assert_int_equal(c.news, 2);
    assert_int_equal(c.confirmed, 2);
    assert_int_equal(vision_tracker_count(t), 2);
    /* Only tag 4 stays in view; 9 is lost once 0.3 s have passed. */
    vision_tracker_update(t, 1600000, d, 1, out, on_ev, &c);
    assert_int_equal(c.lost, 0);
    vision_tracker_update(t, 1800000, d, 1, out, on_ev, &c);
    assert_int_equal(c.lost, 1);
    assert_int_equal(c.last_tag, 9);
    assert_int_equal(vision_tracker_count(t), 1);
    /* Tag 9 again: a new track, confirmed anew. */
    vision_tracker_update(t, 1900000, &d[1], 1, out, on_ev, &c);
    assert_true(out[0]->track_id > first + 1);
    assert_int_equal(out[0]->hits, 1);
    assert_int_equal(c.news, 3);
    /* Everything expires on a timer too. */
    vision_tracker_expire(t, 5000000, on_ev, &c);
    assert_int_equal(vision_tracker_count(t), 0);
    assert_int_equal(c.lost, 3);
    vision_tracker_destroy(t);
}

/* The same id twice in one frame (two printed copies) counts once per frame. */
static void test_duplicate_ids_in_one_frame(void **state)
{
    vision_tracker_t *t = vision_tracker_create(NULL);
    const vision_track_t *out[2];
    vision_detection_t d[2] = { det(1, 1.0), det(1, 3.0) };
    vision_tracker_update(t, 0, d, 2, out, NULL, NULL);
    assert_ptr_equal(out[0], out[1]);
    assert_int_equal(out[0]->hits, 1);
    assert_true(fabs(out[0]->pose.t[2] - 1.0) < 1e-12);
    vision_tracker_destroy(t);
}

/* Smoothing: a step in position is approached geometrically; rotation is blended too. */
static void test_smoothing(void **state)
{
    vision_tracker_opts_t o = { 0.5, 1000000, 1 };
    vision_tracker_t *t = vision_tracker_create(&o);
    const vision_track_t *out[1];
    vision_detection_t d = det(2, 1.0);
    vision_tracker_update(t, 0, &d, 1, out, NULL, NULL);
    d.pose.t[2] = 2.0;
    vision_rot_rpy(0, 0, 0.4, d.pose.R);
    vision_tracker_update(t, 1, &d, 1, out, NULL, NULL);
    assert_true(fabs(out[0]->pose.t[2] - 1.5) < 1e-9);
    double I[9] = { 1, 0, 0, 0, 1, 0, 0, 0, 1 };
    assert_true(fabs(vision_rot_angle_between(out[0]->pose.R, I) - 0.2) < 0.01);
    for (int i = 0; i < 30; i++)
        vision_tracker_update(t, 2 + i, &d, 1, out, NULL, NULL);
    assert_true(fabs(out[0]->pose.t[2] - 2.0) < 1e-6);
    assert_true(vision_rot_angle_between(out[0]->pose.R, d.pose.R) < 1e-4);
    /* A detection without pose does not disturb the smoothed one. */
    d.pose_valid = false;
    d.pose.t[2] = 100;
    vision_tracker_update(t, 40, &d, 1, out, NULL, NULL);
    assert_true(fabs(out[0]->pose.t[2] - 2.0) < 1e-6);
    vision_tracker_destroy(t);
}

/* Geometry helpers agree with each other. */
static void test_geometry(void **state)
{
    double R[9], q[4], R2[9];
    vision_rot_rpy(0.3, -1.2, 2.5, R);
    vision_rot_to_quat(R, q);
    vision_quat_to_rot(q, R2);
    assert_true(vision_rot_angle_between(R, R2) < 1e-6);
    vision_pose_t a, b, c;
    vision_rot_rpy(0.1, 0.2, 0.3, a.R);
    a.t[0] = 1; a.t[1] = 2; a.t[2] = 3;
    vision_pose_inverse(&a, &b);
    vision_pose_compose(&a, &b, &c);
    for (int i = 0; i < 9; i++)
        assert_true(fabs(c.R[i] - (i % 4 == 0)) < 1e-12);
    for (int i = 0; i < 3; i++)
        assert_true(fabs(c.t[i]) < 1e-12);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ids_hits_and_loss),
        cmocka_unit_test(test_duplicate_ids_in_one_frame),
        cmocka_unit_test(test_smoothing),
        cmocka_unit_test(test_geometry),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
