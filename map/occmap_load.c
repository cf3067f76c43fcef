/* occmap_load: ROS map_server maps (map.yaml + PGM image) with map_server's semantics: trinary,
 * scale and raw modes, negate, thresholds and the origin's yaw (docs/map.md). */
#include "map/occmap.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/clear.h"
#include "core/file.h"

/* Images larger than this are refused before they are read (20000 x 20000 16-bit pixels). */
#define OCCMAP_MAX_IMAGE_BYTES ((size_t)800 << 20)

/* map_server's rule for one pixel value v of an image whose white is maxval. */
static int8_t pixel_cell(unsigned v, unsigned maxval, const occmap_meta_t *m)
{
    if (m->mode == OCCMAP_RAW)
        return v <= 100 ? (int8_t)v : OCCMAP_UNKNOWN;
    double p = m->negate ? (double)v / maxval : (double)(maxval - v) / maxval;
    if (p > m->occupied_thresh)
        return OCCMAP_OCCUPIED;
    if (p < m->free_thresh)
        return OCCMAP_FREE;
    if (m->mode == OCCMAP_TRINARY)
        return OCCMAP_UNKNOWN;
    return (int8_t)(99.0 * (p - m->free_thresh) / (m->occupied_thresh - m->free_thresh));
}

/* Value of the image-frame grid at a map-frame point (unknown outside). */
static int8_t sample(const occmap_t *img, double c, double s, double x, double y)
{
    double dx = x - img->origin_x, dy = y - img->origin_y;
    double lx = c * dx + s * dy, ly = -s * dx + c * dy;
    return occmap_get(img, (int)floor(lx / img->resolution), (int)floor(ly / img->resolution));
}

/* The rotated image on an axis-aligned grid of the same resolution covering it. A cell is
 * occupied when any of five points in it (centre and corners) falls on an occupied cell, so
 * a thin rotated wall stays closed; otherwise it takes the value under its centre. */
static occmap_t *resample(const occmap_t *img, double yaw)
{
    double c = cos(yaw), s = sin(yaw), W = img->width * img->resolution, H = img->height * img->resolution;
    double xs[4] = { 0, c * W, c * W - s * H, -s * H }, ys[4] = { 0, s * W, s * W + c * H, c * H };
    double x0 = xs[0], x1 = xs[0], y0 = ys[0], y1 = ys[0];
    for (int k = 1; k < 4; k++) {
        x0 = fmin(x0, xs[k]), x1 = fmax(x1, xs[k]);
        y0 = fmin(y0, ys[k]), y1 = fmax(y1, ys[k]);
    }
    double res = img->resolution;
    occmap_t *m = occmap_create((int)ceil((x1 - x0) / res - 1e-9), (int)ceil((y1 - y0) / res - 1e-9), res,
                                img->origin_x + x0, img->origin_y + y0);
    if (!m)
        return NULL;
    static const double corner[5][2] = { { 0.5, 0.5 }, { 0.05, 0.05 }, { 0.95, 0.05 }, { 0.05, 0.95 }, { 0.95, 0.95 } };
    for (int cy = 0; cy < m->height; cy++) {
        for (int cx = 0; cx < m->width; cx++) {
            int8_t v = OCCMAP_UNKNOWN;
            for (int k = 0; k < 5; k++) {
                int8_t u = sample(img, c, s, m->origin_x + (cx + corner[k][0]) * res,
                                  m->origin_y + (cy + corner[k][1]) * res);
                if (k == 0)
                    v = u;
                if (u == OCCMAP_OCCUPIED) {
                    v = u;
                    break;
                }
            }
            m->cells[(size_t)cy * m->width + cx] = v;
        }
    }
    return m;
}

/* m itself when yaw is 0, else its resampled copy (m is freed either way on failure). */
static occmap_t *align(occmap_t *m, double yaw)
{
    if (yaw == 0)
        return m;
    occmap_t *r = resample(m, yaw);
    occmap_destroy(m);
    return r;
}

occmap_t *occmap_from_image(const pgm_t *img, const occmap_meta_t *meta)
{
    occmap_t *m = occmap_create(img->width, img->height, meta->resolution, meta->origin_x, meta->origin_y);
    if (!m)
        return NULL;
    for (int row = 0; row < img->height; row++)
        for (int i = 0; i < img->width; i++)      /* the image's top row is the map's last row */
            m->cells[(size_t)(img->height - 1 - row) * img->width + i] =
                pixel_cell(img->pixels[(size_t)row * img->width + i], (unsigned)img->maxval, meta);
    return align(m, meta->origin_yaw);
}

