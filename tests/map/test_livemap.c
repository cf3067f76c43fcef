/* test_livemap: a reader's map from whole MAP messages and MAP_UPDATE rectangles. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "map/livemap.h"

static int8_t cells[4 * 3];

static marie_occupancy_grid_t whole(int64_t utime)
{
    for (int i = 0; i < 12; i++)
        cells[i] = -1;
    return (marie_occupancy_grid_t){ .utime = utime, .resolution = 0.05f, .width = 4, .height = 3,
                                     .origin = { 1.0, 2.0, 0 }, .ncells = 12, .cells = cells };
}

static void patches_the_rectangle_into_its_map(void **state)
{
    livemap_t lm = { 0 };
    char why[128];
    marie_occupancy_grid_t g = whole(7);
    assert_int_equal(livemap_full(&lm, &g, why, sizeof(why)), 0);
    cells[0] = 100;     /* the reader holds a copy */
    int8_t r[] = { 0, 100, 0, 100 };
    marie_occupancy_grid_update_t u = { .utime = 8, .map_utime = 7, .x = 2, .y = 1, .width = 2, .height = 2,
                                        .ncells = 4, .cells = r };
    assert_int_equal(livemap_update(&lm, &u, why, sizeof(why)), 0);
    const int8_t want[12] = { -1, -1, -1, -1, -1, -1, 0, 100, -1, -1, 0, 100 };
    assert_memory_equal(lm.map.cells, want, 12);
    occmap_t *m = livemap_occmap(&lm);
    assert_non_null(m);
    assert_int_equal(m->cells[7], 100);
    assert_true(m->origin_x == 1.0 && m->width == 4);
    occmap_destroy(m);
    livemap_free(&lm);
    assert_null(livemap_occmap(&lm));
}

static void an_update_for_another_map_waits_for_the_next_whole_one(void **state)
{
    livemap_t lm = { 0 };
    char why[128];
    int8_t r[] = { 100 };
    marie_occupancy_grid_update_t u = { .utime = 8, .map_utime = 7, .x = 0, .y = 0, .width = 1, .height = 1,
                                        .ncells = 1, .cells = r };
    assert_int_equal(livemap_update(&lm, &u, why, sizeof(why)), 1);      /* no map yet */
    marie_occupancy_grid_t g = whole(6);
    assert_int_equal(livemap_full(&lm, &g, why, sizeof(why)), 0);
    assert_int_equal(livemap_update(&lm, &u, why, sizeof(why)), 1);      /* another map's */
    assert_int_equal(lm.map.cells[0], -1);
    livemap_free(&lm);
}

static void contradictions_are_refused_and_change_nothing(void **state)
{
    livemap_t lm = { 0 };
    char why[128] = "";
    marie_occupancy_grid_t g = whole(7);
    g.ncells = 11;
    assert_int_equal(livemap_full(&lm, &g, why, sizeof(why)), -1);
    assert_non_null(strstr(why, "11 cells"));
    assert_null(lm.map.cells);
    g = whole(7);
    g.resolution = 0;
    assert_int_equal(livemap_full(&lm, &g, why, sizeof(why)), -1);
    g = whole(7);
    assert_int_equal(livemap_full(&lm, &g, why, sizeof(why)), 0);
    int8_t r[6] = { 100, 100, 100, 100, 100, 100 };
    marie_occupancy_grid_update_t u = { .map_utime = 7, .x = 3, .y = 0, .width = 2, .height = 3, .ncells = 6,
                                        .cells = r };
    assert_int_equal(livemap_update(&lm, &u, why, sizeof(why)), -1);     /* past the right edge */
    assert_non_null(strstr(why, "outside"));
    u = (marie_occupancy_grid_update_t){ .map_utime = 7, .x = 0, .y = 2, .width = 1, .height = 2, .ncells = 2, .cells = r };
    assert_int_equal(livemap_update(&lm, &u, why, sizeof(why)), -1);     /* past the top */
    u = (marie_occupancy_grid_update_t){ .map_utime = 7, .x = -1, .y = 0, .width = 1, .height = 1, .ncells = 1, .cells = r };
    assert_int_equal(livemap_update(&lm, &u, why, sizeof(why)), -1);
    u = (marie_occupancy_grid_update_t){ .map_utime = 7, .x = 0, .y = 0, .width = 2, .height = 2, .ncells = 3, .cells = r };
    assert_int_equal(livemap_update(&lm, &u, why, sizeof(why)), -1);     /* count contradicts the size */
    for (int i = 0; i < 12; i++)
        assert_int_equal(lm.map.cells[i], -1);
    livemap_free(&lm);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(patches_the_rectangle_into_its_map),
        cmocka_unit_test(an_update_for_another_map_waits_for_the_next_whole_one),
        cmocka_unit_test(contradictions_are_refused_and_change_nothing),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
