/* occmap_load: reads a ROS map_server map.yaml and the PGM image it names. */
#include "adapters/common/occmap.h"

#include <errno.h>
#include <libgen.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static uint8_t *read_file(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    uint8_t *buf = NULL;
    if (fseek(f, 0, SEEK_END) == 0) {
        long n = ftell(f);
        if (n >= 0 && fseek(f, 0, SEEK_SET) == 0 && (buf = malloc(n ? n : 1)) != NULL) {
            if (fread(buf, 1, n, f) != (size_t)n) {
                free(buf);
                buf = NULL;
            } else {
                *len = n;
            }
        }
    }
    int e = errno;
    fclose(f);
    errno = e;
    return buf;
}

occmap_t *occmap_load(const char *yaml_path, marie_errors_t *errs)
{
    static const char *const keys[] = { "image", "resolution", "origin", "negate", "occupied_thresh",
                                        "free_thresh", "mode", NULL };
    occmap_t *m = NULL;
    marie_doc_t *doc = marie_doc_load(yaml_path, errs);
    if (!doc)
        return NULL;
    const marie_node_t *root = marie_doc_root(doc);
    if (!root || root->kind != MARIE_NODE_MAP) {
        marie_errors_add(errs, yaml_path, root ? root->line : 1, root ? root->col : 1, "map file: expected a mapping");
        goto out;
    }
    size_t nerr = errs->n;
    marie_node_check_keys(root, keys, "map", errs);
    const char *image = NULL;
    occmap_meta_t meta = { .resolution = 0, .occupied_thresh = 0.65, .free_thresh = 0.196 };
    int64_t neg = 0;
    const marie_node_t *n;
    if (!(n = marie_node_get(root, "image")))
        marie_errors_add(errs, yaml_path, root->line, root->col, "map: missing 'image'");
    else
        marie_node_str(n, &image, errs);
    if (!(n = marie_node_get(root, "resolution")))
        marie_errors_add(errs, yaml_path, root->line, root->col, "map: missing 'resolution'");
    else if (marie_node_double(n, &meta.resolution, errs) == 0 && !(meta.resolution > 0))
        marie_errors_add(errs, n->file, n->line, n->col, "resolution: must be > 0");
    if ((n = marie_node_get(root, "origin"))) {
        if (n->kind != MARIE_NODE_SEQ || n->n < 2)
            marie_errors_add(errs, n->file, n->line, n->col, "origin: expected [x, y, theta]");
        else {
            marie_node_double(n->items[0], &meta.origin_x, errs);
            marie_node_double(n->items[1], &meta.origin_y, errs);
        }
    }
    if ((n = marie_node_get(root, "negate")))
        marie_node_int(n, &neg, errs);
    meta.negate = neg != 0;
    if ((n = marie_node_get(root, "occupied_thresh")))
        marie_node_double(n, &meta.occupied_thresh, errs);
    if ((n = marie_node_get(root, "free_thresh")))
        marie_node_double(n, &meta.free_thresh, errs);
    if (errs->n != nerr)
        goto out;
    char path[4096];
    if (image[0] == '/') {
        snprintf(path, sizeof(path), "%s", image);
    } else {
        char *dup = strdup(yaml_path);
        if (!dup)
            goto out;
        snprintf(path, sizeof(path), "%s/%s", dirname(dup), image);
        free(dup);
    }
    size_t len = 0;
    uint8_t *buf = read_file(path, &len);
    n = marie_node_get(root, "image");
    if (!buf) {
        marie_errors_add(errs, n->file, n->line, n->col, "image: cannot read %s: %s", path, strerror(errno));
        goto out;
    }
    char why[160];
    m = occmap_from_pgm(buf, len, &meta, why, sizeof(why));
    if (!m)
        marie_errors_add(errs, n->file, n->line, n->col, "image %s: %s", path, why);
    free(buf);
out:
    marie_doc_destroy(doc);
    return m;
}
