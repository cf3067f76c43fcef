/* test_mapeval: the measure behind `marie map compare` scores what it claims: a perfect copy
 * 1/1/1, a shifted copy badly until aligned, invented walls against precision, missing walls
 * against recall, unknown space against coverage. */
#include <math.h>
#include <setjmp.h>
#include <stdbool.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "map/mapeval.h"

static occmap_t *office(void)
{
    marie_errors_t errs = { 0 };
    occmap_t *m = occmap_load("sim/worlds/office.yaml", &errs);
    assert_non_null(m);
    return m;
}

static void test_a_copy_scores_one(void **state)
{
    occmap_t *w = office(), *c = occmap_clone(w);
    mapeval_t e;
    mapeval_compare(w, c, 2.0, 15.0, &e);
    assert_true(e.precision == 1.0 && e.recall == 1.0 && e.coverage == 1.0);
    assert_true(e.truth_walls > 1000 && e.truth_free > 100000);
    occmap_destroy(c);
    occmap_destroy(w);
}

static void test_a_shifted_copy_is_found_by_alignment(void **state)
{
    occmap_t *w = office(), *c = occmap_clone(w);
    c->origin_x += 0.2;         /* four cells east */
    c->origin_y -= 0.1;
    mapeval_t e;
    mapeval_compare(w, c, 2.0, 15.0, &e);
    assert_true(e.precision < 0.6);
    double dx, dy, th;
    occmap_t *al = mapeval_align(w, c, 0.5, 0.03, &dx, &dy, &th);
    assert_non_null(al);
    assert_true(fabs(dx + 0.2) < 0.026 && fabs(dy - 0.1) < 0.026 && fabs(th) < 0.003);
    mapeval_compare(w, al, 2.0, 15.0, &e);
    assert_true(e.precision > 0.99 && e.recall > 0.99);
    occmap_destroy(al);
    occmap_destroy(c);
    occmap_destroy(w);
}

/* A map that is right needs no alignment: every shift within a cell fits as well (the walls are
 * dilated by one), and the smallest, none, is the one taken. */
static void test_a_copy_is_not_moved_by_alignment(void **state)
{
    /* The office with a margin, so that no wall sits on the grid's edge (a shift would push it
     * off the grid and lose it, which would break the tie). */
    occmap_t *o = office(), *w = occmap_create(o->width + 40, o->height + 40, o->resolution, -1.0, -1.0);
    assert_non_null(w);
    for (int y = 0; y < o->height; y++)
        memcpy(&w->cells[(size_t)(y + 20) * w->width + 20], &o->cells[(size_t)y * o->width], (size_t)o->width);
    occmap_destroy(o);
    occmap_t *c = occmap_clone(w);
    double dx = 1, dy = 1, th = 1;
    occmap_t *al = mapeval_align(w, c, 0.5, 0.03, &dx, &dy, &th);
    assert_non_null(al);
    assert_true(fabs(dx) < 1e-9 && fabs(dy) < 1e-9 && fabs(th) < 1e-9);
    mapeval_t e;
    mapeval_compare(w, al, 2.0, 15.0, &e);
    assert_true(e.precision == 1.0 && e.recall == 1.0);
    occmap_destroy(al);
    occmap_destroy(c);
    occmap_destroy(w);
}

/* A copy turned by 0.004 rad about the map frame's origin (the rows of its cells along that
 * heading, as a map's own frame may be): the judgement finds the turn and scores the cells where
 * they are, without resampling the map onto the world's grid a second time (which cost a right
 * map several points of precision). */
static void test_a_turned_copy_is_judged_at_its_turn(void **state)
{
    occmap_t *w = office();
    double c = cos(-0.004), s = sin(-0.004);
    occmap_t *t = occmap_from_cells(w->width, w->height, w->resolution, c * w->origin_x - s * w->origin_y,
                                    s * w->origin_x + c * w->origin_y, -0.004, w->cells);
    assert_non_null(t);
    mapeval_judgement_t j;
    assert_int_equal(mapeval_judge(w, t, 2.0, 15.0, &j), 0);
    print_message("turned copy: as built %.3f / %.3f, aligned by %.4f rad: %.3f / %.3f\n", j.raw.precision,
                  j.raw.recall, j.th, j.aligned.precision, j.aligned.recall);
    assert_true(fabs(j.th - 0.004) < 0.0026);
    assert_true(j.aligned.precision > 0.99 && j.aligned.recall > 0.99);
    occmap_destroy(t);
    occmap_destroy(w);
}

/* A wall drawn across free space where the world has none: every one of its cells is a false
 * positive, and nothing else changes. */
static void test_invented_walls_lower_precision(void **state)
{
    occmap_t *w = office(), *c = occmap_clone(w);
    mapeval_t e0, e;
    mapeval_compare(w, c, 2.0, 15.0, &e0);
    int cx = 0, cy = 0, drawn = 0;
    assert_true(occmap_cell(c, 5.0, 15.0, &cx, &cy));
    for (int x = cx; x < cx + 40; x++) {
        bool clear = true;      /* no true wall within one cell */
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++)
                clear = clear && occmap_get(w, x + dx, cy + dy) != OCCMAP_OCCUPIED;
        if (clear) {
            c->cells[(size_t)cy * c->width + x] = OCCMAP_OCCUPIED;
            drawn++;
        }
    }
    assert_true(drawn > 20);
    mapeval_compare(w, c, 2.0, 15.0, &e);
    assert_int_equal(e.map_occupied, e0.map_occupied + drawn);
    assert_true(fabs(e.precision - (double)e0.map_occupied / e.map_occupied) < 1e-9);
    occmap_destroy(c);
    occmap_destroy(w);
}

/* Walls the map lost (marked free) count against recall; cells it never saw count against
 * coverage, not against recall (a wall next to unseen space was not visible). */
static void test_lost_walls_lower_recall_and_unseen_space_coverage(void **state)
{
    occmap_t *w = office(), *c = occmap_clone(w);
    size_t n = (size_t)c->width * c->height;
    for (size_t i = 0; i < n; i++)
        if ((int)(i % c->width) < c->width / 2 && c->cells[i] == OCCMAP_OCCUPIED)
            c->cells[i] = OCCMAP_FREE;
    mapeval_t e;
    mapeval_compare(w, c, 2.0, 15.0, &e);
    assert_true(e.precision == 1.0);
    assert_true(e.recall > 0.2 && e.recall < 0.8);
    occmap_t *u = occmap_clone(w);
    for (size_t i = 0; i < n; i++)
        if ((int)(i / u->width) < u->height / 2)
            u->cells[i] = OCCMAP_UNKNOWN;
    mapeval_compare(w, u, 2.0, 15.0, &e);
    assert_true(e.coverage > 0.2 && e.coverage < 0.8);
    assert_true(e.precision == 1.0);
    assert_true(e.recall > 0.99);
    occmap_destroy(u);
    occmap_destroy(c);
    occmap_destroy(w);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_a_copy_scores_one),
        cmocka_unit_test(test_a_shifted_copy_is_found_by_alignment),
        cmocka_unit_test(test_a_copy_is_not_moved_by_alignment),
        cmocka_unit_test(test_a_turned_copy_is_judged_at_its_turn),
        cmocka_unit_test(test_invented_walls_lower_precision),
        cmocka_unit_test(test_lost_walls_lower_recall_and_unseen_space_coverage),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
