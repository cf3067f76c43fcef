/* marie-vision-render: the synthetic camera as a command: renders AprilTags at given poses to
 * image files or publishes them as marie.image_t frames, for demos and tests without a robot. */
#include <errno.h>
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "camera/vision_image.h"
#include "camera/vision_render.h"
#include "camera/vision_simcam.h"
#include "core/config.h"
#include "core/time.h"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: marie-vision-render [options] --tag ID:SIZE:X:Y:Z[:ROLL:PITCH:YAW]...\n"
            "       marie-vision-render [options] --world FILE [--robot X:Y:THETA] [--turn RAD_PER_S]\n"
            "  tag poses are in the camera's optical frame (x right, y down, z forward; m, rad);\n"
            "  a tag with zero angles faces the camera.\n"
            "  --family NAME      tag family (tag36h11)\n"
            "  --size WxH         image size (640x480)\n"
            "  --fx F --fy F --cx C --cy C   intrinsics (500, 500, centre)\n"
            "  --noise S          Gaussian noise sigma, grey levels (2)\n"
            "  --blur S           Gaussian blur sigma, px (0.5)\n"
            "  --background flat|gradient|clutter\n"
            "  --out FILE         write one frame (png, jpg, pgm...)\n"
            "  --publish CHANNEL  publish frames as marie.image_t (URL from --url or the default)\n"
            "  --rate HZ --count N --format gray|rgb|jpeg   for --publish (10, 10, gray)\n"
            "  --url URL\n"
            "  --world FILE       a YAML file with `camera` and `tags` (see docs/vision.md); the\n"
            "                     robot stands at --robot and turns at --turn while publishing\n");
}

/* --world: the simulator's camera (vision_simcam) on a robot standing in a tag world. */
static int render_world(const char *path, const double robot[3], double turn, const char *out, const char *channel,
                        const char *url, double rate, int count)
{
    marie_errors_t errs = { 0 };
    marie_doc_t *doc = marie_doc_load(path, &errs);
    vision_simcam_opts_t o;
    vision_simcam_opts_default(&o);
    vision_tag_t *tags = NULL;
    size_t n = 0;
    if (!doc || vision_simcam_parse(marie_node_get(marie_doc_root(doc), "camera"),
                                    marie_node_get(marie_doc_root(doc), "tags"), &o, &tags, &n, &errs) < 0) {
        marie_errors_print(&errs, stderr);
        marie_errors_clear(&errs);
        marie_doc_destroy(doc);
        return 2;
    }
    char err[256];
    vision_simcam_t *cam = vision_simcam_create(&o, tags, n, err, sizeof err);
    /* A simulator world (a map.yaml with an image): its walls stand around the tags. */
    bool is_map = marie_node_get(marie_doc_root(doc), "image") != NULL;
    free(tags);
    marie_doc_destroy(doc);
    if (!cam) {
        fprintf(stderr, "marie-vision-render: %s: %s\n", path, err);
        return 2;
    }
    if (is_map) {
        occmap_t *map = occmap_load(path, &errs);
        if (!map || vision_simcam_set_walls(cam, map) < 0) {
            marie_errors_print(&errs, stderr);
            marie_errors_clear(&errs);
            occmap_destroy(map);
            vision_simcam_destroy(cam);
            return 2;
        }
        occmap_destroy(map);
    }
    lcm_t *lcm = channel ? lcm_create(url ? url : marie_default_url()) : NULL;
    int rc = 0;
    if (channel && !lcm) {
        fprintf(stderr, "marie-vision-render: cannot open the LCM bus\n");
        rc = 1;
    }
    int frames = channel ? count : 1;
    for (int i = 0; rc == 0 && i < frames; i++) {
        marie_image_t img;
        double theta = robot[2] + (rate > 0 ? turn * i / rate : 0);
        if (vision_simcam_render(cam, robot[0], robot[1], theta, marie_wall_us(), &img) < 0) {
            fprintf(stderr, "marie-vision-render: cannot render\n");
            rc = 1;
            break;
        }
        if (lcm) {
            marie_image_t_publish(lcm, channel, &img);
            if (i + 1 < frames && rate > 0)
                usleep((useconds_t)(1e6 / rate));
        }
        if (out && i == 0) {
            vision_frame_t f = { 0 };
            if (vision_image_decode(&img, &f, NULL) < 0 || vision_frame_save(&f, out) < 0) {
                fprintf(stderr, "marie-vision-render: cannot write '%s'\n", out);
                rc = 1;
            }
            vision_frame_free(&f);
        }
    }
    if (lcm)
        lcm_destroy(lcm);
    vision_simcam_destroy(cam);
    return rc;
}

