/* occmap_save: writes an occupancy grid as a ROS map_server pair (map.yaml + PGM), as
 * map_saver does, so that occmap_load() and map_server read back the same cells. */
#include "map/occmap.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* map_saver's pixels: occupied black, free white, unknown 205 (just above free_thresh). */
uint8_t occmap_save_pixel(int8_t v)
{
    if (v < 0 || v > 100)
        return 205;
    return (uint8_t)((100 - v) * 255 / 100);
}

/* Write buf to path through a temporary file, so a reader never sees half a map. */
static int write_atomic(const char *path, const void *a, size_t alen, const void *b, size_t blen)
{
    size_t n = strlen(path) + 8;
    char *tmp = malloc(n);
    if (!tmp)
        return -1;
    snprintf(tmp, n, "%s.tmpXX", path);
    FILE *f = fopen(tmp, "wb");
    if (!f)
        goto err_free;
    if (fwrite(a, 1, alen, f) != alen || (blen && fwrite(b, 1, blen, f) != blen)) {
        int e = errno ? errno : EIO;
        fclose(f);
        errno = e;
        goto err_unlink;
    }
    if (fclose(f) != 0 || rename(tmp, path) != 0)
        goto err_unlink;
    free(tmp);
    return 0;
err_unlink: {
    int e = errno;
    unlink(tmp);
    errno = e;
}
err_free:
    free(tmp);
    return -1;
}

int occmap_save(const occmap_t *m, const char *yaml_path)
{
    size_t len = yaml_path ? strlen(yaml_path) : 0;
    if (!m || !m->cells || m->width <= 0 || m->height <= 0 || !(m->resolution > 0) || len < 6 ||
        strcmp(yaml_path + len - 5, ".yaml") != 0) {
        errno = EINVAL;
        return -1;
    }
    char *pgm_path = malloc(len);
    if (!pgm_path)
        return -1;
    snprintf(pgm_path, len, "%.*s.pgm", (int)(len - 5), yaml_path);
    const char *slash = strrchr(pgm_path, '/');
    const char *image = slash ? slash + 1 : pgm_path;
    char hdr[64];
    int hlen = snprintf(hdr, sizeof(hdr), "P5\n%d %d\n255\n", m->width, m->height);
    size_t npx = (size_t)m->width * m->height;
    uint8_t *px = malloc(npx);
    char yaml[512 + 4096];
    int rc = -1;
    if (!px)
        goto out;
    /* PGM row 0 is the top of the map; occmap row 0 the bottom. */
    for (int y = 0; y < m->height; y++)
        for (int x = 0; x < m->width; x++)
            px[(size_t)(m->height - 1 - y) * m->width + x] = occmap_save_pixel(m->cells[(size_t)y * m->width + x]);
    int ylen = snprintf(yaml, sizeof(yaml),
                        "image: %s\nresolution: %.6f\norigin: [%.6f, %.6f, 0.0]\nnegate: 0\n"
                        "occupied_thresh: 0.65\nfree_thresh: 0.196\n",
                        image, m->resolution, m->origin_x, m->origin_y);
    if (ylen < 0 || (size_t)ylen >= sizeof(yaml)) {
        errno = ENAMETOOLONG;
        goto out;
    }
    /* The image first: a yaml is only there once what it names is complete. */
    if (write_atomic(pgm_path, hdr, (size_t)hlen, px, npx) || write_atomic(yaml_path, yaml, (size_t)ylen, NULL, 0))
        goto out;
    rc = 0;
out:
    free(px);
    free(pgm_path);
    return rc;
}
