/* marie-face: the page for people near the robot (a touch screen): what it is doing
 * and why, the places it can go, what it heard and said, a stop request, a light per host.
 * Requests from the page
 * become orders and goal requests signed here, with the key this server holds. */
#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/auth.h"
#include "core/clear.h"
#include "core/component.h"
#include "proto/am_proto.h"
#include "tools/face/face_params.h"
#include "tools/webcommon/vjson.h"
#include "tools/webcommon/webpin.h"
#include "tools/webcommon/webserve.h"

#define MAX_PLACES 24
#define MAX_HOSTS 16
#define MAX_TALK 4

static const face_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }

typedef struct {
    char name[48];
    double x, y, theta;
} place_t;

typedef struct {
    marie_component_t *c;
    webserve_t *web;
    marie_auth_t *auth;
    char sender[300];
    int64_t last_seq;
    pinguard_t *pins;           /* the PIN every request must carry */
    char pin[80];
    place_t places[MAX_PLACES];
    int nplaces;
    /* the present, for pages that connect later */
    char *arb, *goal, *mission, *hosts[MAX_HOSTS], *events[8], *talk[MAX_TALK];
    char host_name[MAX_HOSTS][64];
    int nhosts, next_event, next_talk;
    int requests;
} face_t;

static const marie_port_spec_t ports[] = {
    { "arbitration", &marie_type_arbitration_t, MARIE_IN, MARIE_PUSH, "ARBITRATION" },
    { "goal", &marie_type_goal_t, MARIE_IN, MARIE_PUSH, "GOAL" },
    { "mission_state", &marie_type_mission_state_t, MARIE_IN, MARIE_PUSH, "MISSION_STATE" },
    { "event", &marie_type_event_t, MARIE_IN, MARIE_PUSH, MARIE_CH_EVENT },
    { "am_status", &marie_type_am_status_t, MARIE_IN, MARIE_PUSH, MARIE_CH_AM_STATUS },
    { "heard", &marie_type_speech_t, MARIE_IN, MARIE_PUSH, "SPEECH" },
    { "said", &marie_type_robot_speech_t, MARIE_IN, MARIE_PUSH, "SAY" },
    { "request", &marie_type_goal_request_t, MARIE_OUT, MARIE_PUSH, "GOAL_REQUEST" },
    { "order", &marie_type_am_order_t, MARIE_OUT, MARIE_PUSH, MARIE_CH_AM_ORDER },
    { NULL },
};

static const marie_param_spec_t params[] = FACE_PARAMS;

static void keep(char **slot, const marie_buf_t *b)
{
    free(*slot);
    *slot = b->failed ? NULL : strdup(b->data);
}

static void share(face_t *f, char **slot, marie_buf_t *b)
{
    if (slot)
        keep(slot, b);
    webserve_send_json(f->web, -1, b, false);
    marie_buf_free(b);
}

/* The decision record: who drives and why (the winning behaviour's reason). */
static void on_arb(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    face_t *f = marie_component_user(c);
    const marie_arbitration_t *m = msg;
    const char *why = "";
    for (int i = 0; i < m->nvotes; i++)
        if (strcmp(m->votes[i].name, m->winner) == 0)
            why = m->votes[i].reason;
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_puts(&b, "{\"type\":\"arb\",\"winner\":");
    vj_str(&b, m->winner);
    marie_buf_puts(&b, ",\"why\":");
    vj_str(&b, why);
    marie_buf_puts(&b, ",\"v\":");
    vj_num(&b, m->v, 2);
    marie_buf_puts(&b, "}");
    share(f, &f->arb, &b);
}

static void on_goal(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    face_t *f = marie_component_user(c);
    const marie_goal_t *m = msg;
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_puts(&b, "{\"type\":\"goal\",\"name\":");
    vj_str(&b, m->name);
    marie_buf_printf(&b, ",\"id\":%d,\"x\":", m->id);
    vj_num(&b, m->pose.x, 2);
    marie_buf_puts(&b, ",\"y\":");
    vj_num(&b, m->pose.y, 2);
    marie_buf_puts(&b, "}");
    share(f, &f->goal, &b);
}

static void on_mission(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    face_t *f = marie_component_user(c);
    const marie_mission_state_t *m = msg;
    int done = 0;
    for (int i = 0; i < m->ngoals; i++)
        done += m->goal_states[i] >= MARIE_MISSION_STATE_T_STATE_REACHED;
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_printf(&b, "{\"type\":\"mission\",\"current\":%d,\"goals\":%d,\"done\":%d}", m->current, m->ngoals, done);
    share(f, &f->mission, &b);
}

