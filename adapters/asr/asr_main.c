/* marie-asr: recognizes spoken commands on the separated streams of marie-ssl (or on one
 * microphone of the array) and publishes what was said; deaf while the robot speaks. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/asr/asr.h"
#include "adapters/asr/asr_params.h"
#include "core/buf.h"
#include "core/clear.h"
#include "core/component.h"
#include "core/file.h"

typedef struct {
    asr_t *asr;
    marie_port_t *p_speech;
    const char **phrases;
    char *phrase_text;
    int nphrases;
    int16_t *mono;
    bool speaking;
    int64_t deaf_until;
    int64_t last_utime, last_now;   /* the newest block's time, and the clock's then */
    marie_component_t *c;
} asr_state_t;

static const asr_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }

static void on_heard(const asr_result_t *r, void *user)
{
    asr_state_t *s = user;
    marie_component_count(s->c, r->text[0] ? "utterances" : "unrecognized", 1);
    if (!r->text[0])
        return;
    marie_speech_t m = { .utime = r->end_utime, .start_utime = r->start_utime, .source_id = r->source_id,
                         .text = (char *)r->text, .confidence = (float)r->confidence };
    marie_info("heard \"%s\" from source %d (confidence %.2f)", r->text, r->source_id, r->confidence);
    marie_port_publish(s->p_speech, &m);
}

/* The audio's time now: the newest block's stamp, and what the component's clock says passed
 * since it came. The robot's voice is timed by this, not by ROBOT_SPEECH's stamp, which comes
 * from another clock (the speaker's computer, or the wall while the audio runs on the
 * simulator's): a stamp seconds ahead of the audio's left the recognizer deaf for good. */
static int64_t audio_now(const asr_state_t *s)
{
    return s->last_now ? s->last_utime + (marie_component_now(s->c) - s->last_now) : 0;
}

/* A block arrives: the recognizer hears it unless the robot speaks. */
static bool deaf(asr_state_t *s, int64_t utime)
{
    s->last_utime = utime;
    s->last_now = marie_component_now(s->c);
    bool d = s->speaking || utime < s->deaf_until;
    asr_mute(s->asr, d);
    return d;
}

static void on_separated(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    asr_state_t *s = marie_component_user(c);
    const marie_separated_audio_t *m = msg;
    int block = (int)params_of(c)->block;
    if (m->sample_rate != 16000 || m->nsamples != block) {
        marie_component_bad_input(c, "bad_audio", "separated block of %d samples at %d Hz refused (want %d at 16000)",
                                  m->nsamples, m->sample_rate, block);
        return;
    }
    if (!deaf(s, m->utime))
        asr_feed(s->asr, m->source_id, m->data, m->nsamples, m->utime);
}

/* No block at all (every track died): the stream being decoded is over all the same. Time
 * goes on from the newest block's stamp by the clock. */
static void on_tick(marie_component_t *c, int64_t overruns)
{
    asr_state_t *s = marie_component_user(c);
    if (s->last_now)
        asr_expire(s->asr, audio_now(s));
}

static void on_array(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    asr_state_t *s = marie_component_user(c);
    const marie_audio_frame_t *f = msg;
    int block = (int)params_of(c)->block, channel = (int)params_of(c)->channel;
    if (f->sample_rate != 16000 || f->nsamples != block || channel >= f->nchannels ||
        (int64_t)f->nchannels * f->nsamples != f->nvalues) {
        marie_component_bad_input(c, "bad_audio", "array block of %d x %d samples at %d Hz refused (want channel %d, "
                                  "%d samples at 16000)", f->nchannels, f->nsamples, f->sample_rate, channel, block);
        return;
    }
    for (int i = 0; i < f->nsamples; i++)
        s->mono[i] = f->data[i * f->nchannels + channel];
    if (!deaf(s, f->utime))
        asr_feed(s->asr, -1, s->mono, f->nsamples, f->utime);
}

/* The robot's own voice: deaf from its start until a moment after its end. */
static void on_robot_speech(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    asr_state_t *s = marie_component_user(c);
    const marie_robot_speech_t *m = msg;
    if (m->state == MARIE_ROBOT_SPEECH_T_STATE_SPEAKING) {
        s->speaking = true;
    } else if (m->state == MARIE_ROBOT_SPEECH_T_STATE_DONE || m->state == MARIE_ROBOT_SPEECH_T_STATE_FAILED) {
        s->speaking = false;
        s->deaf_until = audio_now(s) + (int64_t)(params_of(c)->deaf_after_s * 1e6);
    }
}

