/* test_dialogue: marie-dialogue's rules: "go to room b" is a goal at that place and an answer,
 * an unknown place is said so, "stop" stops, "where are you going" tells the goal, the speaker
 * is faced when the array knows where they are; places text parsed or refused with a reason. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "adapters/dialogue/dialogue.h"

static dialogue_t d;

static int setup(void **state)
{
    dialogue_place_t p[8];
    int n;
    char why[128];
    assert_int_equal(dialogue_places_parse("room a=3,2,0; room b=8,5,1.57; kitchen=1,6,3.14; home=0.5,0.5,0", p, 8, &n,
                                           why, sizeof(why)), 0);
    assert_int_equal(n, 4);
    dialogue_init(&d, p, n, "Spartacus");
    return 0;
}

static void test_go_to_room_b(void **state)
{
    dialogue_reply_t r;
    dialogue_hear(&d, "go to room b", 3, true, 0.7, &r);
    assert_true(r.actions & DIALOGUE_GOAL);
    assert_string_equal(r.place.name, "room b");
    assert_true(fabs(r.place.x - 8) < 1e-9 && fabs(r.place.y - 5) < 1e-9 && fabs(r.place.theta - 1.57) < 1e-9);
    assert_true(r.actions & DIALOGUE_FACE);
    assert_true(fabs(r.azimuth - 0.7) < 1e-9);
    assert_string_equal(r.say, "Going to room b.");
    dialogue_hear(&d, "where are you going", 3, false, 0, &r);
    assert_string_equal(r.say, "I am going to room b.");
    assert_false(r.actions & DIALOGUE_FACE);
    dialogue_hear(&d, "go to the kitchen", 3, false, 0, &r);
    assert_string_equal(r.place.name, "kitchen");
    dialogue_hear(&d, "go home", 3, false, 0, &r);
    assert_string_equal(r.place.name, "home");
}

static void test_unknown_place_and_stop(void **state)
{
    dialogue_reply_t r;
    dialogue_hear(&d, "go to room c", 1, false, 0, &r);
    assert_false(r.actions & DIALOGUE_GOAL);
    assert_string_equal(r.say, "I do not know where room c is.");
    dialogue_hear(&d, "go to room a", 1, false, 0, &r);
    dialogue_hear(&d, "stop", 1, false, 0, &r);
    assert_true(r.actions & DIALOGUE_STOP);
    dialogue_hear(&d, "where are you going", 1, false, 0, &r);
    assert_string_equal(r.say, "I am not going anywhere.");
    dialogue_hear(&d, "what is your name", 1, false, 0, &r);
    assert_string_equal(r.say, "My name is Spartacus.");
    long understood = d.understood;
    dialogue_hear(&d, "sing a song", 1, false, 0, &r);
    assert_int_equal(d.understood, understood);
    assert_string_equal(r.say, "Sorry, I did not understand.");
}

static void test_places_refused_with_reason(void **state)
{
    static const char *bad[] = { "room a", "room a=1,2", "Room A=1,2,3", "a=1,2,3,4", "=1,2,3", "a=x,2,3", NULL };
    dialogue_place_t p[4];
    int n;
    for (int i = 0; bad[i]; i++) {
        char why[128] = "";
        assert_int_equal(dialogue_places_parse(bad[i], p, 4, &n, why, sizeof(why)), -1);
        assert_true(why[0] != 0);
    }
    char why[128];
    assert_int_equal(dialogue_places_parse("a=1,1,1;b=1,1,1;c=1,1,1", p, 2, &n, why, sizeof(why)), -1);
    assert_int_equal(dialogue_places_parse("", p, 2, &n, why, sizeof(why)), 0);
    assert_int_equal(n, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_go_to_room_b, setup),
        cmocka_unit_test_setup(test_unknown_place_and_stop, setup),
        cmocka_unit_test(test_places_refused_with_reason),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
