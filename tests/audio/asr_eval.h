/* asr_eval: a continuous scene (an 8-channel WAVE and what was said when, written by
 * tests/audio/room_scene.py) run through marie-ssl's pipeline and marie-asr's recognizer as
 * the components run them, and scored: commands recognized, other sounds taken for commands,
 * false tracks. What the recognition test and benchmark share. */
#ifndef MARIE_TESTS_AUDIO_ASR_EVAL_H
#define MARIE_TESTS_AUDIO_ASR_EVAL_H
#include <stdbool.h>
#include <stddef.h>

#define ASR_EVAL_MAX_EVENTS 4096

typedef struct {
    double start, end;          /* s */
    char kind[16];              /* command, oog, real, noise, fan */
    char text[160];
    double bearing;             /* rad, robot frame */
    bool heard;                 /* scoring: recognized (commands), taken for a command (others) */
    bool wrong;                 /* a command taken for another command */
} asr_eval_event_t;

typedef struct {
    int nevents;
    asr_eval_event_t ev[ASR_EVAL_MAX_EVENTS];
    int commands, recognized;   /* commands said, and recognized right with confidence >= min */
    int wrong;                  /* commands taken for another command (and never for the right one) */
    int others, accepted;       /* other utterances and noises, and those taken for a command */
    int stray;                  /* commands accepted over no utterance at all */
    int results;                /* what the recognizer reported */
    int bad_lines;              /* of the TSV, not understood (reported on stderr with their line) */
    long speech_frames, false_track_frames;   /* frames during speech; with a track far from the speaker and the fan */
    double seconds, cpu_s;
} asr_eval_t;

/* Runs the scene; min_confidence as marie-dialogue's. 0, or -1 with errno. */
int asr_eval_run(const char *wav, const char *tsv, double min_confidence, bool verbose, asr_eval_t *out);

#endif
