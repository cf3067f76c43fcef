/* marie-dialogue: turns recognized commands into navigation goals, stops and turns toward the
 * speaker, and answers through marie-tts; every decision is an event on the dialogue channel. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "adapters/dialogue/dialogue.h"
#include "adapters/dialogue/dialogue_params.h"
#include "adapters/dialogue/speaker_dir.h"
#include "core/auth.h"
#include "core/clear.h"
#include "core/component.h"
#include "core/time.h"

typedef struct {
    dialogue_t d;
    marie_sound_source_t sources[16];
    int nsources;
    speaker_dir_t dirs;         /* the sources of the last seconds, for where each utterance came from */
    int32_t say_id, goal_id;
    int64_t event_seq, last_seq;
    marie_port_t *p_say, *p_goal, *p_event, *p_face, *p_request;
    marie_auth_t *auth;         /* NULL: goals only on SPOKEN_GOAL, no request to the mission */
    char sender[96];
} dlg_t;

static const dlg_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }

static void event(marie_component_t *c, dlg_t *s, const char *kind, const char *text)
{
    marie_event_t e = { .utime = marie_component_now(c), .source = (char *)marie_component_name(c),
                        .seq = s->event_seq++, .severity = MARIE_EVENT_T_SEV_INFO, .kind = (char *)kind,
                        .text = (char *)text };
    marie_port_publish(s->p_event, &e);
}

/* The spoken goal as the mission takes a person's goal: signed with the system's key, as
 * marie-face signs a tap on its page. */
static void request_goal(marie_component_t *c, dlg_t *s, const marie_goal_t *g)
{
    int64_t seq = marie_auth_next_seq(NULL);
    s->last_seq = seq > s->last_seq ? seq : s->last_seq + 1;
    marie_goal_request_t r = { .utime = marie_wall_us(), .sender = s->sender, .seq = s->last_seq, .goal = *g };
    r.goal.utime = r.utime;
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    if (marie_auth_sign_goal_request(s->auth, &r, mac) < 0 || marie_port_publish(s->p_request, &r) < 0)
        marie_component_count(c, "request_errors", 1);
}

static void face(dlg_t *s, int64_t now, int source_id, double azimuth)
{
    marie_sound_source_t src = { 0 };
    for (int i = 0; i < s->nsources; i++)
        if (s->sources[i].id == source_id)
            src = s->sources[i];
    src.id = source_id;
    src.azimuth = (float)azimuth;
    marie_sound_sources_t m = { .utime = now, .count = 1, .sources = &src };
    marie_port_publish(s->p_face, &m);
}

static void on_sources(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    dlg_t *s = marie_component_user(c);
    const marie_sound_sources_t *m = msg;
    s->nsources = m->count < 0 ? 0 : m->count < 16 ? m->count : 16;
    if (s->nsources > 0)        /* no sources: an empty array, NULL */
        memcpy(s->sources, m->sources, sizeof(marie_sound_source_t) * (size_t)s->nsources);
    for (int i = 0; i < s->nsources; i++)
        speaker_dir_add(&s->dirs, m->utime, m->sources[i].id, m->sources[i].azimuth, m->sources[i].energy,
                        m->sources[i].activity);
}

