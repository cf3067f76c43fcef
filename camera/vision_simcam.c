/* vision_simcam: a robot-mounted synthetic camera looking at tags fixed in a 2D world. */
#include "camera/vision_simcam.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera/vision_image.h"
#include "core/err.h"

struct vision_simcam {
    vision_simcam_opts_t o;
    char family[32];
    vision_render_t *r;
    vision_tag_t *tags;
    size_t n;
    uint8_t *pix;
    marie_image_t last;
    uint32_t frame;
    occmap_t *walls;
    uint8_t *scene;             /* the walls' image, width x height */
    float *cols;                /* per column: wall top, wall bottom, shade */
    vision_tag_t *shown;        /* the tags not hidden, this frame */
};

void vision_simcam_opts_default(vision_simcam_opts_t *o)
{
    memset(o, 0, sizeof *o);
    o->family = "tag36h11";
    o->cam = (vision_camera_t){ 640, 480, 500, 500, 319.5, 239.5 };
    o->mount_x = 0.2;
    o->mount_z = 0.5;
    vision_render_opts_default(&o->render);
    o->render.noise_sigma = 2;
    o->render.blur_sigma = 0.5;
    o->render.noise_table = 1;
    o->format = MARIE_IMAGE_T_FORMAT_GRAY8;
    o->jpeg_quality = 90;
    o->wall_height = 2.5;
    o->max_range = 20.0;
}

static int get_double(const marie_node_t *map, const char *key, double *v, marie_errors_t *errs)
{
    const marie_node_t *n = marie_node_get(map, key);
    return n ? marie_node_double(n, v, errs) : 0;
}

static int get_int(const marie_node_t *map, const char *key, int *v, marie_errors_t *errs)
{
    const marie_node_t *n = marie_node_get(map, key);
    int64_t i = *v;
    if (n && marie_node_int(n, &i, errs) < 0)
        return -1;
    *v = (int)i;
    return 0;
}

