/* vision_component: the marie-vision Application Adapter (camera -> AprilTags -> tracks,
 * detections, messages and goals). */
#include "adapters/vision/vision_component.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/common/posebuf.h"
#include "adapters/vision/vision_detect.h"
#include "adapters/vision/vision_landmark.h"
#include "camera/vision_image.h"
#include "adapters/vision/vision_msgmap.h"
#include "adapters/vision/vision_source.h"
#include "adapters/vision/vision_track.h"
#include "core/clear.h"
#include "core/time.h"
#include "adapters/vision/vision_params.h"

#define MAX_TAGS 64     /* per frame; more are counted as truncated */

static const vision_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }

typedef struct {
    marie_component_t *c;
    vision_detector_t *det;
    vision_tracker_t *trk;
    vision_msgmap_t msgs;
    vision_source_t *src;       /* NULL for the lcm source or after a failure */
    bool from_bus, ended, failed;
    int64_t reopen_at_us;
    vision_frame_t frame;
    vision_detection_t dets[MAX_TAGS];
    const vision_track_t *tracks[MAX_TAGS];
    marie_tag_detection_t out[MAX_TAGS];
    int64_t frame_no;
    marie_timer_t *tick;
    marie_timer_t *pending;     /* detection of the newest bus frame, once this read round ends */
    int64_t pending_utime;
    marie_port_t *p_det, *p_goal, *p_lm;
    posebuf_t poses;            /* the robot's pose, for landmarks at the image time */
    vision_mount_t mount;
    marie_landmark_t lms[MAX_TAGS];
} vision_t;

static const marie_port_spec_t ports[] = {
    { "image", &marie_type_image_t, MARIE_IN, MARIE_PUSH, VISION_CH_IMAGE },
    { "detections", &marie_type_tag_detections_t, MARIE_OUT, MARIE_PUSH, VISION_CH_DETECTIONS },
    { "goal", &marie_type_goal_t, MARIE_OUT, MARIE_EVENT, VISION_CH_GOAL },
    { "pose", &marie_type_pose_cov_t, MARIE_IN, MARIE_PUSH, VISION_CH_POSE },
    { "landmarks", &marie_type_landmarks_t, MARIE_OUT, MARIE_PUSH, VISION_CH_LANDMARKS },
    { NULL },
};

static const marie_param_spec_t params[] = VISION_PARAMS;

static void release(vision_t *v)
{
    vision_detector_destroy(v->det);
    vision_tracker_destroy(v->trk);
    vision_msgmap_clear(&v->msgs);
    vision_source_close(v->src);
    vision_frame_free(&v->frame);
    /* The frame timer belongs to this configuration (its rate is a parameter). */
    if (v->tick)
        marie_loop_remove_timer(marie_component_loop(v->c), v->tick);
    if (v->pending)
        marie_loop_remove_timer(marie_component_loop(v->c), v->pending);
    v->tick = v->pending = NULL;
    v->det = NULL;
    v->trk = NULL;
    v->src = NULL;
}

static void on_track(void *user, const vision_track_t *t, vision_track_event_t ev)
{
    vision_t *v = user;
    if (ev == VISION_TRACK_LOST) {
        marie_debug("tag %d (track %d) lost after %d frames", t->tag_id, t->track_id, t->hits);
        return;
    }
    if (ev != VISION_TRACK_CONFIRMED)
        return;
    const vision_msg_t *m = vision_msgmap_find(&v->msgs, t->tag_id);
    if (!m)
        return;
    /* Read once per appearance: a tag that stays in view does not repeat itself. */
    if (m->text) {
        marie_info("tag %d reads: %s", t->tag_id, m->text);
        marie_component_event(v->c, m->severity, m->kind, "%s", m->text);
        marie_component_count(v->c, "messages_read", 1);
    }
    if (m->has_goal) {
        marie_goal_t g = {
            .utime = marie_component_now(v->c), .id = m->goal_id, .name = m->goal_name,
            .pose = { m->x, m->y, m->theta }, .tolerance = m->tolerance, .priority = m->priority,
        };
        if (marie_port_publish(v->p_goal, &g) == 0)
            marie_component_count(v->c, "goals_sent", 1);
    }
}

