/* test_asr_continuous: one recognizer and one array pipeline hear a continuous scene for about
 * three minutes: 40 utterances from six places in espeak-ng's voices (commands, phrases out of
 * the grammar), real recordings, noise bursts and pauses, a fan all along 5 dB under every
 * utterance, in a room of RT60 0.3 s rendered by pyroomacoustics (tests/audio/room_scene.py).
 * Commands are heard to the end and the rest is not taken for commands. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <cmocka.h>

#include "tests/audio/asr_eval.h"

static void test_continuous_room(void **state)
{
    static asr_eval_t e;
    const char *b = getenv("B") ? getenv("B") : "build";
    char wav[512], tsv[512];
    snprintf(wav, sizeof(wav), "%s/share/rooms/test_rt30_snr5.wav", b);
    snprintf(tsv, sizeof(tsv), "%s/share/rooms/test_rt30_snr5.tsv", b);
    assert_int_equal(asr_eval_run(wav, tsv, 0.5, true, &e), 0);
    printf("# %.0f s heard in %.1f s of CPU: commands recognized %d/%d (%d taken for another), other sounds taken "
           "for commands %d/%d, commands over nothing %d, frames with a track born at a reflection %ld/%ld\n",
           e.seconds, e.cpu_s, e.recognized, e.commands, e.wrong, e.accepted, e.others, e.stray, e.false_track_frames,
           e.speech_frames);
    /* The decoder is never held: something is reported for most utterances to the end. */
    assert_true(e.results >= (e.commands + e.others) / 2);
    /* Measured here: 20/25 recognized, 1 taken for another command, 0/15 other sounds taken for
     * a command (before new streams began with the words' onset and before the narrow-beam
     * check: 14/25 and 5/15). The checks keep a margin under that (70%, 2 of 15, 2 wrong); the
     * goals (90%, under 2%) are not met: docs/audio.md. */
    assert_true(e.recognized * 10 >= e.commands * 7);
    assert_true(e.accepted * 7 <= e.others);
    assert_true(e.wrong <= 2);
    assert_true(e.stray <= 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_continuous_room),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