int vision_simcam_parse(const marie_node_t *camera, const marie_node_t *tags, vision_simcam_opts_t *o,
                        vision_tag_t **out, size_t *nout, marie_errors_t *errs)
{
    static const char *const cam_keys[] = { "width", "height", "fx", "fy", "cx", "cy", "mount_x", "mount_y",
                                            "mount_z", "mount_yaw", "mount_pitch", "noise", "blur",
                                            "background", "format", "family", "wall_height", "max_range",
                                            NULL };
    static const char *const tag_keys[] = { "id", "x", "y", "z", "yaw", "size", NULL };
    int rc = 0;
    *out = NULL;
    *nout = 0;
    if (camera) {
        if (camera->kind != MARIE_NODE_MAP) {
            marie_errors_add(errs, camera->file, camera->line, camera->col, "camera: expected a map");
            return marie_fail(EINVAL);
        }
        rc |= marie_node_check_keys(camera, cam_keys, "camera", errs);
        bool cx_set = marie_node_get(camera, "cx"), cy_set = marie_node_get(camera, "cy");
        rc |= get_int(camera, "width", &o->cam.width, errs);
        rc |= get_int(camera, "height", &o->cam.height, errs);
        if (!cx_set)
            o->cam.cx = (o->cam.width - 1) / 2.0;
        if (!cy_set)
            o->cam.cy = (o->cam.height - 1) / 2.0;
        rc |= get_double(camera, "fx", &o->cam.fx, errs);
        rc |= get_double(camera, "fy", &o->cam.fy, errs);
        rc |= get_double(camera, "cx", &o->cam.cx, errs);
        rc |= get_double(camera, "cy", &o->cam.cy, errs);
        rc |= get_double(camera, "mount_x", &o->mount_x, errs);
        rc |= get_double(camera, "mount_y", &o->mount_y, errs);
        rc |= get_double(camera, "mount_z", &o->mount_z, errs);
        rc |= get_double(camera, "mount_yaw", &o->mount_yaw, errs);
        rc |= get_double(camera, "mount_pitch", &o->mount_pitch, errs);
        rc |= get_double(camera, "noise", &o->render.noise_sigma, errs);
        rc |= get_double(camera, "blur", &o->render.blur_sigma, errs);
        rc |= get_double(camera, "wall_height", &o->wall_height, errs);
        rc |= get_double(camera, "max_range", &o->max_range, errs);
        const marie_node_t *n;
        const char *s;
        if ((n = marie_node_get(camera, "background")) && marie_node_str(n, &s, errs) == 0) {
            if (strcmp(s, "flat") == 0) o->render.background = VISION_BG_FLAT;
            else if (strcmp(s, "gradient") == 0) o->render.background = VISION_BG_GRADIENT;
            else if (strcmp(s, "clutter") == 0) o->render.background = VISION_BG_CLUTTER;
            else {
                marie_errors_add(errs, n->file, n->line, n->col, "background: expected flat, gradient or clutter");
                rc = -1;
            }
        }
        if ((n = marie_node_get(camera, "format")) && marie_node_str(n, &s, errs) == 0) {
            if (strcmp(s, "gray") == 0) o->format = MARIE_IMAGE_T_FORMAT_GRAY8;
            else if (strcmp(s, "rgb") == 0) o->format = MARIE_IMAGE_T_FORMAT_RGB8;
            else if (strcmp(s, "jpeg") == 0) o->format = MARIE_IMAGE_T_FORMAT_JPEG;
            else {
                marie_errors_add(errs, n->file, n->line, n->col, "format: expected gray, rgb or jpeg");
                rc = -1;
            }
        }
        if ((n = marie_node_get(camera, "family")) && marie_node_str(n, &s, errs) == 0)
            o->family = s;      /* points into the document; create() copies it */
        const char *why;
        if (rc == 0 && vision_camera_check(&o->cam, &why) < 0) {
            marie_errors_add(errs, camera->file, camera->line, camera->col, "camera: %s", why);
            rc = -1;
        }
    }
    if (tags) {
        if (tags->kind != MARIE_NODE_SEQ) {
            marie_errors_add(errs, tags->file, tags->line, tags->col, "tags: expected a list of {id, x, y, z, yaw, size}");
            return marie_fail(EINVAL);
        }
        *out = calloc(tags->n ? tags->n : 1, sizeof **out);
        if (!*out)
            return marie_fail(ENOMEM);
        for (size_t i = 0; i < tags->n; i++) {
            const marie_node_t *t = tags->items[i];
            if (t->kind != MARIE_NODE_MAP || !marie_node_get(t, "id") || !marie_node_get(t, "x") || !marie_node_get(t, "y")) {
                marie_errors_add(errs, t->file, t->line, t->col, "tags: each entry needs id, x and y");
                rc = -1;
                continue;
            }
            rc |= marie_node_check_keys(t, tag_keys, "tag", errs);
            int id = 0;
            double x = 0, y = 0, z = 0.5, yaw = 0, size = 0.16;
            rc |= get_int(t, "id", &id, errs);
            rc |= get_double(t, "x", &x, errs);
            rc |= get_double(t, "y", &y, errs);
            rc |= get_double(t, "z", &z, errs);
            rc |= get_double(t, "yaw", &yaw, errs);
            rc |= get_double(t, "size", &size, errs);
            if (!(size > 0) || id < 0) {
                marie_errors_add(errs, t->file, t->line, t->col, "tag: id must be >= 0 and size > 0");
                rc = -1;
            }
            vision_tag_t *o2 = &(*out)[(*nout)++];
            o2->id = id;
            o2->size = size;
            vision_pose_tag_on_wall(x, y, z, yaw, &o2->pose);
        }
    }
    if (rc) {
        free(*out);
        *out = NULL;
        *nout = 0;
        return marie_fail(EINVAL);
    }
    return 0;
}

