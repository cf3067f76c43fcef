/* test_map: the one map library: PGM images, map_server's semantics for every map.yaml variant,
 * the origin's yaw, ray casting, and bad files refused with file:line. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "map/occmap.h"
#include "map/clearance.h"
#include "map/gridpath.h"
#include <errno.h>

#define DATA "tests/data/map/"

static void test_pgm_formats(void **state)
{
    const char p2[] = "P2\n# c\n3 2\n# another\n15\n0 1 2\n13 14 15\n";
    const uint8_t p5[] = "P5 3 2 255\n\x01\x02\x03\x04\x05\xff";
    const uint8_t p5_16[] = "P5\n2 1\n1000\n\x03\xe8\x00\x07";
    pgm_t g;
    char err[160];
    assert_int_equal(pgm_parse((const uint8_t *)p2, strlen(p2), &g, err, sizeof(err)), 0);
    assert_int_equal(g.width, 3);
    assert_int_equal(g.height, 2);
    assert_int_equal(g.maxval, 15);
    assert_int_equal(g.pixels[5], 15);
    free(g.pixels);
    assert_int_equal(pgm_parse(p5, sizeof(p5) - 1, &g, err, sizeof(err)), 0);
    assert_int_equal(g.pixels[0], 1);
    assert_int_equal(g.pixels[5], 255);
    free(g.pixels);
    assert_int_equal(pgm_parse(p5_16, sizeof(p5_16) - 1, &g, err, sizeof(err)), 0);
    assert_int_equal(g.pixels[0], 1000);
    assert_int_equal(g.pixels[1], 7);
    free(g.pixels);
    /* Every malformed header or raster is refused with a reason, never read past. */
    const char *bad[] = { "", "P6\n1 1\n255\n\x00", "P5\n0 1\n255\n", "P5\n1 1\n0\n\x00",
                          "P5\n2 2\n255\n\x00", "P2\n2 1\n9\n1", "P2\n2 1\n9\n1 10",
                          "P5\n99999 1\n255\n", "P5\n1 1\n70000\n\x00\x00", "P5\n1 1\n255",
                          "P2 1 1 9 x", "P5\n-1 2\n255\n", "P5\n99999999999 1\n255\n" };
    for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
        err[0] = 0;
        assert_int_not_equal(pgm_parse((const uint8_t *)bad[i], strlen(bad[i]), &g, err, sizeof(err)), 0);
        assert_true(strlen(err) > 0);
        assert_null(g.pixels);
    }
}

/* The map's cells as text, bottom row first: O occupied, F free, U unknown, else the number. */
static void cells_text(const occmap_t *m, char *out, size_t cap)
{
    size_t n = 0;
    for (int j = 0; j < m->height; j++) {
        for (int i = 0; i < m->width; i++) {
            int8_t v = occmap_get(m, i, j);
            n += (size_t)(v == OCCMAP_OCCUPIED ? snprintf(out + n, cap - n, "O")
                          : v == OCCMAP_FREE   ? snprintf(out + n, cap - n, "F")
                          : v == OCCMAP_UNKNOWN ? snprintf(out + n, cap - n, "U")
                                                : snprintf(out + n, cap - n, "%d", v));
        }
        if (j + 1 < m->height)
            n += (size_t)snprintf(out + n, cap - n, " ");
    }
}

/* map_server's variants of one 4x3 image (tests/data/map/small.pgm: black, white and a 0xcd
 * grey at p = 0.196): what each map.yaml means, or why it is refused (the error's line). */