/* What people care about: the mission's progress, signs read, requests, stops. */
static void on_event(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    face_t *f = marie_component_user(c);
    const marie_event_t *m = msg;
    static const char *const shown[] = { "goal_started", "goal_reached", "goal_missed", "mission_done", "sign",
                                         "sign_read", "request_accepted", "request_refused", "estop", "collision", NULL };
    bool show = false;
    for (int i = 0; shown[i]; i++)
        show |= strcmp(m->kind, shown[i]) == 0;
    if (!show)
        return;
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_puts(&b, "{\"type\":\"event\",\"kind\":");
    vj_str(&b, m->kind);
    marie_buf_puts(&b, ",\"src\":");
    vj_str(&b, m->source);
    marie_buf_puts(&b, ",\"text\":");
    vj_str(&b, m->text);
    marie_buf_puts(&b, "}");
    share(f, &f->events[f->next_event++ % 8], &b);
}

/* The conversation: what marie-asr recognized and what marie-dialogue asked marie-tts to say. */
static void talk(face_t *f, const char *who, const char *text)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_printf(&b, "{\"type\":\"talk\",\"who\":\"%s\",\"text\":", who);
    vj_str(&b, text);
    marie_buf_puts(&b, "}");
    share(f, &f->talk[f->next_talk++ % MAX_TALK], &b);
}

static void on_heard(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    talk(marie_component_user(c), "heard", ((const marie_speech_t *)msg)->text);
}

/* The requests on SAY, not marie-tts's progress on ROBOT_SPEECH, which repeats the words. */
static void on_said(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    talk(marie_component_user(c), "said", ((const marie_robot_speech_t *)msg)->text);
}

/* A light per host: green when every component it runs is running, else amber/red. */
static void on_am(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    face_t *f = marie_component_user(c);
    const marie_am_status_t *m = msg;
    int bad = 0, failed = 0;
    for (int i = 0; i < m->ncomponents; i++) {
        const char *st = m->components[i].state;
        bad += strcmp(st, "running") != 0 && strcmp(st, "stopped") != 0;
        failed += strcmp(st, "failed") == 0 || strcmp(st, "hung") == 0 || strcmp(st, "backoff") == 0;
    }
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_puts(&b, "{\"type\":\"host\",\"host\":");
    vj_str(&b, m->host);
    marie_buf_printf(&b, ",\"n\":%d,\"light\":\"%s\",\"t\":%lld}", m->ncomponents, failed ? "red" : bad ? "amber" : "green",
              (long long)marie_wall_us());
    int k = 0;
    while (k < f->nhosts && strcmp(f->host_name[k], m->host) != 0)
        k++;
    if (k == f->nhosts && f->nhosts < MAX_HOSTS)
        snprintf(f->host_name[f->nhosts++], sizeof f->host_name[0], "%s", m->host);
    share(f, k < f->nhosts ? &f->hosts[k] : NULL, &b);
}

static void send_hello(face_t *f, int id)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_printf(&b, "{\"type\":\"hello\",\"controls\":%s,\"places\":[", f->auth ? "true" : "false");
    for (int i = 0; i < f->nplaces; i++) {
        marie_buf_puts(&b, i ? "," : "");
        vj_str(&b, f->places[i].name);
    }
    marie_buf_puts(&b, "]}");
    webserve_send_json(f->web, id, &b, false);
    marie_buf_free(&b);
    char *all[] = { f->arb, f->goal, f->mission };
    for (int i = 0; i < 3; i++)
        if (all[i])
            webserve_send(f->web, id, all[i], strlen(all[i]), false);
    for (int i = 0; i < f->nhosts; i++)
        if (f->hosts[i])
            webserve_send(f->web, id, f->hosts[i], strlen(f->hosts[i]), false);
    for (int i = 0; i < 8; i++) {
        char *e = f->events[(f->next_event + i) % 8];
        if (e)
            webserve_send(f->web, id, e, strlen(e), false);
    }
    for (int i = 0; i < MAX_TALK; i++) {
        char *t = f->talk[(f->next_talk + i) % MAX_TALK];
        if (t)
            webserve_send(f->web, id, t, strlen(t), false);
    }
}

static int64_t next_seq(face_t *f)
{
    int64_t seq = marie_auth_next_seq(NULL);
    f->last_seq = seq > f->last_seq ? seq : f->last_seq + 1;
    return f->last_seq;
}