static void fill(marie_tag_detection_t *o, const vision_detection_t *d, const vision_track_t *t, const char *family)
{
    memset(o, 0, sizeof *o);
    o->family = (char *)family;
    o->id = d->id;
    o->hamming = d->hamming;
    o->decision_margin = d->margin;
    memcpy(o->corners, d->corners, sizeof o->corners);
    memcpy(o->center, d->center, sizeof o->center);
    o->pose_valid = d->pose_valid;
    o->orientation[0] = 1;
    o->smoothed_orientation[0] = 1;
    if (d->pose_valid) {
        memcpy(o->position, d->pose.t, sizeof o->position);
        vision_rot_to_quat(d->pose.R, o->orientation);
        o->pose_error = d->pose_err;
    }
    if (t) {
        o->track_id = t->track_id;
        o->first_seen_utime = t->first_seen_us;
        o->hits = t->hits;
        if (t->pose_valid) {
            memcpy(o->smoothed_position, t->pose.t, sizeof o->smoothed_position);
            vision_rot_to_quat(t->pose.R, o->smoothed_orientation);
        }
    }
}

/* Detections with poses, placed in the map with the robot's pose at the frame's time. */
static void publish_landmarks(vision_t *v, int n, int64_t utime)
{
    double robot[3];
    int64_t slack_us = (int64_t)(params_of(v->c)->pose_slack_s * 1e6);
    if (!posebuf_covers(&v->poses, utime, slack_us) || !posebuf_at(&v->poses, utime, robot)) {
        if (posebuf_newest(&v->poses) != INT64_MIN)
            marie_component_count(v->c, "landmarks_no_pose", 1);
        return;
    }
    int k = 0;
    for (int i = 0; i < n; i++) {
        const vision_detection_t *d = &v->dets[i];
        if (!d->pose_valid)
            continue;
        vision_landmark_t l;
        vision_landmark_place(&v->mount, robot, &d->pose, &l);
        const vision_msg_t *m = vision_msgmap_find(&v->msgs, d->id);
        v->lms[k++] = (marie_landmark_t){
            .family = v->out[i].family, .id = d->id, .track_id = v->out[i].track_id, .x = l.x, .y = l.y, .z = l.z,
            .yaw = l.yaw, .range = l.range, .bearing = l.bearing, .message = m && m->text ? m->text : "",
        };
    }
    if (!k)
        return;
    marie_landmarks_t msg = { .utime = utime, .frame = "map", .robot = { robot[0], robot[1], robot[2] },
                              .count = k, .landmarks = v->lms };
    marie_port_publish(v->p_lm, &msg);
    marie_component_count(v->c, "landmarks", k);
}

static void process(vision_t *v, const vision_frame_t *f, int64_t utime)
{
    marie_component_t *c = v->c;
    int64_t t0 = marie_mono_us();
    bool skipped = false;
    int n = vision_detector_detect(v->det, f->data, f->width, f->height, f->stride, v->dets, MAX_TAGS, &skipped);
    int err = errno;
    float ms = (float)(marie_mono_us() - t0) / 1000.0f;
    if (n < 0) {
        marie_component_bad_input(c, "bad_frame", "frame %dx%d cannot be processed: %s", f->width, f->height,
                                  strerror(err));
        return;
    }
    if (n > MAX_TAGS) {
        marie_component_count(c, "tags_truncated", n - MAX_TAGS);
        n = MAX_TAGS;
    }
    if (skipped)
        marie_component_bad_input(c, "intrinsics_mismatch",
                                  "frame is %dx%d but the intrinsics are for %lldx%lld: poses skipped", f->width,
                                  f->height, (long long)params_of(c)->width,
                                  (long long)params_of(c)->height);
    marie_component_count(c, "frames", 1);
    marie_component_count(c, "detections", n);
    if (vision_tracker_update(v->trk, utime, v->dets, n, v->tracks, on_track, v) < 0)
        memset(v->tracks, 0, sizeof v->tracks);
    const char *family = vision_detector_family(v->det);
    for (int i = 0; i < n; i++)
        fill(&v->out[i], &v->dets[i], v->tracks[i], family);
    char *camera = (char *)params_of(c)->camera;  /* the message names the parameter's camera: a use, no copy */
    marie_tag_detections_t msg = {
        .utime = utime, .camera = camera, .frame = v->frame_no++,
        .width = f->width, .height = f->height, .detect_ms = ms, .count = n, .tags = v->out,
    };
    marie_port_publish(v->p_det, &msg);
    publish_landmarks(v, n, utime);
}