static const struct variant {
    const char *name, *yaml;
    const char *cells;          /* bottom row first; NULL: refused */
    int line;                   /* of the error */
    const char *why;
} variants[] = {
    { "trinary", "image: small.pgm\nresolution: 0.1\norigin: [-1.0, 2.0, 0.0]\n", "OOFF FUFF OFFO", 0, NULL },
    { "explicit defaults", "image: small.pgm\nresolution: 0.1\norigin: [-1, 2, 0]\nmode: trinary\nnegate: 0\n"
      "occupied_thresh: 0.65\nfree_thresh: 0.196\n", "OOFF FUFF OFFO", 0, NULL },
    { "negate 1", "image: small.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 1\n", "FFOO OOOO FOOF", 0, NULL },
    { "negate true", "image: small.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: true\n", "FFOO OOOO FOOF", 0, NULL },
    { "scale", "image: small.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: scale\nfree_thresh: 0.1\n"
      "occupied_thresh: 0.5\n", "OOFF F23FF OFFO", 0, NULL },
    { "raw", "image: small.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: raw\n", "FFUU UUUU FUUF", 0, NULL },
    { "keys of other tools", "image: small.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmap_type: occupancy\n",
      "OOFF FUFF OFFO", 0, NULL },
    { "thresholds above 1", "image: small.pgm\nresolution: 0.1\norigin: [0, 0, 0]\noccupied_thresh: 1.5\n", NULL, 4,
      "occupied_thresh" },
    { "free above occupied", "image: small.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nfree_thresh: 0.7\n", NULL, 4,
      "above occupied_thresh" },
    { "negate 2", "image: small.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 2\n", NULL, 4, "negate" },
    { "no origin", "image: small.pgm\nresolution: 0.1\n", NULL, 1, "missing key 'origin'" },
    { "short origin", "image: small.pgm\nresolution: 0.1\norigin: [0, 0]\n", NULL, 3, "origin" },
    { "unknown mode", "image: small.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: fancy\n", NULL, 4, "mode" },
    { "no resolution", "image: small.pgm\norigin: [0, 0, 0]\n", NULL, 1, "missing key 'resolution'" },
    { "word resolution", "image: small.pgm\nresolution: fast\norigin: [0, 0, 0]\n", NULL, 2, "resolution" },
    { "zero resolution", "image: small.pgm\nresolution: 0\norigin: [0, 0, 0]\n", NULL, 2, "resolution" },
    { "nan origin", "image: small.pgm\nresolution: 0.1\norigin: [.nan, 0, 0]\n", NULL, 3, "'.nan'" },
    { "no image", "resolution: 0.1\norigin: [0, 0, 0]\n", NULL, 1, "missing key 'image'" },
    { "missing image", "image: nowhere.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n", NULL, 1, "nowhere.pgm" },
    { "corrupt image", "image: corrupt.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n", NULL, 1, "truncated" },
};

static void test_map_server_variants(void **state)
{
    char path[] = DATA "variant.yaml";
    for (size_t k = 0; k < sizeof variants / sizeof variants[0]; k++) {
        const struct variant *v = &variants[k];
        FILE *f = fopen(path, "w");
        assert_non_null(f);
        fputs(v->yaml, f);
        fclose(f);
        marie_errors_t errs = { 0 };
        occmap_t *m = occmap_load(path, &errs);
        fprintf(stderr, "variant %-20s %s\n", v->name, m ? "loaded" : errs.n ? errs.msgs[0] : "?");
        if (v->cells) {
            assert_non_null(m);
            char text[128];
            cells_text(m, text, sizeof text);
            if (strcmp(text, v->cells) != 0)
                fail_msg("%s: cells %s, expected %s", v->name, text, v->cells);
        } else {
            assert_null(m);
            char want[64];
            snprintf(want, sizeof want, "%s:%d:", path, v->line);
            bool found = false;
            for (size_t i = 0; i < errs.n; i++)
                found |= strstr(errs.msgs[i], want) && strstr(errs.msgs[i], v->why);
            if (!found)
                fail_msg("%s: no error '%s' at %s", v->name, v->why, want);
        }
        occmap_destroy(m);
        marie_errors_clear(&errs);
    }
    unlink(path);
}

/* A rotated origin: the grid comes back aligned with the map frame, covering the rotated
 * image, with every occupied source cell still occupied where it lies in the world. */
