/* bench_asr: recognition in rooms, continuous: commands recognized and other sounds taken for
 * commands, per condition (reverberation, SNR against a fan), on scenes spoken by espeak-ng and
 * rendered by pyroomacoustics (tests/audio/room_scene.py). As bench_asr_full (make bench-full)
 * each scene is 1500 utterances, about two hours. */
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

int main(int argc, char **argv)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    bool full = strstr(argv[0], "full") != NULL;
    int utterances = full ? 1500 : 30;     /* the default: well under a minute of decoding */
    const char *bench = full ? "asr_full" : "asr";
    static asr_eval_t e;
    for (size_t i = 0; i < sizeof(conditions) / sizeof(conditions[0]); i++) {
        char wav[512], tsv[512], cmd[2048], metric[96];
        snprintf(wav, sizeof(wav), "%s/share/rooms/bench_%s_%d.wav", b, conditions[i].name, utterances);
        snprintf(tsv, sizeof(tsv), "%s/share/rooms/bench_%s_%d.tsv", b, conditions[i].name, utterances);
        struct stat st;
        if (stat(wav, &st)) {
            snprintf(cmd, sizeof(cmd), "mkdir -p %s/share/rooms && %s/room/bin/python tests/audio/room_scene.py scene "
                     "--rt60 %g --snr %g --utterances %d --seed 7 %s/share/voices %s %s", b, b, conditions[i].rt60,
                     conditions[i].snr, utterances, b, wav, tsv);
            if (system(cmd)) {
                fprintf(stderr, "bench_asr: cannot render %s\n", wav);
                return 1;
            }
        }
        if (asr_eval_run(wav, tsv, 0.5, false, &e)) {
            perror("bench_asr");
            return 1;
        }
        snprintf(metric, sizeof(metric), "%s_commands_recognized", conditions[i].name);
        bench_row(bench, metric, 100.0 * e.recognized / (e.commands ? e.commands : 1), "%", -1);
        snprintf(metric, sizeof(metric), "%s_commands_wrong", conditions[i].name);
        bench_row(bench, metric, 100.0 * e.wrong / (e.commands ? e.commands : 1), "%", -1);
        snprintf(metric, sizeof(metric), "%s_others_accepted", conditions[i].name);
        bench_row(bench, metric, 100.0 * e.accepted / (e.others ? e.others : 1), "%", -1);
        snprintf(metric, sizeof(metric), "%s_reflection_track_frames", conditions[i].name);
        bench_row(bench, metric, 100.0 * e.false_track_frames / (e.speech_frames ? e.speech_frames : 1), "%", -1);
        snprintf(metric, sizeof(metric), "%s_cpu_per_audio_s", conditions[i].name);
        bench_row(bench, metric, e.cpu_s / e.seconds, "s/s", -1);
        fprintf(stderr, "%s: %d/%d commands (%d taken for another), %d/%d others accepted, %d stray, %.0f s of audio\n",
                conditions[i].name, e.recognized, e.commands, e.wrong, e.accepted, e.others, e.stray, e.seconds);
    }
    return 0;
}