/* One phrase per line; blank lines and # comments skipped. */
static int load_commands(asr_state_t *s, const char *path)
{
    size_t len;
    s->phrase_text = marie_file_read(path, 1 << 20, &len);
    if (!s->phrase_text)
        return -1;
    size_t cap = 0;
    for (char *save = NULL, *line = strtok_r(s->phrase_text, "\n", &save); line;
         line = strtok_r(NULL, "\n", &save)) {
        while (*line == ' ')
            line++;
        if (!*line || *line == '#')
            continue;
        if (MARIE_GROW(s->phrases, cap, (size_t)s->nphrases + 1) < 0)
            return -1;
        s->phrases[s->nphrases++] = line;
    }
    return s->phrases && s->nphrases ? 0 : (errno = EINVAL, -1);
}

static int init(marie_component_t *c)
{
    asr_state_t *s = marie_component_user(c);
    const asr_params_t *q = marie_component_params(c);
    s->c = c;
    int block = (int)q->block;
    const char *const *phrases = asr_default_commands;
    int n = asr_default_ncommands;
    if (q->commands && *q->commands) {
        if (load_commands(s, q->commands)) {
            marie_component_fail_reason(c, "commands %s: %s", q->commands, strerror(errno));
            return -1;
        }
        phrases = s->phrases;
        n = s->nphrases;
    }
    asr_cfg_t cfg;
    asr_cfg_default(&cfg, phrases, n, block);
    cfg.model = q->model;
    char why[256] = "";
    if (block < 16 || block > 16000 || !(s->mono = malloc(sizeof(int16_t) * (size_t)block)) ||
        !(s->asr = asr_create(&cfg, on_heard, s, why, sizeof(why)))) {
        marie_component_fail_reason(c, "recognizer: %s", why[0] ? why : "block out of range");
        return -1;
    }
    s->p_speech = marie_port(c, "speech");
    bool array = !strcmp(q->input, "array");
    if (!array && strcmp(q->input, "separated")) {
        marie_component_fail_reason(c, "input: separated or array, not '%s'", q->input);
        return -1;
    }
    if (marie_port_on_message(marie_port(c, array ? "array" : "separated"), array ? on_array : on_separated) ||
        marie_port_on_message(marie_port(c, "robot_speech"), on_robot_speech)) {
        marie_component_fail_reason(c, "cannot subscribe to the audio");
        return -1;
    }
    if (!array && !marie_component_every(c, 10, on_tick)) {
        marie_component_fail_reason(c, "cannot start the stream timer");
        return -1;
    }
    marie_info("%d command phrases, listening to the %s", n, array ? "array's first microphone" : "separated streams");
    return 0;
}

static void quit(marie_component_t *c)
{
    asr_state_t *s = marie_component_user(c);
    MARIE_CLEAR(s->asr, asr_destroy);
    MARIE_CLEAR(s->mono, free);
    MARIE_CLEAR(s->phrases, free);
    MARIE_CLEAR(s->phrase_text, free);
}

static const marie_port_spec_t ports[] = {
    { "separated", &marie_type_separated_audio_t, MARIE_IN, MARIE_PUSH, "SEPARATED_AUDIO" },
    { "array", &marie_type_audio_frame_t, MARIE_IN, MARIE_PUSH, "AUDIO" },
    { "robot_speech", &marie_type_robot_speech_t, MARIE_IN, MARIE_PUSH, "ROBOT_SPEECH" },
    { "speech", &marie_type_speech_t, MARIE_OUT, MARIE_PUSH, "SPEECH" },
    { 0 },
};

static const marie_param_spec_t params[] = ASR_PARAMS;

static const marie_component_def_t def = {
    .kind = "asr", .ports = ports, .params = params, .params_size = sizeof(asr_params_t),
    .on_init = init, .on_quit = quit,
};

int main(int argc, char **argv)
{
    asr_state_t s = { 0 };
    return marie_main(&def, argc, argv, &s);
}
