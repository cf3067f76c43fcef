/* spoken_probe: watches the bus of the robot application while a person gives it a goal by voice
 * and measures what the person would see: the command recognized, the robot turning toward them
 * (the simulator's true heading against the true direction to the speaker), the answer spoken,
 * and the goal reached; with the time from the end of the words to the answer.
 *   spoken_probe --speaker X,Y --goal NAME --timeout S
 * Prints key=value lines; exits 0 once the goal is reached, 1 at the time limit. */
#include <getopt.h>
#include <math.h>
#include <signal.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <lcm/lcm.h>

#include "core/config.h"
#include "core/time.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_types.h"

#define DEG (180 / M_PI)
#define HANGOVER_US 450000      /* marie-asr's end-of-speech wait: the words ended this long before */

typedef struct {
    double speaker[2];
    const char *goal;
    /* the simulator's truth */
    double x, y, theta;
    int64_t truth_utime;
    bool have_truth;
    /* the chain */
    int64_t heard_utime;        /* the recognizer's end of speech, audio time */
    char heard[128];
    double heard_err;           /* rad: heading away from the speaker when heard */
    double min_err;             /* rad: closest the heading came to the speaker within 15 s */
    double face_az;             /* rad, robot frame, dialogue's */
    bool faced_event;
    int64_t say_utime, speaking_utime;
    char said[128];
    long tts_blocks, face_wins;
    int64_t started_utime, reached_utime;
    long collisions, refused;
} probe_t;

static volatile sig_atomic_t stop;
static void on_signal(int sig) { stop = 1; }

static double bearing_err(const probe_t *p)
{
    return remainder(atan2(p->speaker[1] - p->y, p->speaker[0] - p->x) - p->theta, 2 * M_PI);
}

static void on_raw(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    probe_t *p = user;
    union {
        marie_pose_cov_t pose;
        marie_speech_t speech;
        marie_event_t event;
        marie_robot_speech_t rs;
        marie_arbitration_t arb;
        marie_heartbeat_t hb;
        marie_audio_frame_t audio;
    } m;
    const marie_type_t *t = !strcmp(ch, "SIM_TRUTH") ? &marie_type_pose_cov_t
                          : !strcmp(ch, "SPEECH") ? &marie_type_speech_t
                          : !strcmp(ch, "DIALOGUE") || !strcmp(ch, "MARIE_EVENT") ? &marie_type_event_t
                          : !strcmp(ch, "ROBOT_SPEECH") || !strcmp(ch, "SAY") ? &marie_type_robot_speech_t
                          : !strcmp(ch, "ARBITRATION") ? &marie_type_arbitration_t
                          : !strcmp(ch, "MARIE_HEARTBEAT") ? &marie_type_heartbeat_t
                          : &marie_type_audio_frame_t;
    if (marie_decode_checked(t, rb->data, rb->data_size, &m) < 0)
        return;
    if (t == &marie_type_pose_cov_t) {
        p->x = m.pose.pose.x;
        p->y = m.pose.pose.y;
        p->theta = m.pose.pose.theta;
        p->truth_utime = m.pose.utime;
        p->have_truth = true;
        if (p->heard_utime && m.pose.utime < p->heard_utime + 15000000 && fabs(bearing_err(p)) < fabs(p->min_err))
            p->min_err = bearing_err(p);
    } else if (t == &marie_type_speech_t) {
        if (!p->heard_utime && strstr(m.speech.text, p->goal) && p->have_truth) {
            p->heard_utime = m.speech.utime;
            snprintf(p->heard, sizeof p->heard, "%s", m.speech.text);
            p->heard_err = p->min_err = bearing_err(p);
        }
    } else if (t == &marie_type_event_t) {
        if (!strcmp(ch, "DIALOGUE") && !strcmp(m.event.kind, "face") && !p->faced_event)
            p->faced_event = sscanf(m.event.text, "speaker %*d at azimuth %lf", &p->face_az) == 1;
        if (!strcmp(m.event.kind, "request_refused"))
            p->refused++;
        /* Events are stamped on the wall clock: the simulated time they came at is the truth's. */
        if (!strcmp(m.event.kind, "goal_started") && strstr(m.event.text, p->goal) && !p->started_utime)
            p->started_utime = p->truth_utime;
        if (!strcmp(m.event.kind, "goal_reached") && strstr(m.event.text, p->goal) && !p->reached_utime)
            p->reached_utime = p->truth_utime;
    } else if (t == &marie_type_robot_speech_t) {
        if (!strcmp(ch, "SAY") && p->heard_utime && !p->say_utime)
            p->say_utime = m.rs.utime;
        if (!strcmp(ch, "ROBOT_SPEECH") && m.rs.state == MARIE_ROBOT_SPEECH_T_STATE_SPEAKING && p->heard_utime &&
            !p->speaking_utime) {
            p->speaking_utime = m.rs.utime;
            snprintf(p->said, sizeof p->said, "%s", m.rs.text);
        }
    } else if (t == &marie_type_arbitration_t) {
        p->face_wins += !strcmp(m.arb.winner, "face_speaker");
    } else if (t == &marie_type_heartbeat_t) {
        for (int i = 0; i < m.hb.ncounters; i++)
            if (!strcmp(m.hb.counters[i].name, "collisions") && m.hb.counters[i].value > p->collisions)
                p->collisions = m.hb.counters[i].value;
    } else if (p->speaking_utime) {
        p->tts_blocks++;
    }
    t->decode_cleanup(&m);
}

