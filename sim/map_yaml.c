/* map_yaml: map.yaml through libmarie's YAML tree, so every error carries file:line:col. */
#include "sim/map.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int read_file(const char *path, uint8_t **buf, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return -errno;
    size_t cap = 1 << 16, n = 0;
    uint8_t *b = malloc(cap);
    int rc = 0;
    while (b) {
        if (n == cap) {
            uint8_t *g = cap > (size_t)1 << 31 ? NULL : realloc(b, cap * 2);
            if (!g) {
                rc = -ENOMEM;
                break;
            }
            b = g;
            cap *= 2;
        }
        size_t got = fread(b + n, 1, cap - n, f);
        n += got;
        if (got == 0) {
            if (ferror(f))
                rc = -EIO;
            break;
        }
    }
    if (!b)
        rc = -ENOMEM;
    fclose(f);
    if (rc) {
        free(b);
        return rc;
    }
    *buf = b;
    *len = n;
    return 0;
}

/* A number node in [lo, hi] (hi_open: strictly below hi), else an error at the node. */
static int get_number(const marie_node_t *root, const char *key, double lo, double hi, int lo_open,
                      double *out, marie_errors_t *errs, const char *file)
{
    const marie_node_t *n = marie_node_get(root, key);
    if (!n) {
        marie_errors_add(errs, file, root->line, root->col, "map: missing key '%s'", key);
        return -1;
    }
    if (n->kind != MARIE_NODE_SCALAR) {
        marie_errors_add(errs, n->file, n->line, n->col, "%s: expected a number", key);
        return -1;
    }
    if (marie_node_double(n, out, errs) < 0)
        return -1;
    if (!isfinite(*out) || *out > hi || *out < lo || (lo_open && *out == lo)) {
        marie_errors_add(errs, n->file, n->line, n->col, "%s: %g is out of range, expected %s%g, %g]",
                         key, *out, lo_open ? "(" : "[", lo, hi);
        return -1;
    }
    return 0;
}

sim_map_t *sim_map_load(const char *yaml_path, marie_errors_t *errs)
{
    marie_doc_t *doc = marie_doc_load(yaml_path, errs);
    if (!doc)
        return NULL;
    sim_map_t *map = NULL;
    uint8_t *buf = NULL;
    size_t len = 0;
    sim_pgm_t pgm = { 0 };
    char *img_path = NULL;
    size_t nerr = errs->n;
    const marie_node_t *root = marie_doc_root(doc);
    if (!root || root->kind != MARIE_NODE_MAP) {
        marie_errors_add(errs, yaml_path, root ? root->line : 1, root ? root->col : 1,
                         "map: expected a mapping with image, resolution, origin, ...");
        goto out;
    }
    sim_map_info_t info = { .negate = 0, .occupied_thresh = 0.65, .free_thresh = 0.196 };
    get_number(root, "resolution", 0.0, 100.0, 1, &info.resolution, errs, yaml_path);

    const marie_node_t *o = marie_node_get(root, "origin");
    if (!o) {
        marie_errors_add(errs, yaml_path, root->line, root->col, "map: missing key 'origin'");
    } else if (o->kind != MARIE_NODE_SEQ || o->n != 3) {
        marie_errors_add(errs, o->file, o->line, o->col, "origin: expected [x, y, yaw]");
    } else {
        for (int k = 0; k < 3; k++)
            if (marie_node_double(o->items[k], &info.origin[k], errs) == 0 && !isfinite(info.origin[k]))
                marie_errors_add(errs, o->file, o->items[k]->line, o->items[k]->col,
                                 "origin: not a finite number");
    }
    const marie_node_t *ng = marie_node_get(root, "negate");
    if (ng) {
        int64_t v = 0;
        bool b;
        if (ng->kind == MARIE_NODE_SCALAR && ng->value &&
            (strcmp(ng->value, "true") == 0 || strcmp(ng->value, "false") == 0)) {
            if (marie_node_bool(ng, &b, errs) == 0)
                info.negate = b;
        } else if (marie_node_int(ng, &v, errs) == 0) {
            if (v != 0 && v != 1)
                marie_errors_add(errs, ng->file, ng->line, ng->col, "negate: expected 0 or 1, got %lld",
                                 (long long)v);
            info.negate = v == 1;
        }
    }
    if (marie_node_get(root, "occupied_thresh"))
        get_number(root, "occupied_thresh", 0.0, 1.0, 0, &info.occupied_thresh, errs, yaml_path);
    if (marie_node_get(root, "free_thresh"))
        get_number(root, "free_thresh", 0.0, 1.0, 0, &info.free_thresh, errs, yaml_path);
    if (info.free_thresh > info.occupied_thresh) {
        const marie_node_t *n = marie_node_get(root, "free_thresh");
        marie_errors_add(errs, n ? n->file : yaml_path, n ? n->line : root->line, n ? n->col : root->col,
                         "free_thresh %g is above occupied_thresh %g", info.free_thresh,
                         info.occupied_thresh);
    }
    const marie_node_t *mode = marie_node_get(root, "mode");
    if (mode) {
        const char *s = NULL;
        if (marie_node_str(mode, &s, errs) == 0 && strcmp(s, "trinary") != 0 && strcmp(s, "scale") != 0)
            marie_errors_add(errs, mode->file, mode->line, mode->col,
                             "mode: '%s' is not supported (trinary or scale)", s);
    }

    const marie_node_t *im = marie_node_get(root, "image");
    const char *image = NULL;
    if (!im) {
        marie_errors_add(errs, yaml_path, root->line, root->col, "map: missing key 'image'");
    } else if (marie_node_str(im, &image, errs) == 0) {
        if (!image || !*image) {
            marie_errors_add(errs, im->file, im->line, im->col, "image: empty file name");
            image = NULL;
        }
    }
    if (image && errs->n == nerr) {
        /* Relative image paths are relative to the YAML file, as in map_server. */
        const char *slash = strrchr(yaml_path, '/');
        if (image[0] == '/' || !slash)
            img_path = strdup(image);
        else if (asprintf(&img_path, "%.*s/%s", (int)(slash - yaml_path), yaml_path, image) < 0)
            img_path = NULL;
        if (!img_path) {
            marie_errors_add(errs, im->file, im->line, im->col, "image: out of memory");
            goto out;
        }
        int rc = read_file(img_path, &buf, &len);
        if (rc) {
            marie_errors_add(errs, im->file, im->line, im->col, "image: cannot read %s: %s", img_path,
                             strerror(-rc));
            goto out;
        }
        char why[160];
        if (sim_pgm_parse(buf, len, &pgm, why, sizeof(why))) {
            marie_errors_add(errs, im->file, im->line, im->col, "image: %s: %s", img_path, why);
            goto out;
        }
        map = sim_map_from_pgm(&pgm, &info);
        if (!map)
            marie_errors_add(errs, im->file, im->line, im->col, "image: out of memory");
    }
out:
    free(pgm.pixels);
    free(buf);
    free(img_path);
    marie_doc_destroy(doc);
    return map;
}
