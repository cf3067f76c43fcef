/* test_vision_component: marie-vision in-process on a real LCM bus: images in (raw, JPEG,
 * folder), detections with poses and stable track ids out, tag messages read as events and
 * goals, and bad cameras, images and intrinsics refused or counted without a crash. */
#include <errno.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include <lcm/lcm.h>

#include "adapters/vision/vision_component.h"
#include "camera/vision_image.h"
#include "camera/vision_render.h"
#include "adapters/vision/vision_source.h"
#include "core/time.h"

#define W 640
#define H 480
static const vision_camera_t cam = { W, H, 500.0, 500.0, 319.5, 239.5 };

/* ---- what the component sent ---- */
typedef struct {
    int ndet, nevents, ngoals;
    marie_tag_detections_t *last;       /* copy of the newest detections */
    char kinds[16][32], texts[16][64];
    int sev[16];
    marie_goal_t goal;
    char goal_name[64];
    int first_track[1024];              /* track id per tag id at first sight */
    int track_changes;
} seen_t;
static seen_t seen;

static void on_det(const lcm_recv_buf_t *rb, const char *ch, const marie_tag_detections_t *m, void *u)
{
    seen.ndet++;
    if (seen.last)
        marie_tag_detections_t_destroy(seen.last);
    seen.last = marie_tag_detections_t_copy(m);
}

static void on_event(const lcm_recv_buf_t *rb, const char *ch, const marie_event_t *m, void *u)
{
    if (seen.nevents < 16) {
        snprintf(seen.kinds[seen.nevents], 32, "%s", m->kind);
        snprintf(seen.texts[seen.nevents], 64, "%s", m->text);
        seen.sev[seen.nevents] = m->severity;
    }
    seen.nevents++;
}

static void on_goal(const lcm_recv_buf_t *rb, const char *ch, const marie_goal_t *m, void *u)
{
    seen.ngoals++;
    seen.goal = *m;
    snprintf(seen.goal_name, sizeof seen.goal_name, "%s", m->name);
    seen.goal.name = seen.goal_name;
}

static int count_events(const char *kind)
{
    int n = 0;
    for (int i = 0; i < seen.nevents && i < 16; i++)
        n += strcmp(seen.kinds[i], kind) == 0;
    return n;
}

static lcm_t *bus;
static marie_tag_detections_t_subscription_t *sub_det;
static marie_event_t_subscription_t *sub_ev;
static marie_goal_t_subscription_t *sub_goal;

static int setup(void **state)
{
    memset(&seen, 0, sizeof seen);
    bus = lcm_create(marie_default_url());
    assert_non_null(bus);
    sub_det = marie_tag_detections_t_subscribe(bus, VISION_CH_DETECTIONS, on_det, NULL);
    sub_ev = marie_event_t_subscribe(bus, MARIE_CH_EVENT, on_event, NULL);
    sub_goal = marie_goal_t_subscribe(bus, VISION_CH_GOAL, on_goal, NULL);
    return 0;
}

static int teardown(void **state)
{
    if (seen.last)
        marie_tag_detections_t_destroy(seen.last);
    seen.last = NULL;
    marie_tag_detections_t_unsubscribe(bus, sub_det);
    marie_event_t_unsubscribe(bus, sub_ev);
    marie_goal_t_unsubscribe(bus, sub_goal);
    lcm_destroy(bus);
    return 0;
}

/* Creates marie-vision with extra "--param k=v" pairs and asks it to init and start.
 * Returns the component; *why gets the refusal if init/start failed. */
static marie_component_t *start(const char **why, ...)
{
    char *argv[64] = { "marie-vision" };
    int argc = 1;
    va_list ap;
    va_start(ap, why);
    for (const char *p; (p = va_arg(ap, const char *)) && argc < 62;) {
        argv[argc++] = "--param";
        argv[argc++] = (char *)p;
    }
    va_end(ap);
    marie_errors_t errs = { 0 };
    marie_component_t *c = marie_component_create(&vision_component_def, argc, argv, NULL, &errs);
    if (!c) {
        marie_errors_print(&errs, stderr);
        marie_errors_clear(&errs);
        fail_msg("component not created");
    }
    const char *r;
    *why = NULL;
    if (marie_component_command(c, MARIE_CMD_INIT, &r) < 0 || marie_component_command(c, MARIE_CMD_START, &r) < 0)
        *why = r;
    return c;
}