static void test_origin_yaw(void **state)
{
    occmap_t *src = occmap_make_office(12, 8, 0.05, 3);
    assert_non_null(src);
    pgm_t img = { src->width, src->height, 255, malloc((size_t)src->width * src->height * sizeof(uint16_t)) };
    for (int j = 0; j < src->height; j++)
        for (int i = 0; i < src->width; i++)
            img.pixels[(size_t)(src->height - 1 - j) * src->width + i] = occmap_get(src, i, j) == OCCMAP_OCCUPIED ? 0 : 254;
    const double yaw = 0.3, ox = 1.5, oy = -2.0;
    occmap_meta_t meta = { .resolution = 0.05, .origin_x = ox, .origin_y = oy, .origin_yaw = yaw,
                           .occupied_thresh = 0.65, .free_thresh = 0.196 };
    occmap_t *m = occmap_from_image(&img, &meta);
    assert_non_null(m);
    double W = 12, H = 8, c = cos(yaw), s = sin(yaw);
    assert_true(fabs(m->width * 0.05 - (W * c + H * s)) < 0.1 && fabs(m->height * 0.05 - (W * s + H * c)) < 0.1);
    assert_true(fabs(m->origin_x - (ox - H * s)) < 0.051 && fabs(m->origin_y - oy) < 0.051);
    size_t occupied = 0, free_kept = 0, free_total = 0;
    for (int j = 0; j < src->height; j++)
        for (int i = 0; i < src->width; i++) {
            double lx = (i + 0.5) * 0.05, ly = (j + 0.5) * 0.05;
            double x = ox + c * lx - s * ly, y = oy + s * lx + c * ly;
            if (occmap_get(src, i, j) == OCCMAP_OCCUPIED) {
                assert_true(occmap_occupied_at(m, x, y));
                occupied++;
            } else {
                free_total++;
                free_kept += !occmap_occupied_at(m, x, y);
            }
        }
    /* Walls thicken by at most a cell: most free space stays free. */
    assert_true(occupied > 100 && free_kept > 0.85 * free_total);
    /* Outside the rotated image is unknown. */
    assert_int_equal(occmap_get(m, 0, 0), OCCMAP_UNKNOWN);
    occmap_destroy(m);
    free(img.pixels);
    occmap_destroy(src);
}

/* A thin wall at 45 degrees stays closed to rays after resampling. */
static void test_rotated_wall_stays_closed(void **state)
{
    pgm_t img = { 40, 40, 255, malloc(40 * 40 * sizeof(uint16_t)) };
    for (int k = 0; k < 40 * 40; k++)
        img.pixels[k] = 254;
    for (int r = 0; r < 40; r++)
        img.pixels[r * 40 + 20] = 0;            /* a one-cell wall down column 20 */
    occmap_meta_t meta = { .resolution = 0.1, .origin_yaw = M_PI / 4, .occupied_thresh = 0.65, .free_thresh = 0.196 };
    occmap_t *m = occmap_from_image(&img, &meta);
    assert_non_null(m);
    /* In the image frame the wall is the line lx = 2.05; cast across it at many places. */
    double c = cos(M_PI / 4), s = sin(M_PI / 4);
    for (double ly = 0.5; ly < 3.5; ly += 0.037) {
        double x = c * 1.0 - s * ly, y = s * 1.0 + c * ly;
        double d = occmap_raycast(m, x, y, M_PI / 4, 3.0);   /* along +lx */
        assert_true(d < 1.3);
    }
    occmap_destroy(m);
    free(img.pixels);
}

static void test_raycast_hits_walls(void **state)
{
    occmap_t *m = occmap_create(100, 100, 0.1, 0, 0);
    occmap_fill_rect(m, 8.0, 0, 8.1, 10, OCCMAP_OCCUPIED);
    assert_true(fabs(occmap_raycast(m, 2.05, 5.05, 0, 20) - 5.95) < 1e-9);
    double d = occmap_raycast(m, 2.0, 5.0, M_PI / 4, 20);           /* leaves the map at y=10 before x=8 */
    assert_true(fabs(d - 5.0 * sqrt(2.0)) < 1e-9);
    d = occmap_raycast(m, 2.0, 5.0, -M_PI / 8, 20);
    assert_true(fabs(d - 6.0 / cos(M_PI / 8)) < 1e-9);
    assert_true(occmap_raycast(m, 2.0, 5.0, 0, 3.0) == 3.0);          /* nothing within range */
    assert_true(fabs(occmap_raycast(m, 2.0, 5.0, M_PI, 20) - 2.0) < 1e-9);  /* the map's edge */
    occmap_destroy(m);
}