int main(int argc, char **argv)
{
    probe_t p = { .goal = "room b", .min_err = M_PI };
    double timeout_s = 90;
    static const struct option opts[] = { { "speaker", required_argument, 0, 's' }, { "goal", required_argument, 0, 'g' },
                                          { "timeout", required_argument, 0, 't' }, { 0 } };
    int o;
    while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        if (o == 's' && sscanf(optarg, "%lf,%lf", &p.speaker[0], &p.speaker[1]) == 2)
            continue;
        if (o == 'g')
            p.goal = optarg;
        else if (o == 't')
            timeout_s = atof(optarg);
        else {
            fprintf(stderr, "usage: spoken_probe --speaker X,Y --goal NAME --timeout S\n");
            return 2;
        }
    }
    lcm_t *l = lcm_create(marie_default_url());
    if (!l)
        return 2;
    static const char *const channels[] = { "SIM_TRUTH", "SPEECH", "DIALOGUE", "MARIE_EVENT", "SAY", "ROBOT_SPEECH",
                                            "ARBITRATION", "MARIE_HEARTBEAT", "TTS_AUDIO" };
    for (size_t i = 0; i < sizeof channels / sizeof *channels; i++)
        lcm_subscription_set_queue_capacity(lcm_subscribe(l, channels[i], on_raw, &p), 1000);
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    int64_t end = marie_mono_us() + (int64_t)(timeout_s * 1e6), after = 0;
    while (!stop && marie_mono_us() < end && !(after && marie_mono_us() > after)) {
        lcm_handle_timeout(l, 100);
        if (p.reached_utime && !after)
            after = marie_mono_us() + 1000000;      /* the last heartbeats and truth */
    }
    double words_end = (p.heard_utime - HANGOVER_US) / 1e6;
    printf("heard=%s\n", p.heard[0] ? p.heard : "-");
    printf("face_event=%d azimuth_deg=%.1f\n", p.faced_event, p.face_az * DEG);
    printf("heading_error_when_heard_deg=%.1f\n", fabs(p.heard_err) * DEG);
    printf("heading_error_min_deg=%.1f\n", fabs(p.min_err) * DEG);
    printf("face_speaker_cycles=%ld\n", p.face_wins);
    printf("said=%s\n", p.said[0] ? p.said : "-");
    printf("tts_blocks=%ld\n", p.tts_blocks);
    printf("answer_after_words_s=%.3f\n", p.speaking_utime && p.heard_utime ? p.speaking_utime / 1e6 - words_end : -1);
    printf("answer_after_recognition_s=%.3f\n", p.speaking_utime && p.heard_utime ? (p.speaking_utime - p.heard_utime) / 1e6 : -1);
    printf("answer_requested_after_words_s=%.3f\n", p.say_utime && p.heard_utime ? p.say_utime / 1e6 - words_end : -1);
    printf("goal_started=%d\n", p.started_utime > 0);
    printf("reached_after_words_s=%.1f\n", p.reached_utime && p.heard_utime ? p.reached_utime / 1e6 - words_end : -1);
    printf("truth_final=%.2f,%.2f\n", p.x, p.y);
    printf("requests_refused=%ld\n", p.refused);
    printf("collisions=%ld\n", p.collisions);
    lcm_destroy(l);
    return p.reached_utime ? 0 : 1;
}