static int send_place(face_t *f, const place_t *pl)
{
    marie_goal_request_t r = {
        .utime = marie_wall_us(), .sender = f->sender, .seq = next_seq(f),
        .goal = { .utime = marie_wall_us(), .id = 800000 + ++f->requests, .name = (char *)pl->name,
                  .pose = { pl->x, pl->y, pl->theta }, .tolerance = 0, .priority = 0 },
    };
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    if (marie_auth_sign_goal_request(f->auth, &r, mac) < 0)
        return -1;
    return marie_port_publish(marie_port(f->c, "request"), &r);
}

static int send_order(face_t *f, int op)
{
    char *targets[1] = { (char *)params_of(f->c)->stop_target };
    marie_am_order_t o = {
        .utime = marie_wall_us(), .sender = f->sender, .seq = next_seq(f), .host = "*", .op = (int8_t)op,
        .ntargets = 1, .targets = targets, .arg = "", .system_path = "", .system_text = "",
    };
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    if (marie_auth_sign_order(f->auth, &o, mac) < 0)
        return -1;
    return marie_port_publish(marie_port(f->c, "order"), &o);
}

static void on_cmd(void *user, int client, const char *addr, bool hello, const char *text, size_t len)
{
    face_t *f = user;
    if (hello) {
        send_hello(f, client);
        return;
    }
    vj_cmd_t cmd;
    const char *op = NULL;
    if (vj_cmd_parse(&cmd, text, len) < 0 || !(op = vj_cmd_str(&cmd, "op"))) {
        marie_component_bad_input(f->c, "bad_command", "page command not understood (%zu bytes)", len);
        webserve_notice(f->web, client, "error", "command not understood");
        return;
    }
    if (!f->auth) {
        webserve_notice(f->web, client, "error", "requests are disabled (no key)");
        return;
    }
    if (!webpin_allow(f->pins, f->c, f->web, client, addr, vj_cmd_str(&cmd, "pin")))
        return;
    double k = -1;
    char msg[128];
    int rc = -1;
    if (strcmp(op, "go") == 0 && vj_cmd_num(&cmd, "place", &k) && k >= 0 && k < f->nplaces) {
        rc = send_place(f, &f->places[(int)k]);
        snprintf(msg, sizeof msg, "going to %s", f->places[(int)k].name);
    } else if (strcmp(op, "stop") == 0 || strcmp(op, "resume") == 0) {
        bool stop = strcmp(op, "stop") == 0;
        rc = send_order(f, stop ? MARIE_AM_ORDER_T_OP_PAUSE : MARIE_AM_ORDER_T_OP_RESUME);
        snprintf(msg, sizeof msg, stop ? "stop asked" : "moving on");
    } else {
        webserve_notice(f->web, client, "error", "unknown request");
        return;
    }
    marie_info("face: %s%s", msg, rc < 0 ? " (not sent)" : "");
    webserve_notice(f->web, -1, rc < 0 ? "error" : "info", rc < 0 ? "the request could not be sent" : msg);
}

static int parse_places(face_t *f)
{
    const marie_node_t *seq = params_of(f->c)->places;
    marie_errors_t errs = { 0 };
    static const char *const keys[] = { "name", "x", "y", "theta", NULL };
    f->nplaces = 0;
    for (size_t i = 0; seq && seq->kind == MARIE_NODE_SEQ && i < seq->n && i < MAX_PLACES; i++) {
        const marie_node_t *n = seq->items[i];
        place_t *p = &f->places[f->nplaces];
        const char *name = NULL;
        if (n->kind != MARIE_NODE_MAP || !marie_node_get(n, "name") || !marie_node_get(n, "x") || !marie_node_get(n, "y")) {
            marie_errors_add(&errs, n->file, n->line, n->col, "places: each needs name, x and y");
            continue;
        }
        marie_node_check_keys(n, keys, "place", &errs);
        marie_node_str(marie_node_get(n, "name"), &name, &errs);
        snprintf(p->name, sizeof p->name, "%s", name ? name : "");
        marie_node_double(marie_node_get(n, "x"), &p->x, &errs);
        marie_node_double(marie_node_get(n, "y"), &p->y, &errs);
        p->theta = 0;
        if (marie_node_get(n, "theta"))
            marie_node_double(marie_node_get(n, "theta"), &p->theta, &errs);
        f->nplaces++;
    }
    if (seq && (seq->kind != MARIE_NODE_SEQ || seq->n > MAX_PLACES))
        marie_errors_add(&errs, seq->file, seq->line, seq->col, "places: expected a list of at most %d", MAX_PLACES);
    if (errs.n) {
        marie_errors_print(&errs, stderr);
        marie_component_fail_reason(f->c, "%s", errs.msgs[0]);
        marie_errors_clear(&errs);
        return -1;
    }
    return 0;
}