static void test_small_files_load(void **state)
{
    const char *files[] = { DATA "small.yaml", DATA "small_ascii.yaml" };
    for (int f = 0; f < 2; f++) {
        marie_errors_t errs = { 0 };
        occmap_t *m = occmap_load(files[f], &errs);
        assert_non_null(m);
        assert_int_equal(m->width, 4);
        assert_int_equal(m->height, 3);
        assert_true(fabs(m->resolution - 0.1) < 1e-12);
        assert_true(fabs(m->origin_x + 1.0) < 1e-12 && fabs(m->origin_y - 2.0) < 1e-12);
        char text[64];
        cells_text(m, text, sizeof text);
        assert_string_equal(text, "OOFF FUFF OFFO");
        double x, y;
        occmap_cell_center(m, 0, 0, &x, &y);
        assert_true(fabs(x + 0.95) < 1e-9 && fabs(y - 2.05) < 1e-9);
        assert_true(occmap_occupied_at(m, -1.5, 0));                  /* outside counts as blocked */
        occmap_destroy(m);
    }
}

static void test_bad_files(void **state)
{
    static const struct { const char *file; int line; const char *why; } bad[] = {
        { "missing_image.yaml", 1, "missing key 'image'" }, { "zero_resolution.yaml", 2, "resolution" },
        { "negative_resolution.yaml", 2, "resolution" }, { "word_resolution.yaml", 2, "resolution" },
        { "bad_yaml.yaml", 0, "bad_yaml.yaml" }, { "no_such_image.yaml", 1, "No such file" },
        { "corrupt_image.yaml", 1, "truncated" }, { "bad_thresh.yaml", 4, "occupied_thresh" },
        { "short_origin.yaml", 3, "origin" }, { "does_not_exist.yaml", 0, "does_not_exist.yaml" },
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        char path[128], want[160];
        snprintf(path, sizeof path, DATA "%s", bad[k].file);
        snprintf(want, sizeof want, "%s:%d:", path, bad[k].line);
        marie_errors_t errs = { 0 };
        assert_null(occmap_load(path, &errs));
        bool found = false;
        for (size_t i = 0; i < errs.n; i++)
            found |= (bad[k].line == 0 || strstr(errs.msgs[i], want)) && strstr(errs.msgs[i], bad[k].why);
        if (!found)
            fail_msg("%s: expected '%s' at line %d", bad[k].file, bad[k].why, bad[k].line);
        marie_errors_clear(&errs);
    }
}

static void test_office_world_loads(void **state)
{
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load("sim/worlds/office.yaml", &errs);
    assert_non_null(m);
    assert_true(fabs(m->width * m->resolution - 40) < 0.1 && fabs(m->height * m->resolution - 30) < 0.1);
    assert_true(occmap_occupied_at(m, 0.05, 15));    /* outer wall */
    assert_false(occmap_occupied_at(m, 10, 15));     /* main corridor */
    occmap_destroy(m);
}

/* gridpath: the shortest 8-connected path around a wall, never through a blocked corner, none
 * when the goal is walled off, and the straightened path keeps only the turning cells. */
static void test_gridpath(void **state)
{
    enum { W = 20, H = 10 };
    uint8_t pass[W * H];
    memset(pass, 1, sizeof pass);
    for (int y = 0; y < 8; y++)
        pass[y * W + 10] = 0;                       /* a wall at x = 10, open at y 8..9 */
    int *cells = NULL, n = 0;
    double len = gridpath_find(W, H, pass, 0 * W + 2, 0 * W + 18, &cells, &n);
    assert_true(fabs(len - (14 * M_SQRT2 + 4)) < 1e-9);   /* diagonals, but straight past the wall's corners */
    assert_int_equal(cells[0], 2);
    assert_int_equal(cells[n - 1], 18);
    for (int i = 0; i < n; i++)
        assert_true(pass[cells[i]]);
    for (int i = 0; i + 1 < n; i++) {               /* 8-connected steps, no corner cut */
        int ax = cells[i] % W, ay = cells[i] / W, bx = cells[i + 1] % W, by = cells[i + 1] / W;
        assert_true(abs(ax - bx) <= 1 && abs(ay - by) <= 1);
        if (ax != bx && ay != by)
            assert_true(pass[ay * W + bx] && pass[by * W + ax]);
    }
    int m = gridpath_shortcut(W, H, pass, cells, n);
    assert_true(m >= 3 && m < n);
    assert_int_equal(cells[0], 2);
    assert_int_equal(cells[m - 1], 18);
    free(cells);
    for (int y = 8; y < H; y++)
        pass[y * W + 10] = 0;                       /* now closed */
    assert_true(gridpath_find(W, H, pass, 2, 18, &cells, &n) < 0);
    assert_int_equal(errno, ENOENT);
    assert_null(cells);
    assert_true(gridpath_find(W, H, pass, 10, 18, NULL, NULL) < 0);   /* start in the wall */
    assert_int_equal(errno, EINVAL);
}

