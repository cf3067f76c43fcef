/* marie-vision-render: the synthetic camera as a command: renders AprilTags at given poses to
 * image files or publishes them as marie.image_t frames, for demos and tests without a robot. */
#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "camera/vision_image.h"
#include "camera/vision_render.h"
#include "camera/vision_simcam.h"
#include "core/cli.h"
#include "core/config.h"
#include "core/lcm.h"
#include "core/loop.h"
#include "core/time.h"
#include "lcmtypes/marie_types.h"

#define PROG "marie-vision-render"

/* What frame i shows: tags at poses in the camera's frame (--tag), or the simulator's camera on a
 * robot standing in a tag world (--world). */
typedef struct {
    vision_render_t *tagr;
    vision_camera_t cam;
    vision_render_opts_t ro;
    vision_tag_t tags[MARIE_CLI_LIST_MAX];
    int ntags;
    uint8_t *pix;
    vision_simcam_t *sim;
    double robot[3], turn, rate;
} scene_t;

/* Frame i as an image_t of `format` (--world: the world's own camera format). Its data is the
 * simcam's, or malloc'd for tags: scene_done() lets it go. 0 or -1. */
static int scene_frame(scene_t *s, int64_t i, int format, marie_image_t *img)
{
    if (s->sim) {
        double theta = s->robot[2] + (s->rate > 0 ? s->turn * (double)i / s->rate : 0);
        return vision_simcam_render(s->sim, s->robot[0], s->robot[1], theta, marie_wall_us(), img) < 0 ? -1 : 0;
    }
    int chans = format == MARIE_IMAGE_T_FORMAT_GRAY8 ? 1 : 3, stride = s->cam.width * chans;
    s->ro.seed = (uint32_t)i + 1;
    if (vision_render_frame(s->tagr, &s->cam, s->tags, (size_t)s->ntags, &s->ro, s->pix, stride, chans) < 0)
        return -1;
    return vision_image_encode(s->pix, s->cam.width, s->cam.height, stride, chans, format, 90, marie_wall_us(), img) < 0
               ? -1 : 0;
}

static void scene_done(const scene_t *s, marie_image_t *img)
{
    if (!s->sim)
        free(img->data);
}

static void scene_free(scene_t *s)
{
    vision_render_destroy(s->tagr);
    vision_simcam_destroy(s->sim);
    free(s->pix);
}

/* Frame 0 to an image file (png, jpg, pgm...), in grey. 0 or -1. */
static int save_first(scene_t *s, const char *out)
{
    marie_image_t img;
    if (scene_frame(s, 0, MARIE_IMAGE_T_FORMAT_GRAY8, &img) < 0) {
        fprintf(stderr, PROG ": cannot render\n");
        return -1;
    }
    vision_frame_t f = { 0 };
    int rc = vision_image_decode(&img, &f, NULL) < 0 || vision_frame_save(&f, out) < 0 ? -1 : 0;
    if (rc < 0)
        fprintf(stderr, PROG ": cannot write '%s'\n", out);
    vision_frame_free(&f);
    scene_done(s, &img);
    return rc;
}

typedef struct {
    scene_t *scene;
    lcm_t *lcm;
    const char *channel;
    int format;
    int64_t count, sent;
    int rc;
} pub_t;

/* Publishes the next frame; 0, or -1 (said on stderr) when it cannot be made or sent. */
static int publish_next(pub_t *p)
{
    marie_image_t img;
    if (scene_frame(p->scene, p->sent, p->format, &img) < 0) {
        fprintf(stderr, PROG ": cannot render\n");
        return -1;
    }
    int rc = marie_lcm_publish_msg(p->lcm, p->channel, &marie_type_image_t, &img);
    if (rc < 0)
        fprintf(stderr, PROG ": cannot publish on %s: %s\n", p->channel, strerror(errno));
    scene_done(p->scene, &img);
    p->sent++;
    return rc;
}

static void on_tick(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    pub_t *p = user;
    if (publish_next(p) < 0)
        p->rc = 1;
    if (p->rc || p->sent == p->count)
        marie_loop_quit(loop);
}

static void on_signal(marie_loop_t *loop, int signo, void *user)
{
    marie_loop_quit(loop);
}

