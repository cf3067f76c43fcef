/* sim camera: the simulator's camera, rendered from the world file's walls and tag signs. */
#include "sim/camera.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera/vision_simcam.h"
#include "core/config.h"
#include "core/err.h"
#include "core/log.h"
#include "sim/sim_opts.h"

struct sim_camera {
    vision_simcam_t *cam;
    int64_t period;     /* physics steps per frame */
    size_t ntags;
};

static int resize(vision_simcam_opts_t *o, int w, int h, char *why, size_t len)
{
    if (!w && !h)
        return 0;
    if (w < 16 || h < 16 || w > 4096 || h > 4096) {
        snprintf(why, len, "camera size %dx%d: expected 16..4096 a side", w, h);
        return -1;
    }
    /* The same lens on a sensor read at another resolution. */
    double sx = (double)w / o->cam.width, sy = (double)h / o->cam.height;
    o->cam.fx *= sx;
    o->cam.fy *= sy;
    o->cam.cx = (o->cam.cx + 0.5) * sx - 0.5;
    o->cam.cy = (o->cam.cy + 0.5) * sy - 0.5;
    o->cam.width = w;
    o->cam.height = h;
    return 0;
}

sim_camera_t *sim_camera_create(const char *yaml, const occmap_t *map, const sim_camera_cfg_t *cfg,
                                char *why, size_t len)
{
    if (!(cfg->hz > 0) || !isfinite(cfg->hz) || !(cfg->step > 0)) {
        marie_fail_why(why, len, "camera_hz: expected a positive rate");
        return NULL;
    }
    marie_errors_t errs = { 0 };
    marie_doc_t *doc = marie_doc_load(yaml, &errs);
    vision_simcam_opts_t o;
    vision_simcam_opts_default(&o);
    o.render.seed = cfg->seed;
    vision_tag_t *tags = NULL;
    size_t n = 0;
    sim_camera_t *c = NULL;
    if (!doc)
        goto err_errs;
    const marie_node_t *root = marie_doc_root(doc);
    if (vision_simcam_parse(marie_node_get(root, "camera"), marie_node_get(root, "tags"), &o, &tags, &n, &errs) < 0)
        goto err_errs;
    if (resize(&o, cfg->width, cfg->height, why, len) < 0)
        goto err;
    c = calloc(1, sizeof *c);
    if (!c) {
        snprintf(why, len, "out of memory");
        goto err;
    }
    c->cam = vision_simcam_create(&o, tags, n, why, len);
    if (!c->cam)
        goto err;
    if (vision_simcam_set_walls(c->cam, map) < 0) {
        snprintf(why, len, "out of memory");
        goto err;
    }
    c->period = llround(1.0 / (cfg->hz * cfg->step));
    c->period = c->period < 1 ? 1 : c->period;
    c->ntags = n;
    free(tags);
    marie_doc_destroy(doc);
    return c;
err_errs:
    marie_fail_why(why, len, "%s", errs.n ? errs.msgs[0] : "cannot read the world file");
err:
    MARIE_KEEP_ERRNO(marie_errors_clear(&errs); sim_camera_destroy(c); free(tags); marie_doc_destroy(doc));
    return NULL;
}

void sim_camera_destroy(sim_camera_t *c)
{
    if (!c)
        return;
    vision_simcam_destroy(c->cam);
    free(c);
}

int sim_camera_step(sim_camera_t *c, int64_t k, double x, double y, double theta, int64_t utime, marie_image_t *img)
{
    if (k % c->period)
        return 0;
    int rc = vision_simcam_render(c->cam, x, y, theta, utime, img);
    return rc < 0 ? rc : 1;
}

size_t sim_camera_tags(const sim_camera_t *c)
{
    return c->ntags;
}

int sim_camera_init(marie_component_t *c, const char *yaml, const occmap_t *map, double step, sim_camera_t **out)
{
    *out = NULL;
    if (!sim_opts(c)->camera)
        return 0;
    sim_camera_cfg_t cfg = { .hz = sim_opts(c)->camera_hz, .step = step,
                             .seed = (uint32_t)sim_opts(c)->model.seed };
    const char *size = sim_opts(c)->camera_size;
    char tail;
    if (size[0] && sscanf(size, "%dx%d%c", &cfg.width, &cfg.height, &tail) != 2) {
        marie_component_fail_reason(c, "camera_size: expected WIDTHxHEIGHT (e.g. 320x240), got '%s'", size);
        return -1;
    }
    char why[512];
    *out = sim_camera_create(yaml, map, &cfg, why, sizeof why);
    if (!*out) {
        marie_component_fail_reason(c, "camera: %s", why);
        return -1;
    }
    marie_info("camera: %zu tag signs, %g Hz", (*out)->ntags, cfg.hz);
    return 0;
}

void sim_camera_publish(sim_camera_t *cam, marie_component_t *c, marie_port_t *p, int64_t k, double x, double y,
                        double theta, int64_t utime)
{
    marie_image_t img;
    int64_t t0 = marie_mono_us();
    int rc = sim_camera_step(cam, k, x, y, theta, utime, &img);
    if (rc == 0)
        return;
    if (rc < 0) {
        marie_component_count(c, "camera_errors", 1);
        return;
    }
    marie_component_count(c, "camera_render_us", marie_mono_us() - t0);
    marie_component_count(c, "camera_frames", 1);
    marie_port_publish(p, &img);
}