static void on_speech(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    dlg_t *s = marie_component_user(c);
    const marie_speech_t *m = msg;
    char buf[320];
    if (m->confidence < params_of(c)->min_confidence) {
        marie_component_count(c, "unsure", 1);
        snprintf(buf, sizeof(buf), "\"%.200s\" ignored (confidence %.2f)", m->text, m->confidence);
        event(c, s, "unsure", buf);
        return;
    }
    double az = 0;
    bool has_az = speaker_dir_get(&s->dirs, m->source_id, m->start_utime, m->utime, &az);
    dialogue_reply_t r;
    dialogue_hear(&s->d, m->text, m->source_id, has_az, az, &r);
    snprintf(buf, sizeof(buf), "heard \"%.200s\" from source %d", m->text, m->source_id);
    event(c, s, "heard", buf);
    if (r.actions & DIALOGUE_FACE) {
        snprintf(buf, sizeof(buf), "speaker %d at azimuth %.3f rad", m->source_id, r.azimuth);
        event(c, s, "face", buf);
        face(s, marie_component_now(c), m->source_id, r.azimuth);
    }
    if (r.actions & DIALOGUE_STOP)
        event(c, s, "stop", "asked to stop");
    if (r.actions & DIALOGUE_GOAL) {
        /* Ids of their own (the mission's list counts from 1, the touch page from 800000, the
         * viewer from 900000): a request with the id of a listed goal would replace it. */
        double tol = params_of(c)->tolerance;     /* the goal carries the parameter: a use, no copy */
        marie_goal_t g = { .utime = marie_component_now(c), .id = 700000 + ++s->goal_id, .name = r.place.name,
                           .pose = { r.place.x, r.place.y, r.place.theta }, .tolerance = tol, .priority = 10 };
        marie_port_publish(s->p_goal, &g);
        if (s->auth)
            request_goal(c, s, &g);
        snprintf(buf, sizeof(buf), "goal %d: %s (%.2f, %.2f)", g.id, r.place.name, r.place.x, r.place.y);
        event(c, s, "goal", buf);
    }
    if (r.say[0]) {
        marie_robot_speech_t say = { .utime = marie_component_now(c), .id = ++s->say_id, .text = r.say,
                                     .state = MARIE_ROBOT_SPEECH_T_STATE_REQUEST };
        marie_port_publish(s->p_say, &say);
    }
}

static int init(marie_component_t *c)
{
    dlg_t *s = marie_component_user(c);
    const dlg_params_t *q = marie_component_params(c);
    dialogue_place_t places[DIALOGUE_MAX_PLACES];
    int n = 0;
    char why[256];
    if (dialogue_places_parse(q->places, places, DIALOGUE_MAX_PLACES, &n, why, sizeof(why))) {
        marie_component_fail_reason(c, "places: %s", why);
        return -1;
    }
    dialogue_init(&s->d, places, n, q->robot_name);
    speaker_dir_init(&s->dirs);
    s->p_say = marie_port(c, "say");
    s->p_goal = marie_port(c, "goal");
    s->p_event = marie_port(c, "events");
    s->p_face = marie_port(c, "face");
    s->p_request = marie_port(c, "request");
    MARIE_CLEAR(s->auth, marie_auth_destroy);
    if (q->key_file[0]) {
        char err[256], host[64] = "";
        if (!(s->auth = marie_auth_load(q->key_file, err, sizeof err))) {
            marie_component_fail_reason(c, "key file: %s", err);
            return -1;
        }
        gethostname(host, sizeof host - 1);
        snprintf(s->sender, sizeof s->sender, "%s@%s/dialogue", marie_component_name(c), host);
    }
    if (marie_port_on_message(marie_port(c, "speech"), on_speech) ||
        marie_port_on_message(marie_port(c, "sources"), on_sources)) {
        marie_component_fail_reason(c, "cannot subscribe");
        return -1;
    }
    return 0;
}

static const marie_port_spec_t ports[] = {
    { "speech", &marie_type_speech_t, MARIE_IN, MARIE_PUSH, "SPEECH" },
    { "sources", &marie_type_sound_sources_t, MARIE_IN, MARIE_PUSH, "SOUND_SOURCES" },
    { "say", &marie_type_robot_speech_t, MARIE_OUT, MARIE_PUSH, "SAY" },
    { "goal", &marie_type_goal_t, MARIE_OUT, MARIE_PUSH, "SPOKEN_GOAL" },
    { "events", &marie_type_event_t, MARIE_OUT, MARIE_PUSH, "DIALOGUE" },
    { "face", &marie_type_sound_sources_t, MARIE_OUT, MARIE_PUSH, "SPEAKER" },
    { "request", &marie_type_goal_request_t, MARIE_OUT, MARIE_PUSH, "GOAL_REQUEST" },
    { 0 },
};

static const marie_param_spec_t params[] = DLG_PARAMS;

static void quit(marie_component_t *c)
{
    dlg_t *s = marie_component_user(c);
    MARIE_CLEAR(s->auth, marie_auth_destroy);
}

static const marie_component_def_t def = {
    .kind = "dialogue", .ports = ports, .params = params, .params_size = sizeof(dlg_params_t), .on_init = init,
    .on_quit = quit,
};

int main(int argc, char **argv)
{
    dlg_t s = { 0 };
    return marie_main(&def, argc, argv, &s);
}
