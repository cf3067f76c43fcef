/* marie-mission: runs a list of goals with priorities and deadlines, publishes the current goal,
 * reports progress as events, and keeps its progress in the SharedMap so a restart continues. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "adapters/mission/mission.h"
#include "adapters/mission/mission_params.h"
#include "adapters/mission/mission_request.h"
#include "adapters/mission/mission_signs.h"
#include "ca/sharedmap_client.h"
#include "core/auth.h"
#include "core/clear.h"
#include "core/component.h"
#include "core/typeinfo.h"

static const mission_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }

typedef struct {
    marie_component_t *c;
    mission_t m;
    bool have_pose;
    double pose[3];
    int64_t pose_stamp;
    sharedmap_client_t *sm;
    char key[160];
    int restore_tries;
    bool restored, dirty;
    bool restoring;             /* a read of the saved progress is on its way */
    bool saving, save_again;    /* a write is on its way; another is due after it */
    int64_t last_goal_pub;
    int32_t failing_goal;       /* goal the planner reports no path for, -1: none */
    int64_t failing_since;
    mission_signs_t signs;      /* goals found by reading signs */
    marie_auth_t *auth;         /* checks goals people ask for (NULL: all refused) */
    marie_replay_t *replay;
} mis_t;

static void on_event(void *user, const char *kind, const mission_goal_t *g, const char *text)
{
    mis_t *s = user;
    marie_component_event(s->c, MARIE_EVENT_T_SEV_INFO, kind, "%s", text);
    marie_info("%s", text);
    s->dirty = true;
}

static void fill_state(mis_t *s, marie_mission_state_t *st, int32_t *ids, int8_t *states)
{
    for (int i = 0; i < s->m.n; i++) {
        ids[i] = s->m.goals[i].id;
        states[i] = (int8_t)s->m.state[i];
    }
    *st = (marie_mission_state_t){ .utime = marie_component_now(s->c), .mission = (char *)marie_component_name(s->c),
                                   .start_utime = s->m.start_utime, .current = s->m.current, .ngoals = s->m.n,
                                   .goal_ids = ids, .goal_states = states };
}

static void save(mis_t *s);

static void on_saved(sharedmap_client_t *cl, const sharedmap_result_t *r, void *user)
{
    mis_t *s = user;
    s->saving = false;
    if (r->status != 0) {
        marie_component_count(s->c, "state_save_failures", 1);
        marie_warn_ratelimited(10, "mission state not saved in the SharedMap (%s): %s", s->key, strerror(r->status));
    }
    if (s->save_again) {
        s->save_again = false;
        save(s);
    }
}

/* The SharedMap is asked without waiting (the loop keeps turning); one write at a time, the
 * newest state last. */
static void save(mis_t *s)
{
    if (!s->sm)
        return;
    if (s->saving) {
        s->save_again = true;
        return;
    }
    int32_t ids[MISSION_MAX_GOALS];
    int8_t states[MISSION_MAX_GOALS];
    marie_mission_state_t st;
    fill_state(s, &st, ids, states);
    int timeout_ms = (int)params_of(s->c)->sharedmap_timeout_ms;
    if (sharedmap_client_set_async(s->sm, s->key, &marie_type_mission_state_t, &st, timeout_ms, on_saved, s) < 0) {
        int err = errno;
        marie_component_count(s->c, "state_save_failures", 1);
        marie_warn_ratelimited(10, "mission state not saved in the SharedMap (%s): %s", s->key, strerror(err));
        return;
    }
    s->saving = true;
}