/* The reference: Bellman-Ford relaxation over the same moves (slow, obviously right). */
static double shortest_by_relaxation(int w, int h, const uint8_t *pass, int start, int goal)
{
    static double d[130 * 70];
    for (int i = 0; i < w * h; i++)
        d[i] = INFINITY;
    d[start] = 0;
    for (bool changed = true; changed;) {
        changed = false;
        for (int c = 0; c < w * h; c++) {
            if (!pass[c] || !isfinite(d[c]))
                continue;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int x = c % w + dx, y = c / w + dy;
                    if ((!dx && !dy) || x < 0 || y < 0 || x >= w || y >= h || !pass[y * w + x])
                        continue;
                    if (dx && dy && (!pass[(c / w) * w + x] || !pass[y * w + c % w]))
                        continue;
                    double nd = d[c] + (dx && dy ? M_SQRT2 : 1.0);
                    if (nd < d[y * w + x] - 1e-12) {
                        d[y * w + x] = nd;
                        changed = true;
                    }
                }
        }
    }
    return isfinite(d[goal]) ? d[goal] : -1;
}

/* On 300 random grids (10-40 % walls, rooms and noise; lines shorter than, equal to and longer
 * than the search's 64-cell words) the search finds a path exactly when one exists, as short as
 * the reference's, made of legal steps whose costs add up to the length. */
static void test_gridpath_is_shortest_on_random_grids(void **state)
{
    static const int sizes[][2] = { { 41, 29 }, { 64, 33 }, { 97, 64 }, { 130, 70 }, { 20, 128 } };
    static uint8_t pass[130 * 70];
    unsigned seed = 12345;
    int found = 0;
    for (int t = 0; t < 300; t++) {
        const int W = sizes[t % 5][0], H = sizes[t % 5][1];
        int walls = 10 + t % 29;
        for (int i = 0; i < W * H; i++)
            pass[i] = (int)(rand_r(&seed) % 100) >= walls;
        if (t % 2) {                                /* long walls with gaps: rooms and doors */
            for (int k = 0; k < 4; k++) {
                int at = (int)(rand_r(&seed) % W), gap = (int)(rand_r(&seed) % H);
                for (int y = 0; y < H; y++)
                    pass[y * W + at] = abs(y - gap) <= 1;
            }
        }
        int start = (int)(rand_r(&seed) % (W * H)), goal = (int)(rand_r(&seed) % (W * H));
        pass[start] = pass[goal] = 1;
        double want = shortest_by_relaxation(W, H, pass, start, goal);
        int *cells = NULL, n = 0;
        double got = gridpath_find(W, H, pass, start, goal, &cells, &n);
        if (want < 0) {
            assert_true(got < 0);
            assert_int_equal(errno, ENOENT);
            continue;
        }
        found++;
        assert_true(fabs(got - want) < 1e-9);
        assert_int_equal(cells[0], start);
        assert_int_equal(cells[n - 1], goal);
        double walked = 0;
        for (int i = 0; i + 1 < n; i++) {
            int ax = cells[i] % W, ay = cells[i] / W, bx = cells[i + 1] % W, by = cells[i + 1] / W;
            assert_true(pass[cells[i + 1]]);
            assert_true(abs(ax - bx) <= 1 && abs(ay - by) <= 1 && cells[i] != cells[i + 1]);
            if (ax != bx && ay != by)
                assert_true(pass[ay * W + bx] && pass[by * W + ax]);
            walked += ax != bx && ay != by ? M_SQRT2 : 1.0;
        }
        assert_true(fabs(walked - got) < 1e-9);
        free(cells);
    }
    assert_true(found > 100 && found < 300);        /* both outcomes were exercised */
}