/* count frames on channel, the first at once, then one every 1/rate s (0: back to back). */
static int publish(scene_t *s, const char *channel, const char *url, int format, double rate, int64_t count)
{
    lcm_t *lcm = marie_lcm_create(url);
    marie_loop_t *loop = marie_loop_create();
    if (!lcm || !loop) {
        fprintf(stderr, PROG ": cannot open the LCM bus: %s\n", strerror(errno));
        marie_loop_destroy(loop);
        marie_lcm_destroy(lcm);
        return 1;
    }
    pub_t p = { s, lcm, channel, format, count, 0, 0 };
    while (p.rc == 0 && p.sent < count && (rate <= 0 || p.sent == 0))
        p.rc = publish_next(&p) < 0;
    if (p.rc == 0 && p.sent < count) {
        marie_loop_catch_signals(loop, on_signal, NULL);
        if (!marie_loop_add_timer(loop, (int64_t)(1e6 / rate), on_tick, &p) || marie_loop_run(loop) < 0)
            p.rc = 1;
        marie_loop_catch_signals(loop, NULL, NULL);
    }
    marie_loop_destroy(loop);
    marie_lcm_destroy(lcm);
    return p.rc;
}

/* --world FILE: the simulator's camera (vision_simcam) and, for a simulator world (a map.yaml
 * with an image), its walls around the tags. 0, or 2 with the reason on stderr. */
static int load_world(scene_t *s, const char *path)
{
    marie_errors_t errs = { 0 };
    marie_doc_t *doc = marie_doc_load(path, &errs);
    vision_simcam_opts_t o;
    vision_simcam_opts_default(&o);
    vision_tag_t *tags = NULL;
    size_t n = 0;
    int rc = 0;
    if (!doc || vision_simcam_parse(marie_node_get(marie_doc_root(doc), "camera"),
                                    marie_node_get(marie_doc_root(doc), "tags"), &o, &tags, &n, &errs) < 0)
        rc = 2;
    bool is_map = doc && marie_node_get(marie_doc_root(doc), "image") != NULL;
    marie_doc_destroy(doc);
    char err[256];
    if (rc == 0 && !(s->sim = vision_simcam_create(&o, tags, n, err, sizeof err))) {
        fprintf(stderr, PROG ": %s: %s\n", path, err);
        rc = 2;
    }
    free(tags);
    if (rc == 0 && is_map) {
        occmap_t *map = occmap_load(path, &errs);
        if (!map || vision_simcam_set_walls(s->sim, map) < 0)
            rc = 2;
        occmap_destroy(map);
    }
    marie_errors_print(&errs, stderr);
    marie_errors_clear(&errs);
    return rc;
}

/* --tag ID:SIZE:X:Y:Z[:ROLL:PITCH:YAW] into *t. 0 or -1. */
static int parse_tag(const char *text, vision_tag_t *t)
{
    double v[7] = { 0 };
    int n = sscanf(text, "%d:%lf:%lf:%lf:%lf:%lf:%lf:%lf", &t->id, &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &v[6]);
    if (n != 5 && n != 8)
        return -1;
    t->size = v[0];
    vision_rot_rpy(v[4], v[5], v[6], t->pose.R);
    memcpy(t->pose.t, &v[1], sizeof t->pose.t);
    return 0;
}

/* The tag scene from the options. 0, or 2 with the reason on stderr. */
static int load_tags(scene_t *s, const char *family, const marie_cli_list_t *tags)
{
    for (int i = 0; i < tags->n; i++)
        if (parse_tag(tags->items[i], &s->tags[s->ntags++]) < 0) {
            fprintf(stderr, PROG ": --tag: expected ID:SIZE:X:Y:Z[:ROLL:PITCH:YAW], got '%s'\n", tags->items[i]);
            return 2;
        }
    if (s->cam.cx < 0)
        s->cam.cx = (s->cam.width - 1) / 2.0;
    if (s->cam.cy < 0)
        s->cam.cy = (s->cam.height - 1) / 2.0;
    const char *why;
    if (vision_camera_check(&s->cam, &why) < 0) {
        fprintf(stderr, PROG ": camera: %s\n", why);
        return 2;
    }
    if (!(s->tagr = vision_render_create(family))) {
        fprintf(stderr, PROG ": unknown tag family '%s'\n", family);
        return 2;
    }
    s->pix = malloc((size_t)s->cam.width * s->cam.height * 3);
    return s->pix ? 0 : 2;
}

/* A word among `names` (NULL-ended) as its index, or -1 with the reason on stderr. */
static int choose(const char *opt, const char *text, const char *const *names)
{
    for (int i = 0; names[i]; i++)
        if (strcmp(text, names[i]) == 0)
            return i;
    fprintf(stderr, PROG ": --%s: unknown '%s'\n", opt, text);
    return -1;
}

