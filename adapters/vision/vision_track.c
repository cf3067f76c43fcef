/* vision_track: follows tag ids over frames: track ids, first/last seen, smoothed pose. */
#include "adapters/vision/vision_track.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"

struct vision_tracker {
    vision_tracker_opts_t opts;
    vision_track_t *tracks;
    int64_t *seen_frame;    /* frame counter of each track's last update */
    size_t n, cap;
    int next_id;
    int64_t frame;
};

void vision_tracker_opts_default(vision_tracker_opts_t *o)
{
    o->alpha = 0.3;
    o->lost_after_us = 500000;
    o->min_hits = 2;
}

vision_tracker_t *vision_tracker_create(const vision_tracker_opts_t *o)
{
    vision_tracker_t *t = calloc(1, sizeof *t);
    if (!t)
        return NULL;
    if (o)
        t->opts = *o;
    else
        vision_tracker_opts_default(&t->opts);
    if (!(t->opts.alpha > 0 && t->opts.alpha <= 1))
        t->opts.alpha = 1;
    if (t->opts.min_hits < 1)
        t->opts.min_hits = 1;
    t->next_id = 1;
    return t;
}

void vision_tracker_destroy(vision_tracker_t *t)
{
    if (!t)
        return;
    free(t->tracks);
    free(t->seen_frame);
    free(t);
}

size_t vision_tracker_count(const vision_tracker_t *t) { return t->n; }
const vision_track_t *vision_tracker_get(const vision_tracker_t *t, size_t i) { return i < t->n ? &t->tracks[i] : NULL; }

static void smooth(vision_track_t *tr, const vision_pose_t *p, double a)
{
    for (int i = 0; i < 3; i++)
        tr->pose.t[i] = (1 - a) * tr->pose.t[i] + a * p->t[i];
    /* Normalised linear blend of quaternions, taking the shorter way round. */
    double q0[4], q1[4], dot = 0;
    vision_rot_to_quat(tr->pose.R, q0);
    vision_rot_to_quat(p->R, q1);
    for (int i = 0; i < 4; i++)
        dot += q0[i] * q1[i];
    double s = dot < 0 ? -1 : 1, q[4];
    for (int i = 0; i < 4; i++)
        q[i] = (1 - a) * q0[i] + a * s * q1[i];
    vision_quat_to_rot(q, tr->pose.R);
}

void vision_tracker_expire(vision_tracker_t *t, int64_t now_us, vision_track_cb_t cb, void *user)
{
    size_t j = 0;
    for (size_t i = 0; i < t->n; i++) {
        if (now_us - t->tracks[i].last_seen_us > t->opts.lost_after_us) {
            if (cb)
                cb(user, &t->tracks[i], VISION_TRACK_LOST);
            continue;
        }
        t->tracks[j] = t->tracks[i];
        t->seen_frame[j] = t->seen_frame[i];
        j++;
    }
    t->n = j;
}

static vision_track_t *find(vision_tracker_t *t, int tag_id, size_t *idx)
{
    for (size_t i = 0; i < t->n; i++)
        if (t->tracks[i].tag_id == tag_id) {
            *idx = i;
            return &t->tracks[i];
        }
    return NULL;
}

int vision_tracker_update(vision_tracker_t *t, int64_t now_us, const vision_detection_t *dets, int n,
                          const vision_track_t **out, vision_track_cb_t cb, void *user)
{
    vision_tracker_expire(t, now_us, cb, user);
    t->frame++;
    /* Grow first so that pointers handed out below stay valid for the whole frame. */
    if (t->n + (size_t)(n > 0 ? n : 0) > t->cap) {
        size_t cap = (t->n + n) * 2 + 8;
        vision_track_t *nt = realloc(t->tracks, cap * sizeof *nt);
        if (!nt)
            return marie_fail(ENOMEM);
        t->tracks = nt;
        int64_t *ns = realloc(t->seen_frame, cap * sizeof *ns);
        if (!ns)
            return marie_fail(ENOMEM);
        t->seen_frame = ns;
        t->cap = cap;
    }
    for (int k = 0; k < n; k++) {
        const vision_detection_t *d = &dets[k];
        size_t i;
        vision_track_t *tr = find(t, d->id, &i);
        if (!tr) {
            i = t->n++;
            tr = &t->tracks[i];
            memset(tr, 0, sizeof *tr);
            tr->track_id = t->next_id++;
            if (t->next_id <= 0)
                t->next_id = 1;
            tr->tag_id = d->id;
            tr->first_seen_us = now_us;
            t->seen_frame[i] = 0;
            if (cb)
                cb(user, tr, VISION_TRACK_NEW);
        }
        if (out)
            out[k] = tr;
        if (t->seen_frame[i] == t->frame)
            continue;
        t->seen_frame[i] = t->frame;
        tr->last_seen_us = now_us;
        tr->hits++;
        if (d->pose_valid) {
            if (tr->pose_valid)
                smooth(tr, &d->pose, t->opts.alpha);
            else
                tr->pose = d->pose;
            tr->pose_valid = true;
        }
        if (!tr->confirmed && tr->hits >= t->opts.min_hits) {
            tr->confirmed = true;
            if (cb)
                cb(user, tr, VISION_TRACK_CONFIRMED);
        }
    }
    return 0;
}