/* Runs the component's loop and our bus for `ms` milliseconds, or until cond() holds. */
static void pump(marie_component_t *c, int ms, int (*cond)(void))
{
    int64_t end = marie_mono_us() + ms * 1000LL;
    while (marie_mono_us() < end) {
        marie_loop_run_once(marie_component_loop(c), 5);
        while (lcm_handle_timeout(bus, 0) > 0)
            ;
        if (cond && cond())
            break;
    }
}

static vision_render_t *rnd;
static uint8_t pix[W * H * 3];

/* Renders tags `ids` in a row 1.5 m away. */
static void render(const int *ids, int n, int channels, uint32_t seed)
{
    vision_tag_t t[8];
    for (int i = 0; i < n; i++) {
        t[i].id = ids[i];
        t[i].size = 0.16;
        vision_pose_identity(&t[i].pose);
        t[i].pose.t[0] = -0.5 + 1.0 * i / (n > 1 ? n - 1 : 1);
        t[i].pose.t[1] = 0.05 * i;
        t[i].pose.t[2] = 1.5;
    }
    vision_render_opts_t o;
    vision_render_opts_default(&o);
    o.noise_sigma = 3;
    o.blur_sigma = 0.6;
    o.seed = seed;
    assert_int_equal(vision_render_frame(rnd, &cam, t, n, &o, pix, W * channels, channels), n);
}

static void send_image(int format, int64_t utime)
{
    marie_image_t img;
    int ch = format == MARIE_IMAGE_T_FORMAT_GRAY8 ? 1 : 3;
    assert_int_equal(vision_image_encode(pix, W, H, W * ch, ch, format, 90, utime, &img), 0);
    assert_int_equal(marie_image_t_publish(bus, VISION_CH_IMAGE, &img), 0);
    free(img.data);
}

static int ndet_target;
static int got_ndet(void) { return seen.ndet >= ndet_target; }

/* Tags 3 and 7 are configured: 3 reads as an event, 7 as a goal (and an event); 9 means
 * nothing. Each reads once per appearance, after min_hits frames, and again after the tag
 * was out of view for lost_after_s. Poses come out in metres in the camera frame. */
static void test_lcm_images_read_messages(void **state)
{
    const char *why;
    marie_component_t *c = start(&why, "fx=500", "fy=500", "cx=319.5", "cy=239.5", "width=640", "height=480",
                                 "tag_size=0.16", "min_hits=2", "lost_after_s=0.5",
                                 "messages=[{id: 3, message: dock ahead, kind: dock, severity: warn},"
                                 " {id: 7, message: to the charger, goal: {x: 2.0, y: -1.0, theta: 0.5, name: charger, priority: 4}}]",
                                 NULL);
    assert_null(why);
    assert_int_equal(marie_component_state(c), MARIE_STATE_RUNNING);
    int ids[3] = { 3, 7, 9 };
    int64_t t0 = 1000000000;
    int formats[4] = { MARIE_IMAGE_T_FORMAT_GRAY8, MARIE_IMAGE_T_FORMAT_RGB8, MARIE_IMAGE_T_FORMAT_JPEG, MARIE_IMAGE_T_FORMAT_BGR8 };
    int track3 = 0;
    for (int f = 0; f < 4; f++) {
        render(ids, 3, formats[f] == MARIE_IMAGE_T_FORMAT_GRAY8 ? 1 : 3, 10 + f);
        send_image(formats[f], t0 + f * 100000);
        ndet_target = f + 1;
        pump(c, 3000, got_ndet);
        assert_int_equal(seen.ndet, f + 1);
        marie_tag_detections_t *d = seen.last;
        assert_int_equal(d->count, 3);
        assert_int_equal(d->width, W);
        assert_int_equal(d->utime, t0 + f * 100000);
        for (int k = 0; k < 3; k++) {
            assert_int_equal(d->tags[k].id, ids[k]);
            assert_string_equal(d->tags[k].family, "tag36h11");
            assert_true(d->tags[k].pose_valid);
            assert_int_equal(d->tags[k].hits, f + 1);
            double ex = -0.5 + 0.5 * k, ey = 0.05 * k;
            assert_true(fabs(d->tags[k].position[0] - ex) < 0.02);
            assert_true(fabs(d->tags[k].position[1] - ey) < 0.02);
            assert_true(fabs(d->tags[k].position[2] - 1.5) < 0.03);
            assert_true(fabs(d->tags[k].smoothed_position[2] - 1.5) < 0.03);
            assert_true(d->tags[k].orientation[0] > 0.99);
        }
        if (f == 0)
            track3 = d->tags[0].track_id;
        assert_int_equal(d->tags[0].track_id, track3);
        assert_int_equal(d->tags[0].first_seen_utime, t0);
    }
    pump(c, 100, NULL);
    assert_int_equal(count_events("dock"), 1);
    assert_int_equal(count_events("tag_message"), 1);
    for (int i = 0; i < seen.nevents; i++)
        if (strcmp(seen.kinds[i], "dock") == 0) {
            assert_string_equal(seen.texts[i], "dock ahead");
            assert_int_equal(seen.sev[i], MARIE_EVENT_T_SEV_WARN);
        }
    assert_int_equal(seen.ngoals, 1);
    assert_string_equal(seen.goal.name, "charger");
    assert_true(seen.goal.pose.x == 2.0 && seen.goal.pose.y == -1.0 && seen.goal.pose.theta == 0.5);
    assert_int_equal(seen.goal.priority, 4);
    assert_int_equal(marie_component_counter(c, "messages_read"), 2);

    /* Out of view for a second (an empty frame), then back: a new track, read again. */
    int none[1] = { 0 };
    render(none, 0, 1, 99);
    send_image(MARIE_IMAGE_T_FORMAT_GRAY8, t0 + 1500000);
    ndet_target = 5;
    pump(c, 3000, got_ndet);
    assert_int_equal(seen.last->count, 0);
    for (int f = 0; f < 2; f++) {
        render(ids, 1, 1, 50 + f);
        send_image(MARIE_IMAGE_T_FORMAT_GRAY8, t0 + 2000000 + f * 100000);
        ndet_target = 6 + f;
        pump(c, 3000, got_ndet);
    }
    assert_int_equal(seen.last->count, 1);
    assert_int_not_equal(seen.last->tags[0].track_id, track3);
    pump(c, 100, NULL);
    assert_int_equal(count_events("dock"), 2);
    assert_int_equal(seen.ngoals, 1);
    assert_int_equal(marie_component_counter(c, "bad_image"), 0);
    marie_component_destroy(c);
}

