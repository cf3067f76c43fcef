/* test_tts_process: marie-tts as a process on a real LCM bus (this test's namespace): a say
 * request becomes Festival's voice as audio blocks between a "speaking" and a "done" report;
 * an empty request is refused; a synthesizer that cannot run reports "failed", not a hang; the
 * command parameter is split into words as a shell splits a simple line. */
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

#include "adapters/tts/tts_child.h"
#include "core/component.h"
#include "core/typeinfo.h"
#include "tests/proc.h"

static struct {
    int speaking, done, failed;
    long samples, blocks_while_speaking, blocks_outside;
    int64_t speaking_mono, done_mono;
    double peak;
} rx;

static void on_state(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    marie_robot_speech_t m;
    if (marie_decode_checked(&marie_type_robot_speech_t, rb->data, rb->data_size, &m) < 0)
        return;
    if (m.state == MARIE_ROBOT_SPEECH_T_STATE_SPEAKING && m.id == 7) {
        rx.speaking++;
        rx.speaking_mono = marie_mono_us();
    } else if (m.state == MARIE_ROBOT_SPEECH_T_STATE_DONE && m.id == 7) {
        rx.done++;
        rx.done_mono = marie_mono_us();
    } else if (m.state == MARIE_ROBOT_SPEECH_T_STATE_FAILED) {
        rx.failed++;
    }
    marie_type_robot_speech_t.decode_cleanup(&m);
}

static void on_audio(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    marie_audio_frame_t f;
    if (marie_decode_checked(&marie_type_audio_frame_t, rb->data, rb->data_size, &f) < 0)
        return;
    rx.samples += f.nsamples;
    if (rx.speaking && !rx.done)
        rx.blocks_while_speaking++;
    else
        rx.blocks_outside++;
    for (int i = 0; i < f.nvalues; i++)
        rx.peak = fmax(rx.peak, fabs(f.data[i] / 32768.0));
    marie_type_audio_frame_t.decode_cleanup(&f);
}

static char *bin(const char *name)
{
    static char p[256];
    snprintf(p, sizeof(p), "%s/bin/%s", getenv("B") ? getenv("B") : "build", name);
    return p;
}

static void say(lcm_t *l, int id, const char *text)
{
    marie_robot_speech_t m = { .utime = 1, .id = id, .text = (char *)text, .state = MARIE_ROBOT_SPEECH_T_STATE_REQUEST };
    marie_robot_speech_t_publish(l, "SAY", &m);
}

static void test_say_is_heard_between_speaking_and_done(void **state)
{
    memset(&rx, 0, sizeof(rx));
    lcm_t *l = lcm_create(marie_default_url());
    assert_non_null(l);
    lcm_subscribe(l, "ROBOT_SPEECH", on_state, NULL);
    lcm_subscribe(l, "TTS_AUDIO", on_audio, NULL);
    char *argv[] = { bin("marie-tts"), NULL };
    char log[] = "/tmp/marie-tts-XXXXXX";
    close(mkstemp(log));
    pid_t pid = test_spawn(argv, log);
    assert_true(pid > 0);
    usleep(500000);
    say(l, 3, "");
    say(l, 7, "I am going to room b.");
    int64_t t0 = marie_mono_us();
    while (!rx.done && !rx.failed && marie_mono_us() - t0 < 30000000)
        lcm_handle_timeout(l, 100);
    for (int i = 0; i < 3; i++)
        lcm_handle_timeout(l, 100);
    test_stop(pid);
    printf("# %ld samples (%.2f s) in %ld blocks while speaking, %ld outside; speaking for %.2f s wall; peak %.2f\n",
           rx.samples, rx.samples / 16000.0, rx.blocks_while_speaking, rx.blocks_outside,
           (rx.done_mono - rx.speaking_mono) / 1e6, rx.peak);
    assert_int_equal(rx.speaking, 1);
    assert_int_equal(rx.done, 1);
    assert_int_equal(rx.failed, 0);
    assert_true(rx.samples > 16000);            /* a sentence lasts over a second */
    assert_int_equal(rx.blocks_outside, 0);
    assert_true(rx.peak > 0.05);
    /* Paced as heard: the report of the end comes after about the voice's length (loose bound:
     * not a timing test, only that the voice is not dumped at once). */
    assert_true(rx.done_mono - rx.speaking_mono > (int64_t)(rx.samples / 16000.0 * 0.5e6));
    FILE *f = fopen(log, "r");
    char line[512];
    int refused = 0;
    while (f && fgets(line, sizeof(line), f))
        refused |= strstr(line, "say request 3 refused") != NULL;
    if (f)
        fclose(f);
    assert_true(refused);
    unlink(log);
    lcm_destroy(l);
}