static void resume(mis_t *s, const marie_mission_state_t *st)
{
    int64_t now = marie_component_now(s->c);
    double max_age_s = params_of(s->c)->resume_max_age_s;
    if (st->utime > now || st->start_utime > now) {
        marie_component_event(s->c, MARIE_EVENT_T_SEV_WARN, "mission_state_ignored",
                              "saved progress is from the future (another run?): starting afresh");
    } else if (max_age_s > 0 && (now - st->utime) / 1e6 > max_age_s) {
        marie_component_event(s->c, MARIE_EVENT_T_SEV_WARN, "mission_state_ignored",
                              "saved progress is %.0f s old (resume_max_age_s %.0f): starting afresh",
                              (now - st->utime) / 1e6, max_age_s);
    } else if (mission_restore(&s->m, st->start_utime, st->current, st->goal_ids, st->goal_states, st->ngoals) == 0) {
        marie_component_event(s->c, MARIE_EVENT_T_SEV_INFO, "mission_resumed",
                              "resumed: %lld reached, %lld missed of %d, current goal index %d",
                              (long long)s->m.reached, (long long)s->m.missed, s->m.n, s->m.current);
        s->dirty = true;
    } else {
        marie_component_event(s->c, MARIE_EVENT_T_SEV_WARN, "mission_state_ignored",
                              "saved progress under %s belongs to another goal list", s->key);
    }
}

static void on_restored(sharedmap_client_t *cl, const sharedmap_result_t *r, void *user)
{
    mis_t *s = user;
    s->restoring = false;
    int err = r->status;
    if (err == ETIMEDOUT && ++s->restore_tries < 3)
        return;                 /* the SharedMap may be starting too: ask again next tick */
    s->restored = true;
    if (err == ENOENT) {
        marie_info("no saved progress under %s: starting the mission", s->key);
        return;
    }
    marie_mission_state_t st;
    memset(&st, 0, sizeof(st));
    if (err == 0 && marie_decode_checked(&marie_type_mission_state_t, r->data, r->len, &st) < 0)
        err = EBADMSG;
    if (err) {
        marie_component_count(s->c, "state_restore_failures", 1);
        marie_warn("cannot read saved progress %s: %s; starting the mission", s->key, strerror(err));
        return;
    }
    resume(s, &st);
    marie_type_mission_state_t.decode_cleanup(&st);
}

/* Returns true once restoring is settled (restored, nothing stored, or given up); until
 * then it asks the SharedMap, without waiting for the answer. */
static bool restore(mis_t *s)
{
    if (!s->sm || s->restored)
        return true;
    if (!s->restoring) {
        int rc = sharedmap_client_get_async(s->sm, s->key, (int)params_of(s->c)->sharedmap_timeout_ms, on_restored, s);
        s->restoring = rc == 0;
        if (rc < 0) {
            marie_warn("cannot ask for saved progress %s: %s; starting the mission", s->key, strerror(errno));
            s->restored = true;
        }
    }
    return s->restored;
}

static void publish_goal(mis_t *s)
{
    if (s->m.current < 0)
        return;
    const mission_goal_t *g = &s->m.goals[s->m.current];
    marie_goal_t msg = { .utime = marie_component_now(s->c), .id = g->id, .name = (char *)g->name,
                         .pose = { g->x, g->y, g->theta }, .tolerance = g->tolerance, .priority = g->priority,
                         .deadline_utime = mission_deadline(&s->m, s->m.current) };
    marie_port_publish(marie_port(s->c, "goal"), &msg);
    s->last_goal_pub = msg.utime;
}

static void tick(marie_component_t *c, int64_t overruns)
{
    mis_t *s = marie_component_user(c);
    if (s->sm)
        sharedmap_client_tick(s->sm);
    if (!restore(s))
        return;
    const mission_params_t *q = params_of(c);
    int64_t now = marie_component_now(c);
    bool fresh = s->have_pose && (q->stale_pose_s <= 0 || (now - s->pose_stamp) / 1e6 <= q->stale_pose_s);
    bool was_done = s->m.done;
    if (s->m.current >= 0 && q->unreachable_s > 0 && s->failing_goal == s->m.goals[s->m.current].id &&
        (now - s->failing_since) / 1e6 > q->unreachable_s) {
        mission_give_up(&s->m, "the planner finds no path", on_event, s);
        s->failing_goal = -1;
    }
    if (mission_signs_steer(&s->signs, &s->m, fresh ? s->pose : NULL, on_event, s))
        s->dirty = true;
    mission_update(&s->m, now, fresh ? s->pose : NULL, on_event, s);
    if (s->dirty) {
        s->dirty = false;
        save(s);
        publish_goal(s);
    } else if (q->republish_s > 0 && (now - s->last_goal_pub) / 1e6 >= q->republish_s) {
        publish_goal(s);
    }
    if (!was_done || s->dirty) {
        int32_t ids[MISSION_MAX_GOALS];
        int8_t states[MISSION_MAX_GOALS];
        marie_mission_state_t st;
        fill_state(s, &st, ids, states);
        marie_port_publish(marie_port(c, "state"), &st);
    }
}