/* Corrupt and inconsistent images over LCM are counted as bad input, logged, and dropped;
 * the component keeps running and still reads the next good frame. */
static void test_bad_images_counted(void **state)
{
    const char *why;
    marie_component_t *c = start(&why, "min_hits=1", NULL);
    assert_null(why);
    int ids[1] = { 5 };
    render(ids, 1, 1, 3);
    marie_image_t good;
    assert_int_equal(vision_image_encode(pix, W, H, W, 1, MARIE_IMAGE_T_FORMAT_JPEG, 90, 1, &good), 0);

    marie_image_t bad[9];
    uint8_t junk[4096];
    for (size_t i = 0; i < sizeof junk; i++)
        junk[i] = (uint8_t)(i * 131 + 7);
    junk[0] = 0xff;
    junk[1] = 0xd8;
    for (int i = 0; i < 9; i++)
        bad[i] = (marie_image_t){ .utime = 1, .width = W, .height = H, .row_stride = W,
                                  .format = MARIE_IMAGE_T_FORMAT_GRAY8, .size = 16, .data = junk };
    bad[0].format = MARIE_IMAGE_T_FORMAT_JPEG;              /* SOI marker then garbage */
    bad[0].size = sizeof junk;
    bad[1].format = MARIE_IMAGE_T_FORMAT_JPEG;              /* no SOI */
    bad[1].data = junk + 2;
    bad[1].size = 100;
    bad[2] = good;                                           /* a JPEG cut to a tenth */
    bad[2].size = good.size / 10;
    bad[3] = good;                                           /* JPEG of another size than declared */
    bad[3].width = 320;
    bad[4].size = W * H - 1;                                 /* raw, too few bytes */
    bad[4].data = pix;
    bad[5].row_stride = W - 1;                               /* stride shorter than a row */
    bad[5].size = W * H;
    bad[5].data = pix;
    bad[6].format = 9;                                       /* unknown format */
    bad[7].width = -4;                                       /* negative size */
    bad[8].width = 100000;                                   /* absurd size */
    bad[8].height = 100000;
    for (int i = 0; i < 9; i++)
        assert_int_equal(marie_image_t_publish(bus, VISION_CH_IMAGE, &bad[i]), 0);
    /* Not an image at all on the image channel. */
    marie_goal_t g = { .name = "x" };
    marie_goal_t_publish(bus, VISION_CH_IMAGE, &g);
    marie_image_t_publish(bus, VISION_CH_IMAGE, &good);
    ndet_target = 1;
    pump(c, 5000, got_ndet);
    assert_int_equal(seen.ndet, 1);     /* only the good frame was looked at */
    assert_int_equal(marie_component_counter(c, "bad_image"), 9);
    assert_int_equal(marie_component_counter(c, "bad_fingerprint"), 1);
    assert_int_equal(marie_component_state(c), MARIE_STATE_RUNNING);
    assert_int_equal(seen.last->count, 1);
    assert_int_equal(seen.last->tags[0].id, 5);
    assert_false(seen.last->tags[0].pose_valid);    /* no intrinsics configured */
    free(good.data);
    marie_component_destroy(c);
}

