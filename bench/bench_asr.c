/* bench_asr: recognition in rooms, continuous: commands recognized and other sounds taken for
 * commands, per condition (reverberation, SNR against a fan), on scenes spoken by espeak-ng and
 * rendered by pyroomacoustics (tests/audio/room_scene.py). As bench_asr_full (make bench-full)
 * each scene is 1500 utterances, about two hours. `bench_asr ROOM.wav ROOM.tsv` scores a
 * recording of one's own room the same way (docs/audio.md). */
#include <errno.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "bench/bench.h"
#include "tests/audio/asr_eval.h"

static const struct {
    const char *name;
    double rt60, snr;
} conditions[] = {
    { "anechoic_snr5", 0, 5 }, { "rt30_snr10", 0.3, 10 }, { "rt30_snr5", 0.3, 5 }, { "rt60_snr10", 0.6, 10 },
};

/* A scene rendered by room_scene.py, or a recording of the user's, once it is there. */
static int render(const char *b, size_t i, int utterances, const char *wav, const char *tsv)
{
    struct stat st;
    if (!stat(wav, &st))
        return 0;
    char cmd[2048];
    snprintf(cmd, sizeof(cmd), "mkdir -p %s/share/rooms && %s/room/bin/python tests/audio/room_scene.py scene "
             "--rt60 %g --snr %g --utterances %d --seed 7 %s/share/voices %s %s", b, b, conditions[i].rt60,
             conditions[i].snr, utterances, b, wav, tsv);
    if (system(cmd)) {
        fprintf(stderr, "bench_asr: cannot render %s\n", wav);
        return -1;
    }
    return 0;
}

static int evaluate(const char *bench, const char *name, const char *wav, const char *tsv, bool verbose)
{
    static asr_eval_t e;
    char metric[96];
    if (asr_eval_run(wav, tsv, 0.5, verbose, &e)) {
        fprintf(stderr, "bench_asr: %s, %s: %s (an 8-channel 16 kHz WAVE of 1 s or more, and its TSV)\n", wav, tsv,
                strerror(errno));
        return -1;
    }
    snprintf(metric, sizeof(metric), "%s_commands_recognized", name);
    bench_row(bench, metric, 100.0 * e.recognized / (e.commands ? e.commands : 1), "%", -1);
    snprintf(metric, sizeof(metric), "%s_commands_wrong", name);
    bench_row(bench, metric, 100.0 * e.wrong / (e.commands ? e.commands : 1), "%", -1);
    snprintf(metric, sizeof(metric), "%s_others_accepted", name);
    bench_row(bench, metric, 100.0 * e.accepted / (e.others ? e.others : 1), "%", -1);
    snprintf(metric, sizeof(metric), "%s_reflection_track_frames", name);
    bench_row(bench, metric, 100.0 * e.false_track_frames / (e.speech_frames ? e.speech_frames : 1), "%", -1);
    snprintf(metric, sizeof(metric), "%s_cpu_per_audio_s", name);
    bench_row(bench, metric, e.cpu_s / e.seconds, "s/s", -1);
    fprintf(stderr, "%s: %d/%d commands (%d taken for another), %d/%d others accepted, %d stray, %.0f s of audio\n",
            name, e.recognized, e.commands, e.wrong, e.accepted, e.others, e.stray, e.seconds);
    return 0;
}

/* bench_asr ROOM.wav ROOM.tsv: a recording of one's own array (8 channels, 16 kHz) and what
 * was said when, scored the same way, with a line per result. */
int main(int argc, char **argv)
{
    if (argc == 3)
        return evaluate("asr", "own_room", argv[1], argv[2], true) ? 1 : 0;
    const char *b = getenv("B") ? getenv("B") : "build";
    bool full = strstr(argv[0], "full") != NULL;
    int utterances = full ? 1500 : 30;     /* the default: well under a minute of decoding */
    for (size_t i = 0; i < sizeof(conditions) / sizeof(conditions[0]); i++) {
        char wav[512], tsv[512];
        snprintf(wav, sizeof(wav), "%s/share/rooms/bench_%s_%d.wav", b, conditions[i].name, utterances);
        snprintf(tsv, sizeof(tsv), "%s/share/rooms/bench_%s_%d.tsv", b, conditions[i].name, utterances);
        if (render(b, i, utterances, wav, tsv) || evaluate(full ? "asr_full" : "asr", conditions[i].name, wav, tsv, false))
            return 1;
    }
    return 0;
}
