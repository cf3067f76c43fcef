/* vision_detect: AprilTag detection with libapriltag plus tag pose from camera intrinsics. */
#include "adapters/vision/vision_detect.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <apriltag/apriltag.h>
#include <apriltag/apriltag_pose.h>

#include "camera/vision_family.h"
#include "core/err.h"

struct vision_detector {
    apriltag_detector_t *td;
    apriltag_family_t *fam;
    vision_detector_opts_t opts;
    bool have_camera;
    vision_camera_t cam;
    double tag_size;
};

void vision_detector_opts_default(vision_detector_opts_t *o)
{
    *o = (vision_detector_opts_t)VISION_DETECTOR_OPTS_DEFAULTS;
}

vision_detector_t *vision_detector_create(const vision_detector_opts_t *o, char *err, size_t errlen)
{
    vision_detector_opts_t def;
    if (!o) {
        vision_detector_opts_default(&def);
        o = &def;
    }
    const char *why = NULL;
    if (!(o->decimate >= 1.0 && o->decimate <= 8.0))
        why = "decimate must be within 1..8";
    else if (!(o->sigma >= 0.0 && o->sigma <= 10.0))
        why = "sigma must be within 0..10";
    else if (o->threads < 1 || o->threads > 64)
        why = "threads must be within 1..64";
    else if (o->max_hamming < 0 || o->max_hamming > 2)
        why = "max_hamming must be 0, 1 or 2";
    else if (!(o->sharpening >= 0.0 && o->sharpening <= 10.0))
        why = "sharpening must be within 0..10";
    if (why) {
        snprintf(err, errlen, "%s", why);
        return marie_fail_null(EINVAL);
    }
    vision_detector_t *d = calloc(1, sizeof *d);
    if (!d)
        goto err_alloc;
    d->fam = vision_family_create(o->family ? o->family : "tag36h11");
    if (!d->fam) {
        char names[256] = "";
        for (const char *const *n = vision_family_names(); *n; n++)
            snprintf(names + strlen(names), sizeof names - strlen(names), "%s%s", n == vision_family_names() ? "" : ", ", *n);
        snprintf(err, errlen, "unknown tag family '%s' (known: %s)", o->family, names);
        errno = ENOENT;
        goto err_family;
    }
    d->td = apriltag_detector_create();
    if (!d->td)
        goto err_detector;
    apriltag_detector_add_family_bits(d->td, d->fam, o->max_hamming);
    d->td->quad_decimate = (float)o->decimate;
    d->td->quad_sigma = (float)o->sigma;
    d->td->nthreads = o->threads;
    d->td->refine_edges = o->refine_edges;
    d->td->decode_sharpening = o->sharpening;
    d->opts = *o;
    d->opts.family = d->fam->name;
    return d;

err_detector:
    vision_family_destroy(d->fam);
    snprintf(err, errlen, "cannot create the detector");
    errno = ENOMEM;
err_family:
    free(d);
    return NULL;
err_alloc:
    snprintf(err, errlen, "out of memory");
    return marie_fail_null(ENOMEM);
}

void vision_detector_destroy(vision_detector_t *d)
{
    if (!d)
        return;
    apriltag_detector_destroy(d->td);
    vision_family_destroy(d->fam);
    free(d);
}

const char *vision_detector_family(const vision_detector_t *d)
{
    return d->fam->name;
}

int vision_detector_set_camera(vision_detector_t *d, const vision_camera_t *cam, double tag_size, const char **why)
{
    const char *w = NULL;
    if (!cam) {
        d->have_camera = false;
        return 0;
    }
    if (vision_camera_check(cam, &w) == 0 && !(tag_size > 0 && isfinite(tag_size)))
        w = "tag_size must be a positive length in metres";
    if (why)
        *why = w;
    if (w) {
        d->have_camera = false;
        return marie_fail(EINVAL);
    }
    d->cam = *cam;
    d->tag_size = tag_size;
    d->have_camera = true;
    return 0;
}

static int by_id(const void *a, const void *b)
{
    const vision_detection_t *x = a, *y = b;
    return (x->id > y->id) - (x->id < y->id);
}

int vision_detector_detect(vision_detector_t *d, const uint8_t *gray, int width, int height, int stride,
                           vision_detection_t *out, int max, bool *pose_skipped)
{
    if (!d || !gray || width <= 0 || height <= 0 || stride < width || (max > 0 && !out))
        return marie_fail(EINVAL);
    /* libapriltag only reads the image; it takes a non-const buffer. */
    image_u8_t im = { .width = width, .height = height, .stride = stride, .buf = (uint8_t *)gray };
    zarray_t *dets = apriltag_detector_detect(d->td, &im);
    if (!dets)
        return marie_fail(ENOMEM);
    bool pose = d->have_camera && d->cam.width == width && d->cam.height == height;
    if (pose_skipped)
        *pose_skipped = d->have_camera && !pose;
    int n = 0, total = 0;
    for (int i = 0; i < zarray_size(dets); i++) {
        apriltag_detection_t *det;
        zarray_get(dets, i, &det);
        if (det->decision_margin < d->opts.min_margin)
            continue;
        total++;
        if (n >= max)
            continue;
        vision_detection_t *o = &out[n++];
        memset(o, 0, sizeof *o);
        o->id = det->id;
        o->hamming = det->hamming;
        o->margin = det->decision_margin;
        /* libapriltag puts pixel centres at +0.5; marie (like OpenCV and calibration tools)
         * puts them at integers, so corners shift by half a pixel and the pose solver gets
         * the principal point in libapriltag's convention. */
        o->center[0] = det->c[0] - 0.5;
        o->center[1] = det->c[1] - 0.5;
        for (int k = 0; k < 4; k++) {
            o->corners[k][0] = det->p[k][0] - 0.5;
            o->corners[k][1] = det->p[k][1] - 0.5;
        }
        if (pose) {
            apriltag_detection_info_t info = {
                .det = det, .tagsize = d->tag_size,
                .fx = d->cam.fx, .fy = d->cam.fy, .cx = d->cam.cx + 0.5, .cy = d->cam.cy + 0.5,
            };
            apriltag_pose_t p = { 0 };
            double e = estimate_tag_pose(&info, &p);
            if (p.R && p.t && isfinite(e)) {
                for (int k = 0; k < 9; k++)
                    o->pose.R[k] = MATD_EL(p.R, k / 3, k % 3);
                for (int k = 0; k < 3; k++)
                    o->pose.t[k] = MATD_EL(p.t, k, 0);
                o->pose_err = e;
                o->pose_valid = true;
            }
            /* Debian's libapriltag does not export matd_destroy(); a matd_t is one calloc'd
             * block (flexible array member), so free() releases it the same way. */
            free(p.R);
            free(p.t);
        }
    }
    apriltag_detections_destroy(dets);
    if (n > 1)
        qsort(out, n, sizeof *out, by_id);
    return total;
}