static int got_newest(void) { return seen.last && seen.last->utime == 106; }

/* A burst of frames faster than detection: every frame is either detected or counted as
 * skipped, and the newest one is always detected. */
static void test_burst_keeps_newest(void **state)
{
    const char *why;
    marie_component_t *c = start(&why, "min_hits=1", NULL);
    assert_null(why);
    int ids[1] = { 12 };
    render(ids, 1, 1, 8);
    for (int i = 1; i <= 6; i++)
        send_image(MARIE_IMAGE_T_FORMAT_GRAY8, 100 + i);
    pump(c, 5000, got_newest);
    pump(c, 200, NULL);
    assert_int_equal(seen.last->utime, 106);
    assert_int_equal(seen.last->count, 1);
    assert_int_equal(seen.ndet + marie_component_counter(c, "frames_skipped"), 6);
    assert_int_equal(marie_component_counter(c, "frames"), seen.ndet);
    marie_component_destroy(c);
}

static char tmpdir[64];

/* A folder of PNGs (one of them corrupt) is read in name order: tags found in the good
 * ones, the bad one counted as unreadable, the end announced as an event. */
static void test_folder_source(void **state)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/vision-folder-XXXXXX");
    assert_non_null(mkdtemp(tmpdir));
    char path[128];
    vision_frame_t f = { W, H, W, pix, 0 };
    for (int i = 0; i < 4; i++) {
        int ids[1] = { 20 + i };
        render(ids, 1, 1, 30 + i);
        snprintf(path, sizeof path, "%s/%02d.png", tmpdir, i * 2);
        assert_int_equal(vision_frame_save(&f, path), 0);
    }
    snprintf(path, sizeof path, "%s/03.png", tmpdir);
    FILE *fp = fopen(path, "wb");
    fputs("\x89PNG\r\n\x1a\n this is not an image", fp);
    fclose(fp);
    snprintf(path, sizeof path, "%s/notes.txt", tmpdir);     /* ignored: not an image name */
    fp = fopen(path, "wb");
    fclose(fp);

    char src[96];
    snprintf(src, sizeof src, "source=folder:%s", tmpdir);
    const char *why;
    marie_component_t *c = start(&why, src, "rate_hz=100", "min_hits=1",
                                 "messages=[{id: 22, message: third image}]", NULL);
    assert_null(why);
    ndet_target = 4;
    pump(c, 5000, got_ndet);
    pump(c, 100, NULL);
    assert_int_equal(seen.ndet, 4);
    assert_int_equal(seen.last->count, 1);
    assert_int_equal(seen.last->tags[0].id, 23);
    assert_int_equal(marie_component_counter(c, "unreadable_image"), 1);
    assert_int_equal(count_events("source_ended"), 1);
    assert_int_equal(count_events("tag_message"), 1);
    marie_component_destroy(c);
    for (int i = 0; i < 4; i++) {
        snprintf(path, sizeof path, "%s/%02d.png", tmpdir, i * 2);
        unlink(path);
    }
    snprintf(path, sizeof path, "%s/03.png", tmpdir);
    unlink(path);
    snprintf(path, sizeof path, "%s/notes.txt", tmpdir);
    unlink(path);
    rmdir(tmpdir);
}

/* A video file (MJPEG .avi) is read frame by frame and loops when asked; a file of garbage
 * with a video name is refused at init. */
