/* test_ssl_process: marie-sim's microphone array and marie-ssl as processes on a real LCM bus
 * (this test's namespace): 8 x 16 kHz audio blocks arrive without a gap, a phrase said at a
 * known bearing in a room with a fan becomes a tracked source there with its separated
 * stream, and a malformed audio block is refused and counted, not crashed on. */
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
#define WALL_LIMIT_US 40000000      /* a bound on every wait, not a timing assertion */

static struct {
    long blocks, lost, bad_shape;
    int64_t last_seq;
    int64_t first_audio_utime, last_audio_utime;
    long sources_msgs;
    int near_speech;            /* messages with a source within 10 deg of the speaker */
    int speech_id;
    double speech_az_sum;
    long separated, separated_for_speech;
    double sep_energy;
} rx = { .last_seq = -1, .speech_id = -1 };

static double speech_bearing;

static void on_audio(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    marie_audio_frame_t f;
    if (marie_decode_checked(&marie_type_audio_frame_t, rb->data, rb->data_size, &f) < 0)
        return;
    rx.blocks++;
    if (f.nchannels != 8 || f.nsamples != 256 || f.sample_rate != 16000 || f.nvalues != 8 * 256)
        rx.bad_shape++;
    if (rx.last_seq >= 0 && f.seq != rx.last_seq + 1)
        rx.lost += f.seq - rx.last_seq - 1;
    rx.last_seq = f.seq;
    if (!rx.first_audio_utime)
        rx.first_audio_utime = f.utime;
    rx.last_audio_utime = f.utime;
    marie_type_audio_frame_t.decode_cleanup(&f);
}

static void on_sources(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    marie_sound_sources_t m;
    if (marie_decode_checked(&marie_type_sound_sources_t, rb->data, rb->data_size, &m) < 0)
        return;
    rx.sources_msgs++;
    for (int i = 0; i < m.count; i++) {
        double e = fabs(remainder(m.sources[i].azimuth - speech_bearing, 2 * M_PI));
        if (e < 10 * DEG) {
            rx.near_speech++;
            rx.speech_id = m.sources[i].id;
            rx.speech_az_sum += m.sources[i].azimuth;
        }
    }
    marie_type_sound_sources_t.decode_cleanup(&m);
}

static void on_separated(const lcm_recv_buf_t *rb, const char *ch, void *u)
{
    marie_separated_audio_t m;
    if (marie_decode_checked(&marie_type_separated_audio_t, rb->data, rb->data_size, &m) < 0)
        return;
    rx.separated++;
    if (m.source_id == rx.speech_id) {
        rx.separated_for_speech++;
        for (int i = 0; i < m.nsamples; i++)
            rx.sep_energy += (double)m.data[i] * m.data[i];
    }
    marie_type_separated_audio_t.decode_cleanup(&m);
}

static char *bin(const char *name)
{
    static char path[4][256];
    static int k;
    char *p = path[k++ % 4];
    snprintf(p, 256, "%s/bin/%s", getenv("B") ? getenv("B") : "build", name);
    return p;
}

static char *phrase(int n)
{
    static char p[256];
    snprintf(p, sizeof(p), "%s/share/sounds/phrase_%02d.wav", getenv("B") ? getenv("B") : "build", n);
    return p;
}

static int grep_file(const char *path, const char *needle)
{
    FILE *f = fopen(path, "r");
    char line[1024];
    int found = 0;
    while (f && !found && fgets(line, sizeof(line), f))
        found = strstr(line, needle) != NULL;
    if (f)
        fclose(f);
    return found;
}

static void test_sim_array_and_ssl_on_the_bus(void **state)
{
    /* Robot at (3, 2) facing +x in the test world; the speaker 2 m away at 60 degrees, a fan
     * at (1, 1) behind on the right, walls reflecting half the amplitude, 15 dB diffuse noise. */
    speech_bearing = 60 * DEG;
    char scene[1024];
    snprintf(scene, sizeof(scene), "audio=speech file=%s x=%.3f y=%.3f z=1.5 start=0.3 every=2.0 level=0.05; "
             "fan x=1 y=1 z=0.5 level=0.01; walls reflect=0.5; diffuse snr=15",
             phrase(2), 3 + 2 * cos(speech_bearing), 2 + 2 * sin(speech_bearing));
    char *sim_argv[] = { bin("marie-sim"), "--world", "test", "--param", "start_x=3.0", "--param", "start_y=2.0",
                         "--param", scene, NULL };
    char log[] = "/tmp/marie-ssl-proc-XXXXXX";
    int fd = mkstemp(log);
    assert_true(fd >= 0);
    close(fd);
    char *ssl_argv[] = { bin("marie-ssl"), NULL };
    lcm_t *l = lcm_create(marie_default_url());
    assert_non_null(l);
    lcm_subscribe(l, "AUDIO", on_audio, NULL);
    lcm_subscribe(l, "SOUND_SOURCES", on_sources, NULL);
    lcm_subscribe(l, "SEPARATED_AUDIO", on_separated, NULL);
    pid_t ssl = test_spawn(ssl_argv, log);
    pid_t sim = test_spawn(sim_argv, "/dev/null");
    assert_true(ssl > 0 && sim > 0);
    int64_t t0 = marie_mono_us();
    /* Six simulated seconds of audio, or the wall limit. */
    while (marie_mono_us() - t0 < WALL_LIMIT_US &&
           (rx.first_audio_utime == 0 || rx.last_audio_utime - rx.first_audio_utime < 6000000))
        lcm_handle_timeout(l, 100);
    long lost = rx.lost, bad_shape = rx.bad_shape;
    double audio_s = (rx.last_audio_utime - rx.first_audio_utime) / 1e6;
    /* A block of the wrong shape: refused by marie-ssl with a reason, which keeps running. */
    int16_t junk[10] = { 0 };
    marie_audio_frame_t bad = { .utime = 1, .seq = 0, .device = "junk", .sample_rate = 16000, .nchannels = 5,
                                .nsamples = 2, .nvalues = 10, .data = junk };
    marie_audio_frame_t_publish(l, "AUDIO", &bad);
    int64_t t1 = marie_mono_us();
    while (marie_mono_us() - t1 < 10000000 && !grep_file(log, "refused"))
        lcm_handle_timeout(l, 100);
    test_stop(sim);
    int alive = kill(ssl, 0) == 0;
    test_stop(ssl);
    printf("# %ld audio blocks (%.1f s), %ld lost; %ld source messages, %d with the speaker (mean %.1f deg, "
           "truth %.0f); %ld separated blocks, %ld for the speaker\n",
           rx.blocks, audio_s, lost, rx.sources_msgs, rx.near_speech,
           rx.near_speech ? rx.speech_az_sum / rx.near_speech / DEG : NAN, speech_bearing / DEG, rx.separated,
           rx.separated_for_speech);
    assert_true(rx.blocks >= 6 * 62);
    assert_int_equal(lost, 0);
    assert_int_equal(bad_shape, 0);
    assert_true(rx.sources_msgs >= 40);
    assert_true(rx.near_speech >= 10);
    assert_true(rx.separated_for_speech >= 100);
    assert_true(rx.sep_energy > 0);
    assert_true(grep_file(log, "refused"));
    assert_true(alive);
    unlink(log);
    lcm_destroy(l);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sim_array_and_ssl_on_the_bus),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
