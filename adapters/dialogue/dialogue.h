/* dialogue: the rules of marie-dialogue: a recognized command (and who said it, from where)
 * becomes actions: a navigation goal, a stop, turning toward the speaker, and an answer to say.
 * Pure: text in, actions out. */
#ifndef MARIE_DIALOGUE_H
#define MARIE_DIALOGUE_H
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define DIALOGUE_MAX_PLACES 32

typedef struct {
    char name[48];
    double x, y, theta;
} dialogue_place_t;

/* "room a=3,2,0; room b=8,5,1.57" (name=x,y,theta; names are lower case words). 0, or -1 with
 * errno EINVAL and a reason in why. */
int dialogue_places_parse(const char *text, dialogue_place_t *out, int max, int *n, char *why, size_t whylen);

typedef enum {
    DIALOGUE_NONE = 0,
    DIALOGUE_GOAL = 1,          /* go to `place` */
    DIALOGUE_STOP = 2,
    DIALOGUE_FACE = 4,          /* turn toward the speaker (azimuth) */
} dialogue_action_t;

typedef struct {
    unsigned actions;           /* DIALOGUE_* bits */
    dialogue_place_t place;
    double azimuth;             /* rad, robot frame: where the speaker is */
    char say[256];              /* the answer; "" for none */
} dialogue_reply_t;

typedef struct {
    dialogue_place_t places[DIALOGUE_MAX_PLACES];
    int nplaces;
    char robot_name[48];
    bool going;
    char going_to[48];
    int partner;                /* source id of the last speaker, -1 */
    long heard, understood;
} dialogue_t;

void dialogue_init(dialogue_t *d, const dialogue_place_t *places, int n, const char *robot_name);

/* One utterance; has_azimuth says whether the speaker's direction is known. */
void dialogue_hear(dialogue_t *d, const char *text, int source_id, bool has_azimuth, double azimuth,
                   dialogue_reply_t *out);


#ifdef __cplusplus
}
#endif
#endif