/* The clearance is the exact distance from each centre to the nearest blocked centre, less half a
 * cell: checked against every blocked cell on random maps with unknown cells, both ways of
 * counting the unknown, and on a map with nothing blocked. */
static void test_clearance_is_exact(void **state)
{
    unsigned seed = 777;
    for (int t = 0; t < 40; t++) {
        int W = 5 + (int)(rand_r(&seed) % 60), H = 5 + (int)(rand_r(&seed) % 60);
        occmap_t *m = occmap_create(W, H, 0.05 * (1 + t % 4), -1.0, 2.0);
        assert_non_null(m);
        int density = t % 10 == 0 ? 0 : 1 + (int)(rand_r(&seed) % 15);
        for (int i = 0; i < W * H; i++) {
            int r = (int)(rand_r(&seed) % 100);
            m->cells[i] = r < density ? OCCMAP_OCCUPIED : r < density + 3 && t % 3 ? OCCMAP_UNKNOWN : OCCMAP_FREE;
        }
        for (int unk = 0; unk < 2; unk++) {
            float *cl = occmap_clearance(m, unk);
            uint8_t *pass = occmap_passable(m, 0.3, unk);
            assert_non_null(cl);
            assert_non_null(pass);
            for (int y = 0; y < H; y++)
                for (int x = 0; x < W; x++) {
                    double best = INFINITY;
                    for (int j = 0; j < W * H; j++) {
                        int8_t v = m->cells[j];
                        if (v == OCCMAP_OCCUPIED || (v != OCCMAP_FREE && !unk))
                            best = fmin(best, hypot(j % W - x, j / W - y));
                    }
                    double want = isfinite(best) ? (best - 0.5) * m->resolution : (W + H) * m->resolution;
                    assert_true(fabs(cl[y * W + x] - want) < 1e-4);
                    assert_int_equal(pass[y * W + x], cl[y * W + x] > 0.3);
                }
            free(cl);
            free(pass);
        }
        occmap_destroy(m);
    }
}

/* A coarser copy: a coarse cell is a wall when any fine cell in it is, free when all are free,
 * unknown otherwise; the origin stays and the size rounds up. */
static void test_coarsen(void **state)
{
    occmap_t *m = occmap_create(10, 6, 0.05, -1.0, 2.0);
    occmap_fill_rect(m, -1.0, 2.0, -0.96, 2.04, OCCMAP_OCCUPIED);      /* cell (0, 0) */
    m->cells[1 * 10 + 5] = OCCMAP_UNKNOWN;                              /* cell (5, 1) */
    occmap_t *c = occmap_coarsen(m, 0.2);
    assert_non_null(c);
    assert_int_equal(c->width, 3);
    assert_int_equal(c->height, 2);
    assert_true(c->origin_x == -1.0 && c->origin_y == 2.0 && c->resolution == 0.2);
    assert_int_equal(occmap_get(c, 0, 0), OCCMAP_OCCUPIED);
    assert_int_equal(occmap_get(c, 1, 0), OCCMAP_UNKNOWN);
    assert_int_equal(occmap_get(c, 2, 0), OCCMAP_FREE);
    assert_int_equal(occmap_get(c, 0, 1), OCCMAP_FREE);
    assert_null(occmap_coarsen(m, 0.01));
    occmap_destroy(c);
    occmap_destroy(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_pgm_formats),
        cmocka_unit_test(test_map_server_variants),
        cmocka_unit_test(test_origin_yaw),
        cmocka_unit_test(test_rotated_wall_stays_closed),
        cmocka_unit_test(test_raycast_hits_walls),
        cmocka_unit_test(test_small_files_load),
        cmocka_unit_test(test_bad_files),
        cmocka_unit_test(test_office_world_loads),
        cmocka_unit_test(test_gridpath),
        cmocka_unit_test(test_gridpath_is_shortest_on_random_grids),
        cmocka_unit_test(test_clearance_is_exact),
        cmocka_unit_test(test_coarsen),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