vision_simcam_t *vision_simcam_create(const vision_simcam_opts_t *o, const vision_tag_t *tags, size_t n,
                                      char *err, size_t errlen)
{
    const char *why;
    if (vision_camera_check(&o->cam, &why) < 0) {
        snprintf(err, errlen, "camera: %s", why);
        return NULL;
    }
    vision_simcam_t *s = calloc(1, sizeof *s);
    if (!s)
        goto err_nomem;
    s->o = *o;
    snprintf(s->family, sizeof s->family, "%s", o->family ? o->family : "tag36h11");
    s->o.family = s->family;
    s->r = vision_render_create(s->family);
    if (!s->r) {
        snprintf(err, errlen, "unknown tag family '%s'", s->family);
        free(s);
        return NULL;
    }
    for (size_t i = 0; i < n; i++)
        if (tags[i].id < 0 || tags[i].id >= vision_render_ncodes(s->r)) {
            snprintf(err, errlen, "tag id %d is not in %s (0..%d)", tags[i].id, s->family, vision_render_ncodes(s->r) - 1);
            vision_render_destroy(s->r);
            free(s);
            return NULL;
        }
    s->tags = malloc((n ? n : 1) * sizeof *s->tags);
    s->shown = malloc((n ? n : 1) * sizeof *s->shown);
    s->pix = malloc((size_t)o->cam.width * o->cam.height * 3);
    if (!s->tags || !s->shown || !s->pix) {
        vision_simcam_destroy(s);
        goto err_nomem;
    }
    memcpy(s->tags, tags, n * sizeof *tags);
    s->n = n;
    return s;
err_nomem:
    snprintf(err, errlen, "out of memory");
    return NULL;
}

void vision_simcam_destroy(vision_simcam_t *s)
{
    if (!s)
        return;
    vision_render_destroy(s->r);
    free(s->tags);
    free(s->shown);
    free(s->pix);
    free(s->scene);
    free(s->cols);
    occmap_destroy(s->walls);
    free(s->last.data);
    free(s);
}

int vision_simcam_set_walls(vision_simcam_t *s, const occmap_t *map)
{
    occmap_t *m = occmap_clone(map);
    uint8_t *scene = malloc((size_t)s->o.cam.width * s->o.cam.height);
    float *cols = malloc((size_t)s->o.cam.width * 3 * sizeof *cols);
    if (!m || !scene || !cols) {
        occmap_destroy(m);
        free(scene);
        free(cols);
        return marie_fail(ENOMEM);
    }
    occmap_destroy(s->walls);
    free(s->scene);
    free(s->cols);
    s->cols = cols;
    s->walls = m;
    s->scene = scene;
    return 0;
}

/* The optical centre in the world and the heading the camera looks along. */
static void camera_place(const vision_simcam_t *s, double x, double y, double theta, double *cx, double *cy,
                         double *heading)
{
    double c = cos(theta), si = sin(theta);
    *cx = x + c * s->o.mount_x - si * s->o.mount_y;
    *cy = y + si * s->o.mount_x + c * s->o.mount_y;
    *heading = theta + s->o.mount_yaw;
}

/* Distance to the first wall along heading a, or max_range. */
static double wall_distance(const vision_simcam_t *s, double x, double y, double a)
{
    return occmap_raycast(s->walls, x, y, a, s->o.max_range);
}

/* One image column per ray: ceiling, wall (darker with distance, a seam every metre along
 * it), floor (lighter towards the camera). Cheap enough for the simulator's rates. */