int main(int argc, char **argv)
{
    const char *family = "tag36h11", *size = "640x480", *background = "flat", *out = NULL, *channel = NULL,
               *url = NULL, *format = "gray", *world = NULL, *robot = "0:0:0";
    double fx = 500, fy = 500, cx = -1, cy = -1, noise = 2, blur = 0.5, rate = 10, turn = 0;
    int64_t count = 10;
    marie_cli_list_t tags = { .n = 0 };
    const marie_cli_opt_t opts[] = {
        { "tag", MARIE_CLI_LIST, &tags, 0, 0, "ID:SIZE:X:Y:Z[:ROLL:PITCH:YAW] a tag in the camera's optical frame "
                                              "(x right, y down, z forward; m, rad; zero angles face the camera)" },
        { "world", MARIE_CLI_STRING, &world, 0, 0, "FILE a YAML file with `camera` and `tags` (docs/vision.md)" },
        { "robot", MARIE_CLI_STRING, &robot, 0, 0, "X:Y:THETA where the robot stands in --world (0:0:0)" },
        { "turn", MARIE_CLI_DOUBLE, &turn, -100, 100, "RAD_PER_S how fast it turns while publishing (0)" },
        { "family", MARIE_CLI_STRING, &family, 0, 0, "NAME tag family (tag36h11)" },
        { "size", MARIE_CLI_STRING, &size, 0, 0, "WxH image size (640x480)" },
        { "fx", MARIE_CLI_DOUBLE, &fx, 1, 1e6, "F focal length in x, px (500)" },
        { "fy", MARIE_CLI_DOUBLE, &fy, 1, 1e6, "F focal length in y, px (500)" },
        { "cx", MARIE_CLI_DOUBLE, &cx, -1, 1e6, "C principal point x, px (the centre)" },
        { "cy", MARIE_CLI_DOUBLE, &cy, -1, 1e6, "C principal point y, px (the centre)" },
        { "noise", MARIE_CLI_DOUBLE, &noise, 0, 255, "S Gaussian noise sigma, grey levels (2)" },
        { "blur", MARIE_CLI_DOUBLE, &blur, 0, 100, "S Gaussian blur sigma, px (0.5)" },
        { "background", MARIE_CLI_STRING, &background, 0, 0, "flat|gradient|clutter (flat)" },
        { "out", MARIE_CLI_STRING, &out, 0, 0, "FILE write one frame (png, jpg, pgm...)" },
        { "publish", MARIE_CLI_STRING, &channel, 0, 0, "CHANNEL publish frames as marie.image_t" },
        { "rate", MARIE_CLI_DOUBLE, &rate, 0, 1000, "HZ frames a second for --publish, 0: back to back (10)" },
        { "count", MARIE_CLI_INT, &count, 1, 1e9, "N frames for --publish (10)" },
        { "format", MARIE_CLI_STRING, &format, 0, 0, "gray|rgb|jpeg for --publish with --tag (gray)" },
        { "url", MARIE_CLI_STRING, &url, 0, 0, "URL the LCM bus (the default URL)" },
        { NULL },
    };
    int rc = marie_cli_parse(PROG, opts, argc, argv);
    if (rc >= 0)
        return rc;
    static const char *const backgrounds[] = { "flat", "gradient", "clutter", NULL };
    static const char *const formats[] = { "gray", "rgb", "jpeg", NULL };
    static const int format_ids[] = { MARIE_IMAGE_T_FORMAT_GRAY8, MARIE_IMAGE_T_FORMAT_RGB8, MARIE_IMAGE_T_FORMAT_JPEG };
    scene_t s = { .cam = { 640, 480, fx, fy, cx, cy }, .turn = turn, .rate = rate };
    vision_render_opts_default(&s.ro);
    s.ro.noise_sigma = noise;
    s.ro.blur_sigma = blur;
    int bg = choose("background", background, backgrounds), fmt = choose("format", format, formats);
    if (bg < 0 || fmt < 0)
        return 2;
    s.ro.background = bg == 1 ? VISION_BG_GRADIENT : bg == 2 ? VISION_BG_CLUTTER : VISION_BG_FLAT;
    if (sscanf(size, "%dx%d", &s.cam.width, &s.cam.height) != 2 ||
        sscanf(robot, "%lf:%lf:%lf", &s.robot[0], &s.robot[1], &s.robot[2]) != 3 || optind < argc ||
        (!out && !channel)) {
        marie_cli_usage(PROG, opts, stderr);
        return 2;
    }
    rc = world ? load_world(&s, world) : load_tags(&s, family, &tags);
    if (rc == 0 && out && save_first(&s, out) < 0)
        rc = 1;
    if (rc == 0 && channel)
        rc = publish(&s, channel, url, format_ids[fmt], rate, count);
    scene_free(&s);
    return rc;
}