static void on_pose(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    mis_t *s = marie_component_user(c);
    const marie_pose_cov_t *m = msg;
    if (!isfinite(m->pose.x) || !isfinite(m->pose.y)) {
        marie_component_bad_input(c, "bad_pose", "pose is not finite");
        return;
    }
    s->pose[0] = m->pose.x;
    s->pose[1] = m->pose.y;
    s->pose[2] = m->pose.theta;
    s->pose_stamp = marie_component_now(c);
    s->have_pose = true;
}

/* Signs the vision adapter read: goals waiting for one move in front of it. */
static void on_landmarks(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    mis_t *s = marie_component_user(c);
    const marie_landmarks_t *m = msg;
    for (int i = 0; i < m->count; i++) {
        const marie_landmark_t *l = &m->landmarks[i];
        if (l->message[0] && isfinite(l->x) && isfinite(l->y) && isfinite(l->yaw) &&
            mission_signs_read(&s->signs, &s->m, l->message, l->x, l->y, l->yaw, l->range, on_event, s))
            s->dirty = true;
    }
}

/* A goal a person asked for (the touch page): obeyed only when signed with the key, fresh. */
static void on_request(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    mis_t *s = marie_component_user(c);
    const marie_goal_request_t *r = msg;
    marie_auth_result_t ok = marie_auth_check_goal_request(s->auth, s->replay, r);
    if (ok != MARIE_AUTH_OK) {
        marie_component_count(c, "requests_refused", 1);
        marie_component_event(c, MARIE_EVENT_T_SEV_WARN, "request_refused", "goal request '%s' from %s refused: %s",
                              r->goal.name ? r->goal.name : "", r->sender ? r->sender : "?",
                              marie_auth_result_name(ok));
        return;
    }
    const marie_goal_t *g = &r->goal;
    mission_goal_t mg = { .id = g->id, .x = g->pose.x, .y = g->pose.y, .theta = g->pose.theta,
                          .tolerance = g->tolerance > 0 ? g->tolerance : params_of(c)->tolerance,
                          .priority = g->priority };
    snprintf(mg.name, sizeof mg.name, "%s", g->name ? g->name : "request");
    if (!isfinite(mg.x) || !isfinite(mg.y) || !isfinite(mg.theta) || mission_request_insert(&s->m, &mg) < 0) {
        marie_component_bad_input(c, "bad_request", "goal request '%s' not finite or no room for it", mg.name);
        return;
    }
    marie_component_count(c, "requests", 1);
    marie_component_event(c, MARIE_EVENT_T_SEV_INFO, "request_accepted", "goal '%s' (%.2f, %.2f) asked by %s", mg.name,
                          mg.x, mg.y, r->sender);
    s->dirty = true;
    tick(c, 0);         /* a person waits: the goal goes out now, not at the next tick */
}

/* The planner's verdict on the current goal: a goal it keeps failing is given up. */
static void on_path(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    mis_t *s = marie_component_user(c);
    const marie_path_t *m = msg;
    if (m->status == MARIE_PATH_T_STATUS_OK) {
        if (m->goal_id == s->failing_goal)
            s->failing_goal = -1;
    } else if (m->goal_id != s->failing_goal) {
        s->failing_goal = m->goal_id;
        s->failing_since = marie_component_now(c);
    }
}

