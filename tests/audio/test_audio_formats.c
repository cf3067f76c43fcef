/* test_audio_formats: WAVE files written and read back, truncated or foreign files refused;
 * array geometry text parsed or refused with a reason. */
#include <errno.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "core/file.h"
#include "hw/audio/micarray.h"
#include "hw/audio/wav.h"

static void test_wav_round_trip(void **state)
{
    int16_t pcm[2 * 100];
    for (int i = 0; i < 200; i++)
        pcm[i] = (int16_t)(i * 300 - 30000);
    char path[] = "/tmp/marie-wav-XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    close(fd);
    assert_int_equal(wav_write(path, pcm, 100, 2, 16000), 0);
    size_t len;
    uint8_t *buf = marie_file_read(path, 1 << 20, &len);
    assert_non_null(buf);
    wav_info_t w;
    assert_int_equal(wav_parse(buf, len, &w, NULL), 0);
    assert_int_equal(w.rate, 16000);
    assert_int_equal(w.channels, 2);
    assert_int_equal(w.frames, 100);
    float ch1[100];
    wav_channel_float(&w, 1, ch1);
    assert_true(ch1[10] == pcm[21] / 32768.0f);
    /* Truncated: the data chunk is cut to what is there, never read past the buffer. */
    assert_int_equal(wav_parse(buf, 44 + 40, &w, NULL), 0);
    assert_int_equal(w.frames, 10);
    /* Written to a pipe: sizes 0, the data runs to the end. */
    memset(buf + 40, 0, 4);
    assert_int_equal(wav_parse(buf, len, &w, NULL), 0);
    assert_int_equal(w.frames, 100);
    /* Not 16-bit PCM: refused with a reason. */
    buf[34] = 8;
    const char *why = NULL;
    assert_int_equal(wav_parse(buf, len, &w, &why), -1);
    assert_int_equal(errno, EINVAL);
    assert_non_null(why);
    assert_int_equal(wav_parse((const uint8_t *)"RIFF", 4, &w, NULL), -1);
    free(buf);
    unlink(path);
}

static void test_micarray_text(void **state)
{
    micarray_t a;
    assert_int_equal(micarray_parse(MICARRAY_DEFAULT, &a, NULL), 0);
    assert_int_equal(a.n, 8);
    assert_true(a.center[2] > 0.64 && a.center[2] < 0.66);
    assert_true(micarray_aperture(&a) > 0.319 && micarray_aperture(&a) < 0.321);
    assert_int_equal(micarray_parse("0,0,0; 0.1, 0 ,0;", &a, NULL), 0);
    assert_int_equal(a.n, 2);
    static const char *bad[] = { "", "1,2", "0,0,0", "0,0,0;x,1,1", "0,0,0;1,1,100", "0,0,0;1,1,1;;", NULL };
    for (int i = 0; bad[i]; i++) {
        const char *why = NULL;
        assert_int_equal(micarray_parse(bad[i], &a, &why), -1);
        assert_non_null(why);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_wav_round_trip),
        cmocka_unit_test(test_micarray_text),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