/* A synthesizer that cannot run, or stops with an error, reports "failed" (not a hang), and the
 * component's log says why, in the synthesizer's words. */
static void fails_saying(const char *command, const char *why)
{
    memset(&rx, 0, sizeof(rx));
    lcm_t *l = lcm_create(marie_default_url());
    lcm_subscribe(l, "ROBOT_SPEECH", on_state, NULL);
    char param[256], log[] = "/tmp/marie-tts-XXXXXX";
    snprintf(param, sizeof param, "command=%s", command);
    close(mkstemp(log));
    char *argv[] = { bin("marie-tts"), "--param", param, NULL };
    pid_t pid = test_spawn(argv, log);
    usleep(500000);
    say(l, 8, "hello");
    int64_t t0 = marie_mono_us();
    while (!rx.failed && marie_mono_us() - t0 < 10000000)
        lcm_handle_timeout(l, 100);
    int alive = kill(pid, 0) == 0;
    test_stop(pid);
    assert_int_equal(rx.failed, 1);
    assert_true(alive);
    FILE *f = fopen(log, "r");
    char line[512];
    int said = 0;
    while (f && fgets(line, sizeof(line), f))
        said |= strstr(line, "cannot say \"hello\"") && strstr(line, why);
    if (f)
        fclose(f);
    assert_true(said);
    unlink(log);
    lcm_destroy(l);
}

static void test_missing_synthesizer_reports_failed(void **state)
{
    fails_saying("/nonexistent/text2wave -o -", "cannot run /nonexistent/text2wave: No such file or directory");
    /* (the value is YAML: quoted, for its ": ") */
    fails_saying("\"sh -c 'echo SIOD ERROR: ran out of storage >&2; echo closing a file >&2; exit 255'\"",
                 "(SIOD ERROR: ran out of storage)");
    /* Festival itself, given too small a heap */
    fails_saying("'festival --heap 20000 -b ''(set! argv (list \"-F\" \"16000\"))'' /usr/bin/text2wave'",
                 "(SIOD ERROR: ran out of storage)");
}

static void test_command_words_split_as_a_shell_does(void **state)
{
    char line[] = "festival --heap 1000000 -b '(set! argv (list \"-F\" \"16000\"))'  /usr/bin/text2wave\t",
         *argv[8];
    assert_int_equal(tts_split_command(line, argv, 8), 6);
    assert_string_equal(argv[3], "-b");
    assert_string_equal(argv[4], "(set! argv (list \"-F\" \"16000\"))");
    assert_string_equal(argv[5], "/usr/bin/text2wave");
    assert_null(argv[6]);
    char glued[] = "say a\"b c\"'d' \"\"";     /* quoted parts join their word; "" is an empty word */
    assert_int_equal(tts_split_command(glued, argv, 8), 3);
    assert_string_equal(argv[1], "ab cd");
    assert_string_equal(argv[2], "");
    char open_quote[] = "text2wave 'oops", spaces[] = "   ", many[] = "a b c d";
    assert_int_equal(tts_split_command(open_quote, argv, 8), -1);
    assert_int_equal(tts_split_command(spaces, argv, 8), 0);
    assert_int_equal(tts_split_command(many, argv, 4), -1);      /* three words and the NULL */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_say_is_heard_between_speaking_and_done),
        cmocka_unit_test(test_missing_synthesizer_reports_failed),
        cmocka_unit_test(test_command_words_split_as_a_shell_does),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