static void quit(marie_component_t *c)
{
    mis_t *s = marie_component_user(c);
    MARIE_CLEAR(s->sm, sharedmap_client_destroy);
    MARIE_CLEAR(s->auth, marie_auth_destroy);
    MARIE_CLEAR(s->replay, marie_replay_destroy);
}

static int init(marie_component_t *c)
{
    quit(c);    /* init again after a failure starts from scratch */
    mis_t *s = marie_component_user(c);
    s->c = c;
    mission_init(&s->m);
    s->restored = s->dirty = s->restoring = s->saving = s->save_again = false;
    s->restore_tries = 0;
    s->have_pose = false;
    marie_errors_t errs = { 0 };
    int ngoals = mission_parse(&s->m, params_of(c)->goals, params_of(c)->tolerance, &errs);
    int nsigns = ngoals < 0 ? -1 : mission_signs_parse(&s->signs, &s->m, params_of(c)->signs,
                                                       params_of(c)->tolerance, &errs);
    if (ngoals < 0 || nsigns < 0 || ngoals + nsigns == 0) {
        marie_component_fail_reason(c, "goals: %s", errs.n ? errs.msgs[0] : "no goals");
        marie_errors_clear(&errs);
        return -1;
    }
    const char *key = params_of(c)->key_file;
    if (key[0]) {
        char err[256];
        s->auth = marie_auth_load(key, err, sizeof err);
        s->replay = s->auth ? marie_replay_create(NULL) : NULL;
        if (!s->replay) {
            marie_component_fail_reason(c, "key_file: %s", s->auth ? "out of memory" : err);
            return -1;
        }
    }
    s->failing_goal = -1;
    const char *skey = params_of(c)->state_key;
    if (skey[0])
        snprintf(s->key, sizeof(s->key), "%s", skey);
    else
        snprintf(s->key, sizeof(s->key), "mission/%s", marie_component_name(c));
    if (params_of(c)->sharedmap) {
        s->sm = sharedmap_client_create(marie_component_lcm(c), params_of(c)->sharedmap_channel,
                                        marie_component_name(c));
        if (!s->sm) {
            marie_component_fail_reason(c, "cannot create the SharedMap client: %s", strerror(errno));
            return -1;
        }
    }
    if (marie_port_on_message(marie_port(c, "pose"), on_pose) || marie_port_on_message(marie_port(c, "path"), on_path) ||
        marie_port_on_message(marie_port(c, "landmarks"), on_landmarks) ||
        marie_port_on_message(marie_port(c, "request"), on_request)) {
        marie_component_fail_reason(c, "cannot subscribe to the pose and path");
        return -1;
    }
    double hz = params_of(c)->rate_hz;
    if (!(hz > 0 && hz <= 100)) {
        marie_component_fail_reason(c, "rate_hz must be in (0, 100]");
        return -1;
    }
    if (!marie_component_every(c, hz, tick))
        return -1;
    return 0;
}

static const marie_port_spec_t ports[] = {
    { "pose", &marie_type_pose_cov_t, MARIE_IN, MARIE_PUSH, "POSE" },
    { "path", &marie_type_path_t, MARIE_IN, MARIE_PUSH, "PATH" },
    { "goal", &marie_type_goal_t, MARIE_OUT, MARIE_PUSH, "GOAL" },
    { "state", &marie_type_mission_state_t, MARIE_OUT, MARIE_PUSH, "MISSION_STATE" },
    { "landmarks", &marie_type_landmarks_t, MARIE_IN, MARIE_PUSH, "LANDMARKS" },
    { "request", &marie_type_goal_request_t, MARIE_IN, MARIE_PUSH, "GOAL_REQUEST" },
    { 0 },
};

static const marie_param_spec_t params[] = MISSION_PARAMS;

static const marie_component_def_t def = {
    .kind = "mission", .ports = ports, .params = params, .params_size = sizeof(mission_params_t), .on_init = init, .on_quit = quit,
};

int main(int argc, char **argv)
{
    mis_t s;
    memset(&s, 0, sizeof(s));
    return marie_main(&def, argc, argv, &s);
}