occmap_t *occmap_from_cells(int width, int height, double resolution, double origin_x, double origin_y,
                            double origin_yaw, const int8_t *cells)
{
    occmap_t *m = occmap_create(width, height, resolution, origin_x, origin_y);
    if (!m)
        return NULL;
    memcpy(m->cells, cells, (size_t)width * height);
    return align(m, origin_yaw);
}

/* A number in [lo, hi] (lo excluded when lo_open), else an error at the node. */
static int read_number(const marie_node_t *n, const char *key, double lo, double hi, bool lo_open, double *out,
                       marie_errors_t *errs)
{
    if (n->kind != MARIE_NODE_SCALAR) {
        marie_errors_add(errs, n->file, n->line, n->col, "%s: expected a number", key);
        return -1;
    }
    if (marie_node_double(n, out, errs) < 0)
        return -1;
    if (!isfinite(*out) || *out > hi || *out < lo || (lo_open && *out == lo)) {
        marie_errors_add(errs, n->file, n->line, n->col, "%s: %g is out of range, expected %s%g, %g]", key, *out,
                         lo_open ? "(" : "[", lo, hi);
        return -1;
    }
    return 0;
}

static const marie_node_t *required(const marie_node_t *root, const char *key, const char *yaml, marie_errors_t *errs)
{
    const marie_node_t *n = marie_node_get(root, key);
    if (!n)
        marie_errors_add(errs, yaml, root->line, root->col, "map: missing key '%s'", key);
    return n;
}

static void read_origin(const marie_node_t *o, occmap_meta_t *meta, marie_errors_t *errs)
{
    if (o->kind != MARIE_NODE_SEQ || o->n != 3) {
        marie_errors_add(errs, o->file, o->line, o->col, "origin: expected [x, y, yaw]");
        return;
    }
    double v[3] = { 0 };
    for (int k = 0; k < 3; k++)
        read_number(o->items[k], "origin", -1e9, 1e9, false, &v[k], errs);
    meta->origin_x = v[0];
    meta->origin_y = v[1];
    meta->origin_yaw = remainder(v[2], 2 * M_PI);
}

/* negate: 0 or 1 as map_server writes it, or true/false as YAML users do. */
static void read_negate(const marie_node_t *n, occmap_meta_t *meta, marie_errors_t *errs)
{
    const char *s = n->kind == MARIE_NODE_SCALAR && n->value ? n->value : "";
    if (!strcmp(s, "0") || !strcmp(s, "false"))
        meta->negate = false;
    else if (!strcmp(s, "1") || !strcmp(s, "true"))
        meta->negate = true;
    else
        marie_errors_add(errs, n->file, n->line, n->col, "negate: expected 0, 1, true or false, got '%s'", s);
}

static void read_mode(const marie_node_t *n, occmap_meta_t *meta, marie_errors_t *errs)
{
    const char *s = NULL;
    if (marie_node_str(n, &s, errs) < 0)
        return;
    if (!strcmp(s, "trinary"))
        meta->mode = OCCMAP_TRINARY;
    else if (!strcmp(s, "scale"))
        meta->mode = OCCMAP_SCALE;
    else if (!strcmp(s, "raw"))
        meta->mode = OCCMAP_RAW;
    else
        marie_errors_add(errs, n->file, n->line, n->col, "mode: expected trinary, scale or raw, got '%s'", s);
}

static char *image_path(const marie_node_t *n, const char *yaml, marie_errors_t *errs)
{
    const char *image = NULL;
    if (marie_node_str(n, &image, errs) < 0)
        return NULL;
    if (!*image) {
        marie_errors_add(errs, n->file, n->line, n->col, "image: empty file name");
        return NULL;
    }
    /* Relative image paths are relative to the YAML file, as in map_server. */
    const char *slash = strrchr(yaml, '/');
    char *path = NULL;
    if (image[0] == '/' || !slash)
        path = strdup(image);
    else if (asprintf(&path, "%.*s/%s", (int)(slash - yaml), yaml, image) < 0)
        path = NULL;
    if (!path)
        marie_errors_add(errs, n->file, n->line, n->col, "image: %s", strerror(ENOMEM));
    return path;
}

/* Read and check a map.yaml (file:line:col errors in errs) and return the image path it names,
 * resolved against the yaml's folder, which the caller frees; NULL on error. */