static int find_www(face_t *f, char *out, size_t len)
{
    const char *p = params_of(f->c)->www;
    char exe[4096] = "";
    if (p && *p) {
        snprintf(out, len, "%s", p);
        return 0;
    }
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    exe[n > 0 ? n : 0] = 0;
    char *slash = strrchr(exe, '/');
    if (slash)
        *slash = 0;
    const char *rel[] = { "/../share/marie/face", "/../../tools/face/www", "/../../../tools/face/www" };
    for (size_t i = 0; i < sizeof rel / sizeof rel[0]; i++) {
        snprintf(out, len, "%s%s", exe, rel[i]);
        char cand[4200];
        snprintf(cand, sizeof cand, "%s/index.html", out);
        if (access(cand, R_OK) == 0)
            return 0;
    }
    snprintf(out, len, "tools/face/www");
    return access("tools/face/www/index.html", R_OK) == 0 ? 0 : -1;
}

static int init(marie_component_t *c)
{
    face_t *f = marie_component_user(c);
    if (f->web)
        return 0;
    f->c = c;
    if (parse_places(f) < 0)
        return -1;
    const char *key = params_of(c)->key_file;
    if (key[0]) {
        char err[256], who[256];
        if (!(f->auth = marie_auth_load(key, err, sizeof err))) {
            marie_component_fail_reason(c, "key file: %s", err);
            return -1;
        }
        marie_am_sender(who, sizeof who);
        snprintf(f->sender, sizeof f->sender, "%s/face", who);
    }
    const face_params_t *q = params_of(c);
    webpin_params_t wp = { q->pin, q->pin_digits, q->pin_max_failures, q->pin_max_failures_all, q->pin_lockout_s };
    if (!f->pins && !(f->pins = webpin_open(c, &wp, f->pin, sizeof f->pin)))
        return -1;
    static char www[4096];
    if (find_www(f, www, sizeof www) < 0) {
        marie_component_fail_reason(c, "cannot find the page (tools/face/www): set the www parameter");
        return -1;
    }
    static const webserve_file_t files[] = {
        { "/", "index.html", "text/html; charset=utf-8" },
        { "/index.html", "index.html", "text/html; charset=utf-8" },
        { "/face.js", "face.js", "text/javascript; charset=utf-8" },
        { "/face.css", "face.css", "text/css; charset=utf-8" },
    };
    webserve_cfg_t wc = { .www = www, .files = files, .nfiles = 4, .name = "face", .on_cmd = on_cmd, .user = f,
                          .comp = c };
    char why[256];
    if (!(f->web = webserve_start(marie_component_loop(c), q->bind, (int)q->http_port, &wc, why, sizeof why))) {
        marie_component_fail_reason(c, "%s", why);
        return -1;
    }
    marie_port_on_message(marie_port(c, "arbitration"), on_arb);
    marie_port_on_message(marie_port(c, "goal"), on_goal);
    marie_port_on_message(marie_port(c, "mission_state"), on_mission);
    marie_port_on_message(marie_port(c, "event"), on_event);
    marie_port_on_message(marie_port(c, "am_status"), on_am);
    marie_port_on_message(marie_port(c, "heard"), on_heard);
    marie_port_on_message(marie_port(c, "said"), on_said);
    char url[256];
    webserve_url(f->web, params_of(c)->url_file, url, sizeof url);
    printf("marie-face: %s, PIN %s%s\n", url, f->pin, f->auth ? "" : " (no key: requests refused)");
    fflush(stdout);
    return 0;
}

static void quit(marie_component_t *c)
{
    face_t *f = marie_component_user(c);
    MARIE_CLEAR(f->web, webserve_stop);
    MARIE_CLEAR(f->auth, marie_auth_destroy);
    MARIE_CLEAR(f->pins, pinguard_destroy);
    free(f->arb);
    free(f->goal);
    free(f->mission);
    for (int i = 0; i < f->nhosts; i++)
        free(f->hosts[i]);
    for (int i = 0; i < 8; i++)
        free(f->events[i]);
    for (int i = 0; i < MAX_TALK; i++)
        free(f->talk[i]);
}

static const marie_component_def_t def = {
    .kind = "face", .ports = ports, .params = params, .params_size = sizeof(face_params_t),
    .on_init = init, .on_quit = quit,
};

int main(int argc, char **argv)
{
    static face_t f;
    signal(SIGPIPE, SIG_IGN);
    return marie_main(&def, argc, argv, &f);
}
