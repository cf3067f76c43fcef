/* marie-tts: says what it is asked on the `say` port with Festival, publishes the voice as audio
 * blocks in real time and its progress (speaking, done), so that the robot knows when it speaks
 * and marie-asr can stay deaf meanwhile. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/tts/tts_child.h"
#include "adapters/tts/tts_params.h"
#include "core/clear.h"
#include "core/component.h"

#define QUEUE 8

typedef struct {
    int32_t id;
    char *text;
} request_t;

typedef struct {
    marie_component_t *c;
    marie_port_t *p_state, *p_audio;
    char *argv_buf;
    char *argv[32];
    request_t queue[QUEUE];
    int nqueue;
    bool busy;                  /* synthesizing or speaking queue[0] */
    tts_child_t *child;
    marie_timer_t *pace, *timeout;
    int16_t *pcm;
    size_t npcm, pos;
    int rate;
    int64_t seq;
} tts_t;

static const tts_params_t *params_of(const tts_t *s) { return marie_component_params(s->c); }

static void report(tts_t *s, const request_t *r, int8_t state)
{
    marie_robot_speech_t m = { .utime = marie_component_now(s->c), .id = r->id, .text = r->text, .state = state };
    marie_port_publish(s->p_state, &m);
}

static void next(tts_t *s);

static void done(tts_t *s, int8_t state)
{
    marie_loop_t *loop = marie_component_loop(s->c);
    marie_loop_remove_timer(loop, s->pace);
    marie_loop_remove_timer(loop, s->timeout);
    s->pace = s->timeout = NULL;
    MARIE_CLEAR(s->child, tts_child_cancel);
    report(s, &s->queue[0], state);
    marie_component_count(s->c, state == MARIE_ROBOT_SPEECH_T_STATE_DONE ? "said" : "failed", 1);
    free(s->queue[0].text);
    memmove(s->queue, s->queue + 1, sizeof(request_t) * (size_t)(--s->nqueue));
    MARIE_CLEAR(s->pcm, free);
    s->busy = false;
    next(s);
}

/* One block every block period: the voice goes out at the pace it is heard. */
static void on_pace(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    tts_t *s = user;
    if (s->pos >= s->npcm) {
        done(s, MARIE_ROBOT_SPEECH_T_STATE_DONE);
        return;
    }
    int16_t block[8192];
    size_t len = (size_t)params_of(s)->block;
    size_t n = s->npcm - s->pos < len ? s->npcm - s->pos : len;
    memset(block, 0, sizeof(int16_t) * len);
    memcpy(block, s->pcm + s->pos, sizeof(int16_t) * n);
    s->pos += n;
    marie_audio_frame_t f = { .utime = marie_component_now(s->c), .seq = s->seq++, .device = "tts",
                              .sample_rate = s->rate, .nchannels = 1, .nsamples = (int32_t)len, .nvalues = (int32_t)len,
                              .data = block };
    marie_port_publish(s->p_audio, &f);
}

static void on_synth(const int16_t *pcm, size_t n, int rate, const char *why, void *user)
{
    tts_t *s = user;
    s->child = NULL;
    marie_loop_remove_timer(marie_component_loop(s->c), s->timeout);
    s->timeout = NULL;
    if (!pcm || !n) {
        marie_component_event(s->c, MARIE_EVENT_T_SEV_WARN, "tts_failed", "cannot say \"%s\": %s", s->queue[0].text,
                              why ? why : "empty");
        done(s, MARIE_ROBOT_SPEECH_T_STATE_FAILED);
        return;
    }
    s->pcm = malloc(sizeof(int16_t) * n);
    if (!s->pcm) {
        done(s, MARIE_ROBOT_SPEECH_T_STATE_FAILED);
        return;
    }
    memcpy(s->pcm, pcm, sizeof(int16_t) * n);
    s->npcm = n;
    s->pos = 0;
    s->rate = rate;
    report(s, &s->queue[0], MARIE_ROBOT_SPEECH_T_STATE_SPEAKING);
    s->pace = marie_loop_add_wall_timer(marie_component_loop(s->c), params_of(s)->block * 1000000 / rate, on_pace, s);
    if (!s->pace)
        done(s, MARIE_ROBOT_SPEECH_T_STATE_FAILED);
}

