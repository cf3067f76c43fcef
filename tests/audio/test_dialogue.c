/* test_dialogue: marie-dialogue's rules: "go to room b" is a goal at that place and an answer,
 * an unknown place is said so, "stop" stops, "where are you going" tells the goal, the speaker
 * is faced when the array knows where they are, in the direction the words came from; places text
 * parsed or refused with a reason. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "adapters/dialogue/dialogue.h"
#include "adapters/dialogue/speaker_dir.h"

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

/* marie-ssl's track of a speaker 60 degrees away in a room with reflecting walls (logged from
 * test_spoken_command's scene, 10 Hz): heard at 61-63 degrees, then drifting on its rate after
 * the words, 70 degrees by the time the recognizer reports them. The fan's track at -154. */
static const struct {
    double t, az, energy, activity;
} speaker_track[] = {
    { 1.33, 61.2, 0.14, 0.19 }, { 1.42, 60.9, 0.08, 0.57 }, { 1.52, 60.9, 0.04, 0.49 }, { 1.62, 62.2, 0.06, 0.73 },
    { 1.71, 62.6, 0.07, 0.86 }, { 1.81, 63.4, 0.05, 0.92 }, { 1.90, 67.7, 0.03, 0.96 }, { 2.00, 67.6, 0.07, 0.61 },
    { 2.10, 67.4, 0.04, 0.79 }, { 2.19, 68.6, 0.03, 0.48 }, { 2.29, 69.1, 0.03, 0.26 }, { 2.38, 69.5, 0.03, 0.14 },
    { 2.48, 69.8, 0.03, 0.07 }, { 2.58, 70.0, 0.03, 0.04 }, { 2.67, 70.2, 0.03, 0.02 },
};

static void test_speaker_faced_where_the_words_came_from(void **state)
{
    static speaker_dir_t h;
    speaker_dir_init(&h);
    for (size_t i = 0; i < sizeof(speaker_track) / sizeof(speaker_track[0]); i++) {
        int64_t t = (int64_t)(speaker_track[i].t * 1e6);
        speaker_dir_add(&h, t, 1, -154 * M_PI / 180, 0.03, 0.3);
        speaker_dir_add(&h, t, 2, speaker_track[i].az * M_PI / 180, speaker_track[i].energy, speaker_track[i].activity);
    }
    double az;
    /* the utterance as the recognizer reported it: 1.33 to 2.62 s */
    assert_true(speaker_dir_get(&h, 2, 1330000, 2620000, &az));
    printf("# speaker at 60 degrees: faced at %.1f (the track's latest: 70.2)\n", az * 180 / M_PI);
    assert_true(fabs(az * 180 / M_PI - 60) < 5);
    /* seen only before the utterance (its track died): its latest direction */
    assert_true(speaker_dir_get(&h, 2, 3000000, 4000000, &az));
    assert_true(fabs(az * 180 / M_PI - 70.2) < 0.01);
    assert_false(speaker_dir_get(&h, 3, 0, 4000000, &az));
    /* across the back of the robot (+-180 degrees): the mean of 179 and -179 is 180, not 0 */
    speaker_dir_add(&h, 5000000, 4, 179 * M_PI / 180, 0.1, 1);
    speaker_dir_add(&h, 5100000, 4, -179 * M_PI / 180, 0.1, 1);
    assert_true(speaker_dir_get(&h, 4, 5000000, 5100000, &az));
    assert_true(fabs(fabs(az) - M_PI) < 0.01);
}

/* Thousands of sightings later the oldest are forgotten and the newest kept. */
static void test_speaker_dir_keeps_the_last_seconds(void **state)
{
    static speaker_dir_t h;
    speaker_dir_init(&h);
    for (int i = 0; i < 3 * SPEAKER_DIR_MAX; i++)
        speaker_dir_add(&h, (int64_t)i * 1000, i % 7, (i % 7) * 0.1, 0.1, 1);
    double az;
    assert_false(speaker_dir_get(&h, 1, 0, 2 * SPEAKER_DIR_MAX * 1000 - 1, &az));
    assert_true(speaker_dir_get(&h, 3, (3 * SPEAKER_DIR_MAX - 100) * 1000, 3 * SPEAKER_DIR_MAX * 1000, &az));
    assert_true(fabs(az - 0.3) < 1e-6);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup(test_go_to_room_b, setup),
        cmocka_unit_test_setup(test_unknown_place_and_stop, setup),
        cmocka_unit_test(test_places_refused_with_reason),
        cmocka_unit_test(test_speaker_faced_where_the_words_came_from),
        cmocka_unit_test(test_speaker_dir_keeps_the_last_seconds),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
