/* test_map_save: occmap_save writes map_server pairs that occmap_load reads back cell for cell. */
#include <errno.h>
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

static char dir[64];

static int setup(void **state)
{
    snprintf(dir, sizeof(dir), "/tmp/marie-map-save-XXXXXX");
    return mkdtemp(dir) ? 0 : -1;
}

static int teardown(void **state)
{
    char cmd[128];
    snprintf(cmd, sizeof(cmd), "rm -rf %s", dir);
    return system(cmd) == 0 ? 0 : -1;
}

/* What map_server's trinary rule makes of a cell after the round trip. */
static int8_t trinary(int8_t v)
{
    return v < 0 || v > 100 ? OCCMAP_UNKNOWN : v >= 65 ? OCCMAP_OCCUPIED : v < 20 ? OCCMAP_FREE : OCCMAP_UNKNOWN;
}

static void test_round_trip_keeps_cells_and_origin(void **state)
{
    occmap_t *m = occmap_create(7, 5, 0.1, -3.25, 1.5);
    assert_non_null(m);
    const int8_t vals[] = { OCCMAP_UNKNOWN, 0, 5, 19, 20, 50, 64, 66, 90, 100 };
    for (int i = 0; i < m->width * m->height; i++)
        m->cells[i] = vals[i % 10];
    char yaml[128];
    snprintf(yaml, sizeof(yaml), "%s/saved.yaml", dir);
    assert_int_equal(occmap_save(m, yaml), 0);
    marie_errors_t errs = { 0 };
    occmap_t *r = occmap_load(yaml, &errs);
    assert_non_null(r);
    assert_int_equal(r->width, 7);
    assert_int_equal(r->height, 5);
    assert_true(fabs(r->resolution - 0.1) < 1e-9);
    assert_true(fabs(r->origin_x + 3.25) < 1e-6 && fabs(r->origin_y - 1.5) < 1e-6);
    for (int i = 0; i < m->width * m->height; i++)
        assert_int_equal(r->cells[i], trinary(m->cells[i]));
    /* Bottom row of the map, last line of the image: cell (0,0) is the first value. */
    assert_int_equal(r->cells[0], OCCMAP_UNKNOWN);
    occmap_destroy(r);
    occmap_destroy(m);
}

static void test_office_world_survives_a_round_trip(void **state)
{
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load("sim/worlds/office.yaml", &errs);
    assert_non_null(m);
    char yaml[128];
    snprintf(yaml, sizeof(yaml), "%s/office_copy.yaml", dir);
    assert_int_equal(occmap_save(m, yaml), 0);
    occmap_t *r = occmap_load(yaml, &errs);
    assert_non_null(r);
    assert_int_equal(r->width, m->width);
    assert_int_equal(r->height, m->height);
    assert_memory_equal(r->cells, m->cells, (size_t)m->width * m->height);
    occmap_destroy(r);
    occmap_destroy(m);
}

static void test_bad_requests_refused(void **state)
{
    occmap_t *m = occmap_create(3, 3, 0.05, 0, 0);
    errno = 0;
    assert_int_equal(occmap_save(m, "/tmp/no-yaml-suffix.pgm"), -1);
    assert_int_equal(errno, EINVAL);
    assert_int_equal(occmap_save(NULL, "/tmp/x.yaml"), -1);
    errno = 0;
    assert_int_equal(occmap_save(m, "/nonexistent-dir-for-marie/map.yaml"), -1);
    assert_int_equal(errno, ENOENT);
    occmap_destroy(m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip_keeps_cells_and_origin),
        cmocka_unit_test(test_office_world_survives_a_round_trip),
        cmocka_unit_test(test_bad_requests_refused),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