static void on_pose(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    vision_t *v = marie_component_user(c);
    const marie_pose_cov_t *m = msg;
    if (!isfinite(m->pose.x) || !isfinite(m->pose.y) || !isfinite(m->pose.theta)) {
        marie_component_bad_input(c, "bad_pose", "pose with a non-finite field");
        return;
    }
    /* A pose older than the newest (a restart, a replay) starts the buffer over. */
    if (m->utime < posebuf_newest(&v->poses))
        posebuf_clear(&v->poses);
    posebuf_add(&v->poses, m->utime, (double[3]){ m->pose.x, m->pose.y, m->pose.theta });
}

static void on_pending(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    vision_t *v = user;
    v->pending = NULL;      /* a one-shot timer is freed after it fires */
    if (marie_component_state(v->c) == MARIE_STATE_RUNNING)
        process(v, &v->frame, v->pending_utime);
}

/* Every frame is decoded on arrival (so each bad one is counted), but detection runs once per
 * read round on the newest: when detection is slower than the camera, frames that queued up
 * meanwhile are skipped (counted) instead of adding latency. */
static void on_image(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    vision_t *v = marie_component_user(c);
    const marie_image_t *img = msg;
    const char *why = "";
    if (v->pending)
        marie_component_count(c, "frames_skipped", 1);
    int rc = vision_image_decode(img, &v->frame, &why);
    if (rc < 0 && errno == EBADMSG) {
        marie_component_bad_input(c, "bad_image", "image on %s: %s", info->channel, why);
    } else if (rc < 0) {
        marie_component_drop(c, 1);
    } else {
        v->pending_utime = img->utime > 0 ? img->utime : marie_component_now(c);
        if (!v->pending)
            v->pending = marie_loop_add_oneshot(marie_component_loop(c), 0, on_pending, v);
        if (v->pending)
            return;
        marie_component_drop(c, 1);
    }
    /* The frame buffer now holds no valid frame: a pending detection has nothing to look at. */
    if (v->pending) {
        marie_loop_remove_timer(marie_component_loop(c), v->pending);
        v->pending = NULL;
    }
}

static int open_source(vision_t *v)
{
    char err[256];
    v->src = vision_source_open(params_of(v->c)->source, params_of(v->c)->loop, err, sizeof err);
    if (!v->src) {
        marie_component_fail_reason(v->c, "%s", err);
        return -1;
    }
    marie_info("reading %s", vision_source_describe(v->src));
    v->failed = v->ended = false;
    return 0;
}

static void on_tick(marie_component_t *c, int64_t overruns)
{
    vision_t *v = marie_component_user(c);
    if (v->from_bus || v->ended)
        return;
    if (!v->src) {
        /* A camera that failed is reopened once a second. */
        if (marie_mono_us() < v->reopen_at_us)
            return;
        v->reopen_at_us = marie_mono_us() + 1000000;
        char err[256];
        v->src = vision_source_open(params_of(c)->source, params_of(c)->loop, err, sizeof err);
        if (!v->src)
            return;
        marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "camera_reopened", "%s", vision_source_describe(v->src));
    }
    const char *why = "";
    int rc = vision_source_read(v->src, &v->frame, &why);
    if (rc == 0) {
        process(v, &v->frame, marie_component_now(c));
    } else if (errno == EBADMSG) {
        marie_component_bad_input(c, "unreadable_image", "%s", why);
    } else if (errno == ENODATA) {
        v->ended = true;
        marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "source_ended", "%s: %s", vision_source_describe(v->src), why);
    } else {
        marie_component_count(c, "camera_errors", 1);
        marie_component_event(c, MARIE_EVENT_T_SEV_ERROR, "camera_failed", "%s: %s", vision_source_describe(v->src), why);
        MARIE_CLEAR(v->src, vision_source_close);
        v->reopen_at_us = marie_mono_us() + 1000000;
    }
}