static void on_timeout(marie_loop_t *loop, marie_timer_t *t, int64_t overruns, void *user)
{
    tts_t *s = user;
    s->timeout = NULL;
    marie_component_event(s->c, MARIE_EVENT_T_SEV_WARN, "tts_timeout", "synthesis of \"%s\" took over %.0f s",
                          s->queue[0].text, params_of(s)->synth_timeout_s);
    done(s, MARIE_ROBOT_SPEECH_T_STATE_FAILED);
}

static void next(tts_t *s)
{
    if (s->busy || s->nqueue == 0)
        return;
    s->busy = true;
    marie_loop_t *loop = marie_component_loop(s->c);
    s->child = tts_child_start(loop, s->argv, s->queue[0].text, on_synth, s);
    if (!s->child) {
        marie_component_event(s->c, MARIE_EVENT_T_SEV_ERROR, "tts_failed", "cannot start %s: %s", s->argv[0],
                              strerror(errno));
        done(s, MARIE_ROBOT_SPEECH_T_STATE_FAILED);
        return;
    }
    s->timeout = marie_loop_add_wall_oneshot(loop, (int64_t)(params_of(s)->synth_timeout_s * 1e6), on_timeout, s);
}

static void on_say(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    tts_t *s = marie_component_user(c);
    const marie_robot_speech_t *m = msg;
    if (m->state != MARIE_ROBOT_SPEECH_T_STATE_REQUEST)
        return;
    if (!m->text[0] || strlen(m->text) > 2000) {
        marie_component_bad_input(c, "bad_request", "say request %d refused: empty or over 2000 characters", m->id);
        return;
    }
    if (s->nqueue == QUEUE) {
        marie_component_count(c, "dropped", 1);
        return;
    }
    s->queue[s->nqueue].id = m->id;
    if (!(s->queue[s->nqueue].text = strdup(m->text)))
        return;
    s->nqueue++;
    next(s);
}

static int init(marie_component_t *c)
{
    tts_t *s = marie_component_user(c);
    const tts_params_t *q = marie_component_params(c);
    s->c = c;
    if (q->block < 16 || q->block > 8192 || !(q->synth_timeout_s > 0)) {
        marie_component_fail_reason(c, "block must be in [16, 8192], synth_timeout_s > 0");
        return -1;
    }
    free(s->argv_buf);
    s->argv_buf = strdup(q->command);
    int n = s->argv_buf ? tts_split_command(s->argv_buf, s->argv, 32) : -1;
    if (n <= 0) {
        marie_component_fail_reason(c, n == 0 ? "command is empty" : "command: a quote not closed, or over 31 words");
        return -1;
    }
    s->p_state = marie_port(c, "state");
    s->p_audio = marie_port(c, "audio");
    if (marie_port_on_message(marie_port(c, "say"), on_say)) {
        marie_component_fail_reason(c, "cannot subscribe to say");
        return -1;
    }
    return 0;
}

static void quit(marie_component_t *c)
{
    tts_t *s = marie_component_user(c);
    marie_loop_t *loop = marie_component_loop(c);
    marie_loop_remove_timer(loop, s->pace);
    marie_loop_remove_timer(loop, s->timeout);
    tts_child_cancel(s->child);
    for (int i = 0; i < s->nqueue; i++)
        free(s->queue[i].text);
    free(s->pcm);
    free(s->argv_buf);
    memset(s, 0, sizeof(*s));
}

static const marie_port_spec_t ports[] = {
    { "say", &marie_type_robot_speech_t, MARIE_IN, MARIE_PUSH, "SAY" },
    { "state", &marie_type_robot_speech_t, MARIE_OUT, MARIE_PUSH, "ROBOT_SPEECH" },
    { "audio", &marie_type_audio_frame_t, MARIE_OUT, MARIE_PUSH, "TTS_AUDIO" },
    { 0 },
};

static const marie_param_spec_t params[] = TTS_PARAMS;

static const marie_component_def_t def = {
    .kind = "tts", .ports = ports, .params = params, .params_size = sizeof(tts_params_t),
    .on_init = init, .on_quit = quit,
};

int main(int argc, char **argv)
{
    tts_t s = { 0 };
    return marie_main(&def, argc, argv, &s);
}
