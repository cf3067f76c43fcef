/* test_audio_alsa: marie-audio capturing a real ALSA PCM with no hardware behind it: ALSA's
 * `file` plugin over its `null` plugin, defined in an asoundrc, feeds a known 8-channel ramp;
 * each AUDIO block on the bus (this test's namespace) holds exactly the samples its sequence
 * number says, in order; a device that does not exist is refused with ALSA's reason.
 * The null plugin has no clock: capture runs as fast as the process can read, far beyond what
 * the bus delivers, so the receiver here misses blocks (counted, not a driver loss: a block's
 * content is checked against its own sequence number). */
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include <lcm/lcm.h>

#include "core/component.h"
#include "core/typeinfo.h"
#include "tests/proc.h"

#define FRAMES 32000

#define EARLY 125               /* blocks of 256 frames within the file */

static struct {
    long blocks, mismatches, gaps, checked, backwards, early;
    int64_t next_seq;
} rx = { .next_seq = 0 };

static void on_audio(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    marie_audio_frame_t f;
    if (marie_decode_checked(&marie_type_audio_frame_t, rb->data, rb->data_size, &f) < 0)
        return;
    if (f.seq < rx.next_seq)
        rx.backwards++;
    else if (f.seq != rx.next_seq)
        rx.gaps++;
    rx.early += f.seq < EARLY && f.nsamples == 256;
    rx.next_seq = f.seq + 1;
    /* Blocks inside the file's length: frame k, channel c holds (8k + c) mod 30000. */
    for (int k = 0; k < f.nsamples && f.nchannels == 8; k++) {
        long frame = (long)f.seq * f.nsamples + k;
        if (frame >= FRAMES)
            break;
        for (int c = 0; c < 8; c++) {
            rx.checked++;
            rx.mismatches += f.data[k * 8 + c] != (int16_t)((frame * 8 + c) % 30000);
        }
    }
    rx.blocks++;
    marie_type_audio_frame_t.decode_cleanup(&f);
}

static char dir[] = "/tmp/marie-alsa-XXXXXX";

static void write_files(void)
{
    assert_non_null(mkdtemp(dir));
    char path[256];
    snprintf(path, sizeof(path), "%s/in.raw", dir);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    for (long k = 0; k < FRAMES; k++)
        for (int c = 0; c < 8; c++) {
            int16_t v = (int16_t)((k * 8 + c) % 30000);
            fwrite(&v, 2, 1, f);
        }
    fclose(f);
    snprintf(path, sizeof(path), "%s/.asoundrc", dir);
    f = fopen(path, "w");
    assert_non_null(f);
    /* What is captured is also written to `file`: /dev/null, or it grows without end. */
    fprintf(f, "pcm.marie_test {\n type file\n slave.pcm \"null\"\n file \"/dev/null\"\n infile \"%s/in.raw\"\n"
               " format \"raw\"\n}\n", dir);
    fprintf(f, "pcm.marie_play {\n type file\n slave.pcm \"null\"\n file \"%s/out.raw\"\n format \"raw\"\n}\n", dir);
    fclose(f);
    setenv("HOME", dir, 1);     /* ALSA reads ~/.asoundrc */
}

static char *bin(void)
{
    static char p[256];
    snprintf(p, sizeof(p), "%s/bin/marie-audio", getenv("B") ? getenv("B") : "build");
    return p;
}

static void test_capture_through_alsa(void **state)
{
    write_files();
    lcm_t *l = lcm_create(marie_default_url());
    assert_non_null(l);
    lcm_subscribe(l, "AUDIO", on_audio, NULL);
    char *argv[] = { bin(), "--param", "device=marie_test", NULL };
    pid_t pid = test_spawn(argv, "/dev/null");
    assert_true(pid > 0);
    int64_t t0 = marie_mono_us();
    while (rx.blocks < 2000 && marie_mono_us() - t0 < 20000000)
        lcm_handle_timeout(l, 100);
    int alive = kill(pid, 0) == 0;
    test_stop(pid);
    printf("# %ld blocks received (%ld of the %d holding the file), %ld samples compared, %ld differ, "
           "%ld gaps at the receiver, %ld out of order\n", rx.blocks, rx.early, EARLY, rx.checked, rx.mismatches,
           rx.gaps, rx.backwards);
    assert_true(alive);
    assert_true(rx.early >= 10);
    assert_true(rx.checked >= 10L * 256 * 8);
    assert_int_equal(rx.mismatches, 0);
    assert_int_equal(rx.backwards, 0);
    lcm_destroy(l);
}

/* The play port's blocks (the robot's voice) reach the playback PCM sample for sample. */
static void test_playback_through_alsa(void **state)
{
    lcm_t *l = lcm_create(marie_default_url());
    char *argv[] = { bin(), "--param", "playback=marie_play", NULL };
    pid_t pid = test_spawn(argv, "/dev/null");
    assert_true(pid > 0);
    usleep(700000);
    int16_t block[256];
    for (int b = 0; b < 20; b++) {
        for (int i = 0; i < 256; i++)
            block[i] = (int16_t)(b * 256 + i);
        marie_audio_frame_t f = { .utime = b, .seq = b, .device = "tts", .sample_rate = 16000, .nchannels = 1,
                                  .nsamples = 256, .nvalues = 256, .data = block };
        marie_audio_frame_t_publish(l, "TTS_AUDIO", &f);
        usleep(16000);
    }
    usleep(500000);
    test_stop(pid);
    char path[256];
    snprintf(path, sizeof(path), "%s/out.raw", dir);
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    int16_t v;
    long n = 0, bad = 0;
    while (n < 20 * 256 && fread(&v, 2, 1, f) == 1)
        bad += v != (int16_t)n++;
    fclose(f);
    printf("# playback: %ld samples written, %ld differ\n", n, bad);
    assert_int_equal(n, 20 * 256);
    assert_int_equal(bad, 0);
    lcm_destroy(l);
}

static void test_missing_device_is_refused(void **state)
{
    char log[256];
    snprintf(log, sizeof(log), "%s/bad.log", dir);
    char *argv[] = { bin(), "--param", "device=hw:77", NULL };
    pid_t pid = test_spawn(argv, log);
    int found = 0;
    for (int i = 0; i < 100 && !found; i++) {
        usleep(100000);
        FILE *f = fopen(log, "r");
        char line[512];
        while (f && fgets(line, sizeof(line), f))
            found |= strstr(line, "capture hw:77") != NULL;
        if (f)
            fclose(f);
    }
    test_stop(pid);
    assert_true(found);
    char cmd[300];
    snprintf(cmd, sizeof(cmd), "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_capture_through_alsa),
        cmocka_unit_test(test_playback_through_alsa),
        cmocka_unit_test(test_missing_device_is_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
