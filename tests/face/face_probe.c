/* face_probe: the pages' test peer on the bus. --watch S --key FILE prints every goal request
 * (with whether its signature holds under the key) and every GOAL for S seconds; --unsigned
 * NAME publishes a goal request without a signature and one with a forged one; --landmark
 * ID:X:Y:YAW:TEXT publishes a landmark (as marie-vision does) every 0.2 s while watching;
 * --heard TEXT publishes an utterance as marie-asr does, --said TEXT a request to speak as
 * marie-dialogue does. While watching it also prints every event (MARIE_EVENT). */
#include <getopt.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <lcm/lcm.h>

#include "core/auth.h"
#include "core/time.h"
#include "lcmtypes/marie_types.h"

static marie_auth_t *auth;

static void on_request(const lcm_recv_buf_t *rb, const char *ch, const marie_goal_request_t *m, void *u)
{
    marie_auth_result_t r = marie_auth_check_goal_request(auth, NULL, m);
    printf("request %s (%.2f, %.2f) from %s: %s\n", m->goal.name, m->goal.pose.x, m->goal.pose.y, m->sender,
           r == MARIE_AUTH_OK ? "signed" : marie_auth_result_name(r));
    fflush(stdout);
}

static void on_event(const lcm_recv_buf_t *rb, const char *ch, const marie_event_t *m, void *u)
{
    printf("event %s from %s: %s\n", m->kind, m->source, m->text);
    fflush(stdout);
}

static void on_goal(const lcm_recv_buf_t *rb, const char *ch, const marie_goal_t *m, void *u)
{
    static char last[64];
    if (strcmp(last, m->name) != 0)
        printf("goal %s (%.2f, %.2f)\n", m->name, m->pose.x, m->pose.y);
    snprintf(last, sizeof last, "%s", m->name);
    fflush(stdout);
}

int main(int argc, char **argv)
{
    double watch = 0;
    const char *key = NULL, *unsigned_name = NULL, *heard = NULL, *said = NULL;
    marie_landmark_t lm = { .family = "tag36h11" };
    char lm_text[64] = "";
    bool landmark = false;
    static struct option opts[] = { { "watch", 1, 0, 'w' }, { "key", 1, 0, 'k' }, { "unsigned", 1, 0, 'u' },
                                    { "landmark", 1, 0, 'l' }, { "heard", 1, 0, 'h' }, { "said", 1, 0, 's' },
                                    { 0 } };
    int o;
    while ((o = getopt_long(argc, argv, "", opts, NULL)) != -1) {
        if (o == 'w') watch = atof(optarg);
        else if (o == 'k') key = optarg;
        else if (o == 'u') unsigned_name = optarg;
        else if (o == 'h') heard = optarg;
        else if (o == 's') said = optarg;
        else if (o == 'l' && sscanf(optarg, "%d:%lf:%lf:%lf:%63[^\n]", &lm.id, &lm.x, &lm.y, &lm.yaw, lm_text) == 5)
            landmark = true;
        else return 2;
    }
    lcm_t *lcm = lcm_create(NULL);
    if (!lcm)
        return 2;
    char err[256];
    if (key && !(auth = marie_auth_load(key, err, sizeof err))) {
        fprintf(stderr, "face_probe: %s\n", err);
        return 2;
    }
    if (unsigned_name) {
        marie_goal_request_t r = { .utime = marie_wall_us(), .sender = "stranger", .seq = marie_wall_us(),
                                   .goal = { .utime = marie_wall_us(), .id = 4242, .name = (char *)unsigned_name,
                                             .pose = { 1, 1, 0 } } };
        uint8_t none[1] = { 0 }, forged[MARIE_AUTH_MAC_LEN];
        r.mac = none;
        marie_goal_request_t_publish(lcm, "GOAL_REQUEST", &r);
        memset(forged, 0x5a, sizeof forged);
        r.seq++;
        r.mac = forged;
        r.mac_len = MARIE_AUTH_MAC_LEN;
        marie_goal_request_t_publish(lcm, "GOAL_REQUEST", &r);
    }
    if (heard) {
        marie_speech_t m = { .utime = marie_wall_us(), .start_utime = marie_wall_us() - 1000000, .source_id = 1,
                             .text = (char *)heard, .confidence = 0.9f };
        marie_speech_t_publish(lcm, "SPEECH", &m);
    }
    if (said) {
        marie_robot_speech_t m = { .utime = marie_wall_us(), .id = 1, .text = (char *)said,
                                   .state = MARIE_ROBOT_SPEECH_T_STATE_REQUEST };
        marie_robot_speech_t_publish(lcm, "SAY", &m);
    }
    marie_goal_request_t_subscribe(lcm, "GOAL_REQUEST", on_request, NULL);
    marie_goal_t_subscribe(lcm, "GOAL", on_goal, NULL);
    marie_event_t_subscribe(lcm, "MARIE_EVENT", on_event, NULL);
    int64_t end = marie_mono_us() + (int64_t)(watch * 1e6), next = 0;
    lm.message = lm_text;
    while (marie_mono_us() < end) {
        if (landmark && marie_mono_us() >= next) {
            marie_landmarks_t m = { .utime = marie_wall_us(), .frame = "map", .count = 1, .landmarks = &lm };
            marie_landmarks_t_publish(lcm, "LANDMARKS", &m);
            next = marie_mono_us() + 200000;
        }
        lcm_handle_timeout(lcm, 50);
    }
    marie_auth_destroy(auth);
    lcm_destroy(lcm);
    return 0;
}