int main(int argc, char **argv)
{
    static const struct option opts[] = {
        { "family", 1, 0, 'F' }, { "size", 1, 0, 's' }, { "fx", 1, 0, 'x' }, { "fy", 1, 0, 'y' },
        { "cx", 1, 0, 'c' }, { "cy", 1, 0, 'd' }, { "noise", 1, 0, 'n' }, { "blur", 1, 0, 'b' },
        { "background", 1, 0, 'g' }, { "out", 1, 0, 'o' }, { "publish", 1, 0, 'p' }, { "rate", 1, 0, 'r' },
        { "count", 1, 0, 'k' }, { "format", 1, 0, 'f' }, { "url", 1, 0, 'u' }, { "tag", 1, 0, 't' },
        { "world", 1, 0, 'w' }, { "robot", 1, 0, 'R' }, { "turn", 1, 0, 'T' },
        { "help", 0, 0, 'h' }, { 0, 0, 0, 0 },
    };
    const char *family = "tag36h11", *out = NULL, *channel = NULL, *url = NULL, *format = "gray", *world = NULL;
    double robot[3] = { 0, 0, 0 }, turn = 0;
    vision_camera_t cam = { 640, 480, 500, 500, -1, -1 };
    vision_render_opts_t ro;
    vision_render_opts_default(&ro);
    ro.noise_sigma = 2;
    ro.blur_sigma = 0.5;
    double rate = 10;
    int count = 10, ntags = 0;
    vision_tag_t tags[64];
    int ch;
    while ((ch = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        switch (ch) {
        case 'F': family = optarg; break;
        case 's':
            if (sscanf(optarg, "%dx%d", &cam.width, &cam.height) != 2) {
                fprintf(stderr, "marie-vision-render: --size: expected WxH, got '%s'\n", optarg);
                return 2;
            }
            break;
        case 'x': cam.fx = atof(optarg); break;
        case 'y': cam.fy = atof(optarg); break;
        case 'c': cam.cx = atof(optarg); break;
        case 'd': cam.cy = atof(optarg); break;
        case 'n': ro.noise_sigma = atof(optarg); break;
        case 'b': ro.blur_sigma = atof(optarg); break;
        case 'g':
            ro.background = strcmp(optarg, "gradient") == 0 ? VISION_BG_GRADIENT
                            : strcmp(optarg, "clutter") == 0 ? VISION_BG_CLUTTER : VISION_BG_FLAT;
            break;
        case 'o': out = optarg; break;
        case 'p': channel = optarg; break;
        case 'r': rate = atof(optarg); break;
        case 'k': count = atoi(optarg); break;
        case 'f': format = optarg; break;
        case 'u': url = optarg; break;
        case 't': {
            double v[8] = { 0 };
            int id, n = sscanf(optarg, "%d:%lf:%lf:%lf:%lf:%lf:%lf:%lf", &id, &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &v[6]);
            if ((n != 5 && n != 8) || ntags == 64) {
                fprintf(stderr, "marie-vision-render: --tag: expected ID:SIZE:X:Y:Z[:ROLL:PITCH:YAW], got '%s'\n", optarg);
                return 2;
            }
            vision_tag_t *t = &tags[ntags++];
            t->id = id;
            t->size = v[0];
            vision_rot_rpy(v[4], v[5], v[6], t->pose.R);
            t->pose.t[0] = v[1];
            t->pose.t[1] = v[2];
            t->pose.t[2] = v[3];
            break;
        }
        case 'w': world = optarg; break;
        case 'R':
            if (sscanf(optarg, "%lf:%lf:%lf", &robot[0], &robot[1], &robot[2]) != 3) {
                fprintf(stderr, "marie-vision-render: --robot: expected X:Y:THETA, got '%s'\n", optarg);
                return 2;
            }
            break;
        case 'T': turn = atof(optarg); break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    if (cam.cx < 0)
        cam.cx = (cam.width - 1) / 2.0;
    if (cam.cy < 0)
        cam.cy = (cam.height - 1) / 2.0;
    if ((!out && !channel) || optind < argc) {
        usage(stderr);
        return 2;
    }
    if (world)
        return render_world(world, robot, turn, out, channel, url, rate, count);
    vision_render_t *r = vision_render_create(family);
    if (!r) {
        fprintf(stderr, "marie-vision-render: unknown tag family '%s'\n", family);
        return 2;
    }
    const char *why;
    if (vision_camera_check(&cam, &why) < 0) {
        fprintf(stderr, "marie-vision-render: camera: %s\n", why);
        return 2;
    }
    int chans = strcmp(format, "gray") == 0 ? 1 : 3;
    uint8_t *pix = malloc((size_t)cam.width * cam.height * 3);
    int rc = 0;
    if (out) {
        vision_frame_t f = { cam.width, cam.height, cam.width, pix, 0 };
        int n = vision_render_frame(r, &cam, tags, ntags, &ro, pix, cam.width, 1);
        if (n < 0 || vision_frame_save(&f, out) < 0) {
            fprintf(stderr, "marie-vision-render: cannot render or write '%s'\n", out);
            rc = 1;
        }
    }
    if (channel && rc == 0) {
        lcm_t *lcm = lcm_create(url ? url : marie_default_url());
        int fmt = strcmp(format, "jpeg") == 0 ? MARIE_IMAGE_T_FORMAT_JPEG
                  : chans == 3 ? MARIE_IMAGE_T_FORMAT_RGB8 : MARIE_IMAGE_T_FORMAT_GRAY8;
        if (!lcm) {
            fprintf(stderr, "marie-vision-render: cannot open the LCM bus\n");
            rc = 1;
        }
        for (int i = 0; lcm && i < count; i++) {
            ro.seed = (uint32_t)i + 1;
            vision_render_frame(r, &cam, tags, ntags, &ro, pix, cam.width * chans, chans);
            marie_image_t img;
            if (vision_image_encode(pix, cam.width, cam.height, cam.width * chans, chans, fmt, 90, marie_wall_us(), &img) == 0) {
                marie_image_t_publish(lcm, channel, &img);
                free(img.data);
            }
            if (i + 1 < count && rate > 0)
                usleep((useconds_t)(1e6 / rate));
        }
        if (lcm)
            lcm_destroy(lcm);
    }
    free(pix);
    vision_render_destroy(r);
    return rc;
}