static int on_init(marie_component_t *c)
{
    vision_t *v = marie_component_user(c);
    if (!v) {
        v = calloc(1, sizeof *v);
        if (!v) {
            marie_component_fail_reason(c, "out of memory");
            return -1;
        }
        v->c = c;
        marie_component_set_user(c, v);
    }
    release(v);
    v->p_det = marie_port(c, "detections");
    v->p_goal = marie_port(c, "goal");
    v->p_lm = marie_port(c, "landmarks");
    posebuf_clear(&v->poses);
    v->mount = (vision_mount_t){ params_of(c)->mount_x, params_of(c)->mount_y,
                                 params_of(c)->mount_z, params_of(c)->mount_yaw,
                                 params_of(c)->mount_pitch };
    if (marie_port_on_message(marie_port(c, "pose"), on_pose) < 0) {
        marie_component_fail_reason(c, "cannot subscribe to %s", marie_port_channel(marie_port(c, "pose")));
        goto err;
    }
    v->from_bus = strcmp(params_of(c)->source, "lcm") == 0;
    v->ended = v->failed = false;

    char err[256];
    v->det = vision_detector_create(&params_of(c)->detector, err, sizeof err);
    if (!v->det) {
        marie_component_fail_reason(c, "detector: %s", err);
        goto err;
    }
    vision_camera_t cam = {
        (int)params_of(c)->width, (int)params_of(c)->height,
        params_of(c)->fx, params_of(c)->fy, params_of(c)->cx, params_of(c)->cy,
    };
    if (cam.fx != 0 || cam.fy != 0 || cam.cx != 0 || cam.cy != 0 || cam.width != 0 || cam.height != 0) {
        const char *why;
        if (vision_detector_set_camera(v->det, &cam, params_of(c)->tag_size, &why) < 0) {
            marie_component_fail_reason(c, "intrinsics fx=%g fy=%g cx=%g cy=%g for %dx%d, tag_size %g: %s", cam.fx,
                                        cam.fy, cam.cx, cam.cy, cam.width, cam.height,
                                        params_of(c)->tag_size, why);
            goto err;
        }
    }
    vision_tracker_opts_t to = {
        params_of(c)->smoothing, (int64_t)(params_of(c)->lost_after_s * 1e6),
        (int)params_of(c)->min_hits,
    };
    if (!(to.alpha > 0 && to.alpha <= 1) || to.lost_after_us <= 0 || to.min_hits < 1) {
        marie_component_fail_reason(c, "smoothing must be in (0, 1], lost_after_s > 0 and min_hits >= 1");
        goto err;
    }
    v->trk = vision_tracker_create(&to);
    if (!v->trk) {
        marie_component_fail_reason(c, "out of memory");
        goto err;
    }
    marie_errors_t errs = { 0 };
    if (vision_msgmap_parse(params_of(c)->messages, &v->msgs, &errs) < 0) {
        marie_errors_print(&errs, stderr);
        marie_component_fail_reason(c, "messages: %s", errs.n ? errs.msgs[0] : "invalid");
        marie_errors_clear(&errs);
        goto err;
    }
    if (v->from_bus) {
        if (marie_port_on_message(marie_port(c, "image"), on_image) < 0) {
            marie_component_fail_reason(c, "cannot subscribe to %s", marie_port_channel(marie_port(c, "image")));
            goto err;
        }
    } else {
        double hz = params_of(c)->rate_hz;
        if (!(hz > 0 && hz <= 1000)) {
            marie_component_fail_reason(c, "rate_hz must be within (0, 1000]");
            goto err;
        }
        if (open_source(v) < 0)
            goto err;
        v->tick = marie_component_every(c, hz, on_tick);
        if (!v->tick) {
            marie_component_fail_reason(c, "cannot create the frame timer");
            goto err;
        }
    }
    return 0;
err:
    /* A refused init leaves nothing behind: on_quit only runs after a successful one. */
    release(v);
    free(v);
    marie_component_set_user(c, NULL);
    return -1;
}

static void on_quit(marie_component_t *c)
{
    vision_t *v = marie_component_user(c);
    if (!v)
        return;
    release(v);
    free(v);
    marie_component_set_user(c, NULL);
}

const marie_component_def_t vision_component_def = {
    .kind = "marie-vision",
    .ports = ports,
    .params = params, .params_size = sizeof(vision_params_t),
    .on_init = on_init,
    .on_quit = on_quit,
};