static void test_video_source(void **state)
{
    char path[] = "/tmp/vision-video-XXXXXX.avi";
    int fd = mkstemps(path, 4);
    assert_true(fd >= 0);
    close(fd);
    static uint8_t buf[3][W * H];
    vision_frame_t fr[3];
    for (int i = 0; i < 3; i++) {
        int ids[1] = { 40 + i };
        render(ids, 1, 1, 60 + i);
        memcpy(buf[i], pix, W * H);
        fr[i] = (vision_frame_t){ W, H, W, buf[i], 0 };
    }
    assert_int_equal(vision_video_save(path, fr, 3, 10), 0);
    char src[64];
    snprintf(src, sizeof src, "source=video:%s", path);
    const char *why;
    marie_component_t *c = start(&why, src, "rate_hz=100", "loop=true", "min_hits=1", NULL);
    assert_null(why);
    ndet_target = 5;
    pump(c, 5000, got_ndet);
    assert_true(seen.ndet >= 5);
    assert_int_equal(seen.last->count, 1);
    assert_true(seen.last->tags[0].id >= 40 && seen.last->tags[0].id <= 42);
    assert_int_equal(count_events("source_ended"), 0);
    marie_component_destroy(c);

    FILE *fp = fopen(path, "wb");
    fputs("RIFF this is not a video at all", fp);
    fclose(fp);
    c = start(&why, src, NULL);
    assert_non_null(why);
    assert_non_null(strstr(why, "cannot be decoded"));
    marie_component_destroy(c);
    unlink(path);
}

/* Cameras that cannot be opened refuse init with a reason naming the source. */
static void test_unreadable_camera(void **state)
{
    static const char *const srcs[][2] = {
        { "source=device:57", "cannot be opened" },
        { "source=/dev/video99", "cannot be opened" },
        { "source=folder:/nonexistent/vision", "No such file" },
        { "source=video:/nonexistent/clip.avi", "No such file" },
        { "source=/etc/hostname", "expected device:N" },
        { "source=folder:/proc/self/fdinfo", "holds no images" },
    };
    for (size_t i = 0; i < sizeof srcs / sizeof srcs[0]; i++) {
        const char *why;
        marie_component_t *c = start(&why, srcs[i][0], NULL);
        assert_non_null(why);
        if (!strstr(why, srcs[i][1]))
            fail_msg("%s: reason '%s' lacks '%s'", srcs[i][0], why, srcs[i][1]);
        assert_int_not_equal(marie_component_state(c), MARIE_STATE_RUNNING);
        marie_component_destroy(c);
    }
}

/* Wrong intrinsics are refused at init; intrinsics for another image size give detections
 * without poses, counted as intrinsics_mismatch. A bad messages list is refused with the
 * place of the mistake. */
static void test_wrong_intrinsics_and_config(void **state)
{
    static const char *const bad[][2] = {
        { "fx=-500", "focal lengths" },
        { "cx=900", "principal point" },
        { "tag_size=0", "tag_size" },
        { "family=tag99h1", "unknown tag family" },
        { "decimate=0", "decimate" },
        { "smoothing=0", "smoothing" },
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        const char *why;
        marie_component_t *c = start(&why, "fx=500", "fy=500", "cx=319.5", "cy=239.5", "width=640", "height=480",
                                     bad[i][0], NULL);
        assert_non_null(why);
        if (!strstr(why, bad[i][1]))
            fail_msg("%s: reason '%s' lacks '%s'", bad[i][0], why, bad[i][1]);
        marie_component_destroy(c);
    }
    const char *why;
    marie_component_t *c = start(&why, "messages=[{id: 3, message: a}, {id: 3, message: b}]", NULL);
    assert_non_null(why);
    assert_non_null(strstr(why, "mapped twice"));
    marie_component_destroy(c);
    c = start(&why, "messages=[{id: 4, colour: red}]", NULL);
    assert_non_null(why);
    marie_component_destroy(c);

    c = start(&why, "fx=250", "fy=250", "cx=159.5", "cy=119.5", "width=320", "height=240", "min_hits=1", NULL);
    assert_null(why);
    int ids[1] = { 1 };
    render(ids, 1, 1, 5);
    send_image(MARIE_IMAGE_T_FORMAT_GRAY8, 5);
    ndet_target = 1;
    pump(c, 3000, got_ndet);
    assert_int_equal(seen.last->count, 1);
    assert_false(seen.last->tags[0].pose_valid);
    assert_int_equal(marie_component_counter(c, "intrinsics_mismatch"), 1);
    marie_component_destroy(c);
}

int main(void)
{
    rnd = vision_render_create("tag36h11");
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_lcm_images_read_messages, setup, teardown),
        cmocka_unit_test_setup_teardown(test_bad_images_counted, setup, teardown),
        cmocka_unit_test_setup_teardown(test_burst_keeps_newest, setup, teardown),
        cmocka_unit_test_setup_teardown(test_folder_source, setup, teardown),
        cmocka_unit_test_setup_teardown(test_video_source, setup, teardown),
        cmocka_unit_test_setup_teardown(test_unreadable_camera, setup, teardown),
        cmocka_unit_test_setup_teardown(test_wrong_intrinsics_and_config, setup, teardown),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    vision_render_destroy(rnd);
    return rc;
}
