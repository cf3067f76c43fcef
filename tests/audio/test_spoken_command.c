/* test_spoken_command: the spoken-command chain as processes on a real LCM bus (this test's
 * namespace): a person 2 m away in the simulated room says "go to room b" near a fan;
 * marie-sim's array -> marie-ssl -> marie-asr -> marie-dialogue -> marie-tts. The goal for
 * room b is published, the speaker's direction is reported for facing, the robot answers, and
 * it hears the phrase again once it has answered; the time from the recognition to the start of
 * the answer is printed. */
#include <math.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include <lcm/lcm.h>

#include "core/component.h"
#include "core/typeinfo.h"
#include "tests/proc.h"

#define DEG (M_PI / 180)

static struct {
    int heard_b, goals_b, answers, speaking, heard_after_answer;
    double goal_x, goal_y;
    int64_t heard_mono, speaking_mono;
    char face[256], heard_text[256];
} rx;

static void on_speech(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    marie_speech_t m;
    if (marie_decode_checked(&marie_type_speech_t, rb->data, rb->data_size, &m) < 0)
        return;
    snprintf(rx.heard_text, sizeof(rx.heard_text), "%s", m.text);
    if (!strcmp(m.text, "go to room b") && !rx.heard_b++)
        rx.heard_mono = marie_mono_us();
    else if (!strcmp(m.text, "go to room b") && rx.speaking)
        rx.heard_after_answer++;
    marie_type_speech_t.decode_cleanup(&m);
}

static void on_goal(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    marie_goal_t g;
    if (marie_decode_checked(&marie_type_goal_t, rb->data, rb->data_size, &g) < 0)
        return;
    if (!strcmp(g.name, "room b")) {
        rx.goals_b++;
        rx.goal_x = g.pose.x;
        rx.goal_y = g.pose.y;
    }
    marie_type_goal_t.decode_cleanup(&g);
}

static void on_event(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    marie_event_t e;
    if (marie_decode_checked(&marie_type_event_t, rb->data, rb->data_size, &e) < 0)
        return;
    if (!strcmp(e.kind, "face") && !rx.face[0])
        snprintf(rx.face, sizeof(rx.face), "%s", e.text);
    marie_type_event_t.decode_cleanup(&e);
}

static void on_robot_speech(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    marie_robot_speech_t m;
    if (marie_decode_checked(&marie_type_robot_speech_t, rb->data, rb->data_size, &m) < 0)
        return;
    if (m.state == MARIE_ROBOT_SPEECH_T_STATE_SPEAKING && strstr(m.text, "room b") && !rx.speaking++)
        rx.speaking_mono = marie_mono_us();
    marie_type_robot_speech_t.decode_cleanup(&m);
}

static char *bin(const char *name)
{
    static char path[8][256];
    static int k;
    char *p = path[k++ % 8];
    snprintf(p, 256, "%s/bin/%s", getenv("B") ? getenv("B") : "build", name);
    return p;
}

static void test_go_to_room_b_said_in_the_room(void **state)
{
    double bearing = 60 * DEG;
    char scene[1024];
    snprintf(scene, sizeof(scene), "audio=speech file=%s/share/sounds/phrase_02.wav x=%.3f y=%.3f z=1.5 start=1.0 "
             "every=5 level=0.05; fan x=1 y=1 z=0.5 level=0.01; walls reflect=0.4; diffuse snr=20",
             getenv("B") ? getenv("B") : "build", 3 + 2 * cos(bearing), 2 + 2 * sin(bearing));
    char *sim[] = { bin("marie-sim"), "--world", "test", "--param", "start_x=3.0", "--param", "start_y=2.0",
                    "--param", scene, NULL };
    char *ssl[] = { bin("marie-ssl"), NULL };
    char *asr[] = { bin("marie-asr"), NULL };
    char *dlg[] = { bin("marie-dialogue"), "--param", "places=room a=2,2,0; room b=8.5,6,1.57", NULL };
    char *tts[] = { bin("marie-tts"), NULL };
    lcm_t *l = lcm_create(marie_default_url());
    assert_non_null(l);
    lcm_subscribe(l, "SPEECH", on_speech, NULL);
    lcm_subscribe(l, "SPOKEN_GOAL", on_goal, NULL);
    lcm_subscribe(l, "DIALOGUE", on_event, NULL);
    lcm_subscribe(l, "ROBOT_SPEECH", on_robot_speech, NULL);
    pid_t pids[5] = { test_spawn(tts, "/dev/null"), test_spawn(dlg, "/dev/null"), test_spawn(asr, "/dev/null"),
                      test_spawn(ssl, "/dev/null"), 0 };
    usleep(1500000);    /* the recognizer loads its model */
    pids[4] = test_spawn(sim, "/dev/null");
    int64_t t0 = marie_mono_us();
    while (marie_mono_us() - t0 < 40000000 && !(rx.speaking && rx.goals_b && rx.heard_after_answer))
        lcm_handle_timeout(l, 100);
    for (int i = 4; i >= 0; i--)
        test_stop(pids[i]);
    printf("# heard \"%s\"; goal for room b %d at (%.1f, %.1f); face: %s; answer started %.3f s after the "
           "recognition (the recognizer adds its 0.45 s end-of-speech wait before that); heard again after the "
           "answer %d times\n", rx.heard_text, rx.goals_b, rx.goal_x, rx.goal_y, rx.face,
           (rx.speaking_mono - rx.heard_mono) / 1e6, rx.heard_after_answer);
    assert_true(rx.heard_b >= 1);
    assert_true(rx.goals_b >= 1);
    assert_true(fabs(rx.goal_x - 8.5) < 1e-9 && fabs(rx.goal_y - 6) < 1e-9);
    assert_true(rx.speaking >= 1);
    double az = NAN;
    assert_int_equal(sscanf(rx.face, "speaker %*d at azimuth %lf", &az), 1);
    assert_true(fabs(remainder(az - bearing, 2 * M_PI)) < 10 * DEG);
    /* Not deaf for good once it has spoken (its voice is stamped by the wall clock here, the
     * array by the simulator's, as two computers' clocks may differ). */
    assert_true(rx.heard_after_answer >= 1);
    lcm_destroy(l);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_go_to_room_b_said_in_the_room),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
