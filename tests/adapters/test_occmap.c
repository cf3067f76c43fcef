/* test_occmap: map_server maps load with ROS conventions; bad files are refused with a reason. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <unistd.h>
#include <cmocka.h>

#include "adapters/common/occmap.h"

static const occmap_meta_t meta = { 0.5, -1.0, -2.0, false, 0.65, 0.196 };

static void test_pgm_rows_flip_and_thresholds(void **state)
{
    /* 3x2 image: top row black/grey/white, bottom row white/white/black. */
    const uint8_t img[] = "P5\n# comment\n3 2\n255\n\x00\x80\xfe\xfe\xfe\x00";
    char err[128];
    occmap_t *m = occmap_from_pgm(img, sizeof(img) - 1, &meta, err, sizeof(err));
    assert_non_null(m);
    assert_int_equal(m->width, 3);
    assert_int_equal(m->height, 2);
    /* Row 0 is the bottom of the map: the image's last line. */
    assert_int_equal(occmap_get(m, 0, 0), OCCMAP_FREE);
    assert_int_equal(occmap_get(m, 2, 0), OCCMAP_OCCUPIED);
    assert_int_equal(occmap_get(m, 0, 1), OCCMAP_OCCUPIED);
    assert_int_equal(occmap_get(m, 1, 1), OCCMAP_UNKNOWN);   /* p = 0.5: between thresholds */
    assert_int_equal(occmap_get(m, 2, 1), OCCMAP_FREE);
    assert_int_equal(occmap_get(m, 5, 5), OCCMAP_UNKNOWN);
    /* World coordinates go through the origin. */
    assert_true(occmap_occupied_at(m, -1.0 + 0.2, -2.0 + 0.7));   /* cell (0,1) */
    assert_false(occmap_occupied_at(m, -1.0 + 1.2, -2.0 + 0.7));  /* cell (2,1) */
    assert_true(occmap_occupied_at(m, -1.5, 0));                  /* outside counts as blocked */
    occmap_destroy(m);
}

static void test_ascii_pgm_and_negate(void **state)
{
    const char img[] = "P2 2 1 15\n0 15\n";
    occmap_meta_t mt = meta;
    mt.negate = true;
    char err[128];
    occmap_t *m = occmap_from_pgm((const uint8_t *)img, strlen(img), &mt, err, sizeof(err));
    assert_non_null(m);
    assert_int_equal(occmap_get(m, 0, 0), OCCMAP_FREE);      /* negated: black is free */
    assert_int_equal(occmap_get(m, 1, 0), OCCMAP_OCCUPIED);
    occmap_destroy(m);
}

static void test_bad_pgm_refused(void **state)
{
    char err[128];
    const char *bad[] = { "", "P6\n1 1\n255\n\x00", "P5\n3 2\n255\n\x00\x00", "P5\n-1 2\n255\n", "P5\n99999999999 1\n255\n",
                          "P5\n2 2\n0\n\x00\x00\x00\x00", "P2 2 2 255\n1 2 3\n" };
    for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
        err[0] = 0;
        assert_null(occmap_from_pgm((const uint8_t *)bad[i], strlen(bad[i]), &meta, err, sizeof(err)));
        assert_true(err[0] != 0);
    }
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

static void test_load_map_yaml(void **state)
{
    char dir[] = "/tmp/occmapXXXXXX";
    assert_non_null(mkdtemp(dir));
    char path[256], ypath[256];
    snprintf(path, sizeof(path), "%s/m.pgm", dir);
    FILE *f = fopen(path, "wb");
    fwrite("P5\n2 2\n255\n\x00\xfe\xfe\xfe", 1, 15, f);
    fclose(f);
    snprintf(ypath, sizeof(ypath), "%s/m.yaml", dir);
    f = fopen(ypath, "w");
    fprintf(f, "image: m.pgm\nresolution: 0.25\norigin: [1.0, 2.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n");
    fclose(f);
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load(ypath, &errs);
    assert_non_null(m);
    assert_true(m->resolution == 0.25 && m->origin_x == 1.0 && m->origin_y == 2.0);
    assert_int_equal(occmap_get(m, 0, 1), OCCMAP_OCCUPIED);
    assert_true(occmap_occupied_at(m, 1.1, 2.3));
    assert_false(occmap_occupied_at(m, 1.1, 2.1));
    occmap_destroy(m);
    /* Errors carry the file and line. */
    f = fopen(ypath, "w");
    fprintf(f, "image: missing.pgm\nresolution: -1\nbogus: 3\n");
    fclose(f);
    assert_null(occmap_load(ypath, &errs));
    assert_true(errs.n >= 2);
    int saw_line = 0;
    for (size_t i = 0; i < errs.n; i++)
        saw_line |= strstr(errs.msgs[i], "m.yaml:2") != NULL;
    assert_true(saw_line);
    marie_errors_clear(&errs);
    f = fopen(ypath, "w");
    fprintf(f, "image: missing.pgm\nresolution: 0.1\n");
    fclose(f);
    assert_null(occmap_load(ypath, &errs));
    assert_true(errs.n == 1 && strstr(errs.msgs[0], "missing.pgm"));
    marie_errors_clear(&errs);
    unlink(path);
    unlink(ypath);
    rmdir(dir);
}

static void test_office_world_loads(void **state)
{
    /* The simulator's office world, when present, loads with the expected size. */
    marie_errors_t errs = { 0 };
    if (access("sim/worlds/office.yaml", R_OK) != 0)
        skip();
    occmap_t *m = occmap_load("sim/worlds/office.yaml", &errs);
    assert_non_null(m);
    assert_true(fabs(m->width * m->resolution - 40) < 0.1 && fabs(m->height * m->resolution - 30) < 0.1);
    assert_true(occmap_occupied_at(m, 0.05, 15));    /* outer wall */
    assert_false(occmap_occupied_at(m, 10, 15));     /* main corridor */
    occmap_destroy(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_pgm_rows_flip_and_thresholds),
        cmocka_unit_test(test_ascii_pgm_and_negate),
        cmocka_unit_test(test_bad_pgm_refused),
        cmocka_unit_test(test_raycast_hits_walls),
        cmocka_unit_test(test_load_map_yaml),
        cmocka_unit_test(test_office_world_loads),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