static void draw_walls(vision_simcam_t *s, double x, double y, double heading)
{
    const vision_camera_t *k = &s->o.cam;
    int W = k->width, H = k->height;
    double horizon = k->cy - k->fy * tan(s->o.mount_pitch), cz = s->o.mount_z;
    /* Columns first (one ray each), then rows, so the image is written in memory order. */
    float *top = s->cols, *bottom = s->cols + W;
    uint8_t *shade = (uint8_t *)(s->cols + 2 * W);
    for (int u = 0; u < W; u++) {
        double off = atan((u - k->cx) / k->fx);             /* image right = turning right */
        double a = heading - off;
        double d = wall_distance(s, x, y, a);
        double depth = d * cos(off);
        bool hit = d < s->o.max_range;
        top[u] = (float)(hit ? horizon - k->fy * (s->o.wall_height - cz) / depth : horizon);
        bottom[u] = (float)(hit ? horizon + k->fy * cz / depth : horizon);
        double along = fabs(fmod(x + d * cos(a) + y + d * sin(a) + 1000.0, 1.0));
        int g = 190 - (int)(6.0 * d);
        if (along < 0.04 || along > 0.96)
            g -= 60;
        shade[u] = (uint8_t)(g < 40 ? 40 : g);
    }
    for (int v = 0; v < H; v++) {
        uint8_t *row = s->scene + (size_t)v * W;
        uint8_t floor = (uint8_t)(70 + (int)(60.0 * (v - horizon) / (H - horizon + 1)));
        for (int u = 0; u < W; u++)
            row[u] = v < top[u] ? 215 : v <= bottom[u] ? shade[u] : floor;
    }
}

bool vision_simcam_tag_visible(const vision_simcam_t *s, size_t i, double x, double y, double theta)
{
    if (i >= s->n)
        return false;
    double cx, cy, heading;
    camera_place(s, x, y, theta, &cx, &cy, &heading);
    const double *t = s->tags[i].pose.t;
    double dx = t[0] - cx, dy = t[1] - cy, dist = hypot(dx, dy);
    double off = remainder(heading - atan2(dy, dx), 2 * M_PI);
    const vision_camera_t *k = &s->o.cam;
    double u = k->cx + k->fx * tan(off);
    if (fabs(off) >= M_PI / 2 || u < 0 || u > k->width - 1)
        return false;
    /* Tags hang on walls: the wall under the tag is within a cell or two of its centre. */
    if (s->walls && wall_distance(s, cx, cy, atan2(dy, dx)) < dist - 2.5 * s->walls->resolution - 0.02)
        return false;
    return true;
}

void vision_simcam_camera_pose(const vision_simcam_t *s, double x, double y, double theta, vision_pose_t *out)
{
    double cx, cy, heading;
    camera_place(s, x, y, theta, &cx, &cy, &heading);
    vision_pose_camera_in_world(cx, cy, s->o.mount_z, heading, s->o.mount_pitch, out);
}

const vision_simcam_opts_t *vision_simcam_opts(const vision_simcam_t *s)
{
    return &s->o;
}

int vision_simcam_render(vision_simcam_t *s, double x, double y, double theta, int64_t utime, marie_image_t *img)
{
    const vision_simcam_opts_t *o = &s->o;
    double cx, cy, heading;
    camera_place(s, x, y, theta, &cx, &cy, &heading);
    vision_pose_t cam_in_world;
    vision_simcam_camera_pose(s, x, y, theta, &cam_in_world);
    int ch = o->format == MARIE_IMAGE_T_FORMAT_GRAY8 ? 1 : 3;
    vision_render_opts_t ro = o->render;
    ro.seed = o->render.seed + ++s->frame;
    const vision_tag_t *tags = s->tags;
    size_t n = s->n;
    if (s->walls) {
        draw_walls(s, cx, cy, heading);
        ro.background = VISION_BG_IMAGE;
        ro.bg_image = s->scene;
        n = 0;
        for (size_t i = 0; i < s->n; i++)
            if (vision_simcam_tag_visible(s, i, x, y, theta))
                s->shown[n++] = s->tags[i];
        tags = s->shown;
    }
    int drawn = vision_render_world(s->r, &o->cam, &cam_in_world, tags, n, &ro, s->pix, o->cam.width * ch, ch);
    if (drawn < 0)
        return drawn;
    free(s->last.data);
    memset(&s->last, 0, sizeof s->last);
    int rc = vision_image_encode(s->pix, o->cam.width, o->cam.height, o->cam.width * ch, ch, o->format,
                                 o->jpeg_quality, utime, &s->last);
    if (rc < 0)
        return rc;
    *img = s->last;
    return drawn;
}
