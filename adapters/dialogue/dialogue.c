/* dialogue: the rules of marie-dialogue (see dialogue.h). */
#include "adapters/dialogue/dialogue.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/log.h"

static char *trim(char *s)
{
    while (*s == ' ')
        s++;
    size_t n = strlen(s);
    while (n && s[n - 1] == ' ')
        s[--n] = 0;
    return s;
}

static int parse_place(char *item, dialogue_place_t *p, char *why, size_t whylen)
{
    char *eq = strchr(item, '=');
    if (!eq)
        return marie_fail_why(why, whylen, "place '%.40s': expected name=x,y,theta", item);
    *eq = 0;
    char *name = trim(item);
    if (!*name || strlen(name) >= sizeof(p->name))
        return marie_fail_why(why, whylen, "place name empty or longer than %zu", sizeof(p->name) - 1);
    for (char *c = name; *c; c++)
        if (!(islower((unsigned char)*c) || isdigit((unsigned char)*c) || *c == ' '))
            return marie_fail_why(why, whylen, "place name '%.40s': lower case letters, digits and spaces only", name);
    double v[3];
    char *s = eq + 1;
    for (int k = 0; k < 3; k++) {
        char *end;
        errno = 0;
        v[k] = strtod(s, &end);
        if (end == s || errno || !isfinite(v[k]) || fabs(v[k]) > 1e5)
            return marie_fail_why(why, whylen, "place '%.40s': expected x,y,theta numbers", name);
        s = end;
        while (*s == ' ')
            s++;
        if (k < 2 && *s++ != ',')
            return marie_fail_why(why, whylen, "place '%.40s': expected x,y,theta", name);
    }
    if (*s)
        return marie_fail_why(why, whylen, "place '%.40s': text after theta", name);
    snprintf(p->name, sizeof(p->name), "%s", name);
    p->x = v[0];
    p->y = v[1];
    p->theta = v[2];
    return 0;
}

int dialogue_places_parse(const char *text, dialogue_place_t *out, int max, int *n, char *why, size_t whylen)
{
    *n = 0;
    if (!text)
        return 0;
    if (strlen(text) > 8192)
        return marie_fail_why(why, whylen, "places longer than 8192 characters");
    char *copy = strdup(text);
    if (!copy)
        return -1;
    int rc = 0;
    char *save = NULL;
    for (char *item = strtok_r(copy, ";", &save); item && !rc; item = strtok_r(NULL, ";", &save)) {
        if (!*trim(item))
            continue;
        if (*n == max)
            rc = marie_fail_why(why, whylen, "more than %d places", max);
        else if (!(rc = parse_place(item, &out[*n], why, whylen)))
            (*n)++;
    }
    free(copy);
    return rc;
}

void dialogue_init(dialogue_t *d, const dialogue_place_t *places, int n, const char *robot_name)
{
    memset(d, 0, sizeof(*d));
    if (n > DIALOGUE_MAX_PLACES)
        n = DIALOGUE_MAX_PLACES;
    memcpy(d->places, places, sizeof(*places) * (size_t)n);
    d->nplaces = n;
    snprintf(d->robot_name, sizeof(d->robot_name), "%s", robot_name ? robot_name : "marie");
    d->partner = -1;
}

static const dialogue_place_t *find_place(const dialogue_t *d, const char *name)
{
    for (int i = 0; i < d->nplaces; i++)
        if (!strcmp(d->places[i].name, name))
            return &d->places[i];
    return NULL;
}

static bool starts(const char *s, const char *prefix)
{
    return !strncmp(s, prefix, strlen(prefix));
}

static void go_to(dialogue_t *d, const char *where, dialogue_reply_t *r)
{
    /* "go to the kitchen" names the place "kitchen"; "go home" names "home". */
    if (starts(where, "the "))
        where += 4;
    const dialogue_place_t *p = find_place(d, where);
    if (!p) {
        snprintf(r->say, sizeof(r->say), "I do not know where %s is.", where);
        return;
    }
    r->actions |= DIALOGUE_GOAL;
    r->place = *p;
    d->going = true;
    snprintf(d->going_to, sizeof(d->going_to), "%s", p->name);
    snprintf(r->say, sizeof(r->say), "Going to %s.", p->name);
}

void dialogue_hear(dialogue_t *d, const char *text, int source_id, bool has_azimuth, double azimuth,
                   dialogue_reply_t *r)
{
    memset(r, 0, sizeof(*r));
    d->heard++;
    d->partner = source_id;
    r->azimuth = azimuth;
    /* Whoever speaks to the robot is turned toward when the array knows where they are. */
    if (has_azimuth)
        r->actions |= DIALOGUE_FACE;
    bool known = true;
    if (starts(text, "go to "))
        go_to(d, text + 6, r);
    else if (!strcmp(text, "go home"))
        go_to(d, "home", r);
    else if (!strcmp(text, "stop") || !strcmp(text, "wait here") || !strcmp(text, "cancel the mission")) {
        r->actions |= DIALOGUE_STOP;
        d->going = false;
        snprintf(r->say, sizeof(r->say), "Stopping.");
    } else if (!strcmp(text, "where are you going")) {
        if (d->going)
            snprintf(r->say, sizeof(r->say), "I am going to %s.", d->going_to);
        else
            snprintf(r->say, sizeof(r->say), "I am not going anywhere.");
    } else if (!strcmp(text, "what is your name"))
        snprintf(r->say, sizeof(r->say), "My name is %s.", d->robot_name);
    else if (!strcmp(text, "hello robot"))
        snprintf(r->say, sizeof(r->say), "Hello.");
    else if (!strcmp(text, "goodbye"))
        snprintf(r->say, sizeof(r->say), "Goodbye.");
    else if (!strcmp(text, "face me") || !strcmp(text, "come here") || !strcmp(text, "follow me"))
        snprintf(r->say, sizeof(r->say), has_azimuth ? "Yes?" : "I cannot tell where you are.");
    else {
        known = false;
        snprintf(r->say, sizeof(r->say), "Sorry, I did not understand.");
    }
    d->understood += known;
}