static char *occmap_read_meta(const char *yaml_path, occmap_meta_t *meta, marie_errors_t *errs)
{
    *meta = (occmap_meta_t){ .mode = OCCMAP_TRINARY, .occupied_thresh = 0.65, .free_thresh = 0.196 };
    marie_doc_t *doc = marie_doc_load(yaml_path, errs);
    if (!doc)
        return NULL;
    char *path = NULL;
    size_t nerr = errs->n;
    const marie_node_t *root = marie_doc_root(doc), *n;
    if (!root || root->kind != MARIE_NODE_MAP) {
        marie_errors_add(errs, yaml_path, root ? root->line : 1, root ? root->col : 1,
                         "map: expected a mapping with image, resolution, origin, ...");
        goto out;
    }
    /* Keys map_server does not know are ignored, as map_server does: maps from other tools
     * carry their own (docs/map.md). */
    if ((n = required(root, "resolution", yaml_path, errs)))
        read_number(n, "resolution", 0, 100, true, &meta->resolution, errs);
    if ((n = required(root, "origin", yaml_path, errs)))
        read_origin(n, meta, errs);
    if ((n = marie_node_get(root, "negate")))
        read_negate(n, meta, errs);
    if ((n = marie_node_get(root, "mode")))
        read_mode(n, meta, errs);
    if ((n = marie_node_get(root, "occupied_thresh")))
        read_number(n, "occupied_thresh", 0, 1, false, &meta->occupied_thresh, errs);
    if ((n = marie_node_get(root, "free_thresh")))
        read_number(n, "free_thresh", 0, 1, false, &meta->free_thresh, errs);
    if (meta->free_thresh > meta->occupied_thresh) {
        n = marie_node_get(root, "free_thresh");
        if (!n)
            n = marie_node_get(root, "occupied_thresh");
        marie_errors_add(errs, n->file, n->line, n->col, "free_thresh %g is above occupied_thresh %g",
                         meta->free_thresh, meta->occupied_thresh);
    }
    if ((n = required(root, "image", yaml_path, errs))) {
        path = image_path(n, yaml_path, errs);
        meta->image_line = n->line;
        meta->image_col = n->col;
    }
    if (errs->n != nerr) {
        MARIE_CLEAR(path, free);
    }
out:
    marie_doc_destroy(doc);
    return path;
}

occmap_t *occmap_load(const char *yaml_path, marie_errors_t *errs)
{
    occmap_meta_t meta;
    char *path = occmap_read_meta(yaml_path, &meta, errs);
    if (!path)
        return NULL;
    occmap_t *m = NULL;
    pgm_t img = { 0 };
    size_t len = 0;
    char why[200];
    uint8_t *buf = marie_file_read(path, OCCMAP_MAX_IMAGE_BYTES, &len);
    if (!buf) {
        marie_errors_add(errs, yaml_path, meta.image_line, meta.image_col, "image %s: cannot read: %s", path, strerror(errno));
        goto out;
    }
    if (pgm_parse(buf, len, &img, why, sizeof why) < 0) {
        marie_errors_add(errs, yaml_path, meta.image_line, meta.image_col, "image %s: %s%s", path, why,
                         len > 4 && !memcmp(buf, "\x89PNG", 4) ? " (PNG images are not read: convert to PGM)" : "");
        goto out;
    }
    m = occmap_from_image(&img, &meta);
    if (!m)
        marie_errors_add(errs, yaml_path, meta.image_line, meta.image_col, "image %s: %dx%d cells at %g m: %s", path, img.width, img.height,
                         meta.resolution, strerror(errno));
out:
    free(img.pixels);
    free(buf);
    free(path);
    return m;
}

void occmap_world_path(const char *name, char *out, size_t len)
{
    if (strchr(name, '/') || strstr(name, ".yaml")) {
        snprintf(out, len, "%s", name);
        return;
    }
    const char *dirs[] = { getenv("MARIE_SIM_WORLDS"), "sim/worlds", "/usr/local/share/marie/worlds" };
    for (size_t i = 0; i < sizeof(dirs) / sizeof(dirs[0]); i++) {
        if (!dirs[i])
            continue;
        snprintf(out, len, "%s/%s.yaml", dirs[i], name);
        if (access(out, R_OK) == 0)
            return;
    }
    snprintf(out, len, "sim/worlds/%s.yaml", name);
}
