/* marie-viewer-server: follows the bus or plays an LCM log, and streams what the robot saw and
 * decided to a web page over WebSocket (tools/webcommon), with signed manager orders as controls. */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/clear.h"
#include "core/component.h"
#include "core/typeinfo.h"
#include "proto/am_proto.h"
#include "core/auth.h"
#include "core/lcmlog.h"
#include "tools/webcommon/vjson.h"
#include "tools/webcommon/webpin.h"
#include "tools/webcommon/webserve.h"
#include "tools/viewer/viewer.h"

const marie_port_spec_t viewer_ports[] = {
    [P_MAP] = {"map", NULL, MARIE_IN, MARIE_PUSH, "MAP"},
    [P_POSE] = {"pose", NULL, MARIE_IN, MARIE_PUSH, "POSE"},
    [P_TRUTH] = {"truth", NULL, MARIE_IN, MARIE_PUSH, "SIM_TRUTH"},
    [P_PARTICLES] = {"particles", NULL, MARIE_IN, MARIE_PUSH, "PARTICLES"},
    [P_LASER] = {"laser", NULL, MARIE_IN, MARIE_PUSH, "LASER"},
    [P_PATH] = {"path", NULL, MARIE_IN, MARIE_PUSH, "PATH"},
    [P_GOAL] = {"goal", NULL, MARIE_IN, MARIE_PUSH, "GOAL"},
    [P_ARB] = {"arbitration", NULL, MARIE_IN, MARIE_PUSH, "ARBITRATION"},
    [P_EVENT] = {"event", NULL, MARIE_IN, MARIE_PUSH, MARIE_CH_EVENT},
    [P_HB] = {"heartbeat", NULL, MARIE_IN, MARIE_PUSH, MARIE_CH_HEARTBEAT},
    [P_AM_STATUS] = {"am_status", NULL, MARIE_IN, MARIE_PUSH, MARIE_CH_AM_STATUS},
    [P_AM_REPLY] = {"am_reply", NULL, MARIE_IN, MARIE_PUSH, MARIE_CH_AM_REPLY},
    [P_TAGS] = {"tags", NULL, MARIE_IN, MARIE_PUSH, "TAG_DETECTIONS"},
    [P_LANDMARKS] = {"landmarks", NULL, MARIE_IN, MARIE_PUSH, "LANDMARKS"},
    [P_MAP_UPDATE] = {"map_update", NULL, MARIE_IN, MARIE_PUSH, "MAP_UPDATE"},
    [P_NIN] = {"request", &marie_type_goal_request_t, MARIE_OUT, MARIE_PUSH, "GOAL_REQUEST"},
    {"order", &marie_type_am_order_t, MARIE_OUT, MARIE_PUSH, MARIE_CH_AM_ORDER},
    {0},
};

const marie_type_t *const viewer_port_type[P_NIN] = {
    [P_MAP] = &marie_type_occupancy_grid_t, [P_POSE] = &marie_type_pose_cov_t,
    [P_TRUTH] = &marie_type_pose_cov_t, [P_PARTICLES] = &marie_type_particle_cloud_t,
    [P_LASER] = &marie_type_laser_scan_t, [P_PATH] = &marie_type_path_t, [P_GOAL] = &marie_type_goal_t,
    [P_ARB] = &marie_type_arbitration_t, [P_EVENT] = &marie_type_event_t, [P_HB] = &marie_type_heartbeat_t,
    [P_AM_STATUS] = &marie_type_am_status_t, [P_AM_REPLY] = &marie_type_am_reply_t,
    [P_TAGS] = &marie_type_tag_detections_t, [P_LANDMARKS] = &marie_type_landmarks_t,
    [P_MAP_UPDATE] = &marie_type_occupancy_grid_update_t,
};

static const marie_param_spec_t params[] = VIEWER_PARAMS;

void viewer_send(viewer_t *v, int id, const char *data, size_t len, bool droppable)
{
    webserve_send(v->web, id, data, len, droppable);
}

void viewer_send_json(viewer_t *v, int id, marie_buf_t *b, bool droppable)
{
    webserve_send_json(v->web, id, b, droppable);
}

void viewer_notice(viewer_t *v, int id, const char *level, const char *text)
{
    webserve_notice(v->web, id, level, text);
}

/* ---------------------------------------------------------------- messages */

int viewer_port_of_channel(viewer_t *v, const char *ch)
{
    for (int i = 0; i < P_NIN; i++)
        if (strcmp(marie_port_channel(marie_port(v->c, viewer_ports[i].name)), ch) == 0)
            return i;
    return -1;
}

/* Check a payload of input port `pi` and write its message frame into b. Returns false on
 * bad input (counted). */
bool viewer_payload_ok(viewer_t *v, int pi, const char *ch, const void *data, size_t len)
{
    const marie_typeinfo_t *ti = marie_typeinfo_by_fingerprint(viewer_port_type[pi]->hash());
    if (marie_typeinfo_check_flags(ti, data, len, MARIE_CHECK_FINITE) == 0)
        return true;
    bool nonfinite = errno == EDOM;
    /* A log's wrong types were counted when it was indexed: count live payloads only. */
    if (v->live) {
        bool fp = marie_payload_fingerprint(data, len) == ti->fingerprint;
        v->bad_payloads++;
        marie_component_bad_input(v->c, !fp ? "bad_fingerprint" : nonfinite ? "bad_nonfinite" : "bad_payload",
                                  "channel %s: %zu bytes: not a well-formed, finite %s", ch, len,
                                  viewer_port_type[pi]->name);
    }
    return false;
}

bool viewer_encode_msg(viewer_t *v, marie_buf_t *b, int pi, const char *ch, int64_t utime, const void *data, size_t len)
{
    marie_buf_reset(b);
    marie_buf_puts(b, "{\"type\":\"msg\",\"ch\":");
    vj_str(b, ch);
    marie_buf_puts(b, ",\"t\":");
    vj_int(b, utime);
    bool ok = vj_message(b, data, len, pi == P_TRUTH ? VJ_ROLE_TRUTH : pi == P_POSE ? VJ_ROLE_POSE : VJ_ROLE_OTHER) == 0;
    marie_buf_puts(b, "}");
    return ok && !b->failed;
}

bool viewer_decimated(int pi)
{
    return pi == P_LASER || pi == P_POSE || pi == P_TRUTH || pi == P_PARTICLES || pi == P_MAP;
}

/* Rate limit per input on the wall clock: whatever the log speed, the page gets at most
 * laser_hz scans a second. A map (hundreds of KB) goes again only when its cells or
 * geometry changed, or after map_period_s as a refresh. */
bool viewer_pass_rate(viewer_t *v, int pi, int64_t now, const void *raw, size_t len)
{
    if (!viewer_decimated(pi))
        return true;
    chan_state_t *cs = &v->chans[pi];
    if (pi == P_MAP) {
        uint64_t h = 1469598103934665603ULL;        /* FNV-1a, past fingerprint and utime */
        for (size_t i = 16; i < len; i++)
            h = (h ^ ((const uint8_t *)raw)[i]) * 1099511628211ULL;
        if (cs->last_sent_mono && h == v->map_hash && now - cs->last_sent_mono < v->min_gap_us[pi])
            return false;
        v->map_hash = h;
        cs->last_sent_mono = now;
        return true;
    }
    if (cs->last_sent_mono && now - cs->last_sent_mono < v->min_gap_us[pi])
        return false;
    cs->last_sent_mono = now;
    return true;
}

static void set_str(char **slot, const char *s, size_t n)
{
    char *d = malloc(n + 1);
    if (!d)
        return;
    memcpy(d, s, n);
    d[n] = 0;
    free(*slot);
    *slot = d;
}

/* A member of the JSON just written, the first of that name: the message's own field when no
 * earlier field or envelope member has it ("component" of a heartbeat, "host" of a manager's
 * status, "id" of a goal, "x" and "y" of a pose). */
static void json_field(const char *json, const char *k, char *out, size_t cap)
{
    char pat[32];
    snprintf(pat, sizeof pat, "\"%s\":", k);
    const char *p = strstr(json, pat);
    out[0] = 0;
    if (!p)
        return;
    p += strlen(pat);
    size_t n = 0;
    if (*p == '"') {
        p++;
        while (*p && *p != '"' && n + 1 < cap) {
            if (*p == '\\' && p[1])
                p++;
            out[n++] = *p++;
        }
    } else {
        while (*p && *p != ',' && *p != '}' && n + 1 < cap)
            out[n++] = *p++;
    }
    out[n] = 0;
}

/* Live mode: remember what a new page needs to draw the present at once. */
static void live_remember(viewer_t *v, int pi, const marie_buf_t *b, int64_t utime)
{
    if (pi == P_ARB) {
        set_str(&v->arb_ring[v->arb_next], b->data, b->len);
        v->arb_next = (v->arb_next + 1) % RING;
    } else if (pi == P_EVENT) {
        set_str(&v->ev_ring[v->ev_next], b->data, b->len);
        v->ev_next = (v->ev_next + 1) % RING;
    } else if (pi == P_HB || pi == P_AM_STATUS) {
        /* one slot per component, and one per manager (host) */
        char name[128];
        if (pi == P_HB)
            json_field(b->data, "component", name, sizeof name);
        else {
            name[0] = '@';
            json_field(b->data, "host", name + 1, sizeof name - 1);
        }
        int i;
        for (i = 0; i < v->ncomp; i++)
            if (strcmp(v->comp_name[i], name) == 0)
                break;
        if (i == v->ncomp) {
            if (v->ncomp == MAXCOMP)
                return;
            v->comp_name[v->ncomp++] = strdup(name);
        }
        set_str(&v->comp_json[i], b->data, b->len);
    } else if (pi == P_GOAL) {
        char id[32];
        json_field(b->data, "id", id, sizeof id);
        int gid = atoi(id), i;
        for (i = 0; i < v->ngoal; i++)
            if (v->goal_id[i] == gid)
                break;
        if (i == v->ngoal) {
            if (v->ngoal == MAXCOMP)
                return;
            v->goal_id[v->ngoal++] = gid;
        }
        set_str(&v->goal_json[i], b->data, b->len);
    } else if (pi != P_AM_REPLY) {
        set_str(&v->chans[pi].latest, b->data, b->len);
    }
    if (pi == P_POSE || pi == P_TRUTH) {
        /* Trails at 5 Hz for pages that connect later. */
        int k = pi == P_TRUTH;
        if (!v->live_t0)
            v->live_t0 = utime;
        if (utime - v->traj_last[k] >= 200000 || utime < v->traj_last[k]) {
            char x[32], y[32];
            json_field(b->data, "x", x, sizeof x);
            json_field(b->data, "y", y, sizeof y);
            float *p = v->traj[k][v->traj_next[k]];
            p[0] = (float)((utime - v->live_t0) / 1e6);
            p[1] = (float)atof(x);
            p[2] = (float)atof(y);
            v->traj_next[k] = (v->traj_next[k] + 1) % 2048;
            if (v->traj_n[k] < 2048)
                v->traj_n[k]++;
            v->traj_last[k] = utime;
        }
    }
}

/* A live map is held as a reader holds it (map/livemap.h): a whole map is kept, an update is
 * patched in and the map it makes encoded again as a whole one in *raw. 0, or -1 when there is
 * nothing to draw (an update for a map not held, counted; or one that contradicts itself). */
static int live_map(viewer_t *v, int pi, const void **raw, size_t *raw_len)
{
    bool taken = false;
    if (pi == P_MAP) {
        marie_occupancy_grid_t g;
        if (marie_decode_input(&marie_type_occupancy_grid_t, *raw, *raw_len, &g, NULL) != 0)
            return -1;
        taken = livemap_take_full(&v->live_map, v->c, &g);
        marie_type_occupancy_grid_t.decode_cleanup(&g);
        return taken ? 0 : -1;
    }
    marie_occupancy_grid_update_t u;
    if (marie_decode_input(&marie_type_occupancy_grid_update_t, *raw, *raw_len, &u, NULL) != 0)
        return -1;
    taken = livemap_take_update(&v->live_map, v->c, &u);
    marie_type_occupancy_grid_update_t.decode_cleanup(&u);
    if (!taken)
        return -1;
    int len = marie_type_occupancy_grid_t.encoded_size(&v->live_map.map);
    if (len <= 0)
        return -1;
    if ((size_t)len > v->map_raw_cap) {
        uint8_t *nb = realloc(v->map_raw, (size_t)len);
        if (!nb)
            return -1;
        v->map_raw = nb;
        v->map_raw_cap = (size_t)len;
    }
    if (marie_type_occupancy_grid_t.encode(v->map_raw, 0, len, &v->live_map.map) != len)
        return -1;
    *raw = v->map_raw;
    *raw_len = (size_t)len;
    return 0;
}

static void on_live(marie_component_t *c, marie_port_t *p, const void *msg, const marie_msg_info_t *info)
{
    viewer_t *v = marie_component_user(c);
    int pi = -1;
    for (int i = 0; i < P_NIN; i++)
        if (strcmp(marie_port_name(p), viewer_ports[i].name) == 0)
            pi = i;
    if (pi < 0)
        return;
    int64_t now = marie_mono_us();
    v->msgs_in++;
    /* Checked before the rate limit, so every bad message is counted and none can take the
     * place of a good one in the page's share. */
    if (!viewer_payload_ok(v, pi, info->channel, info->raw, info->raw_len))
        return;
    const void *raw = info->raw;
    size_t raw_len = info->raw_len;
    const char *ch = info->channel;
    if ((pi == P_MAP || pi == P_MAP_UPDATE) && live_map(v, pi, &raw, &raw_len) != 0)
        return;
    if (pi == P_MAP_UPDATE) {
        pi = P_MAP;     /* the page gets the map with the update in it */
        ch = marie_port_channel(marie_port(c, viewer_ports[P_MAP].name));
    }
    /* The snapshot cache wants every message; the page only the rate-limited ones. */
    bool send = viewer_pass_rate(v, pi, now, raw, raw_len);
    if (!send && (pi != P_POSE && pi != P_TRUTH)) {
        v->last_rx_mono = now;      /* only data ports are viewer_decimated */
        return;
    }
    if (!viewer_encode_msg(v, &v->jb, pi, ch, info->recv_utime, raw, raw_len))
        return;
    /* Heartbeats and manager reports say the components live, not that data flows: the
     * page's "no data" banner follows the data ports only. */
    if (pi != P_HB && pi != P_AM_STATUS && pi != P_AM_REPLY)
        v->last_rx_mono = now;
    live_remember(v, pi, &v->jb, info->recv_utime);
    if (send)
        viewer_send_json(v, -1, &v->jb, viewer_decimated(pi));
}

/* ---------------------------------------------------------------- commands */

static void send_hello(viewer_t *v, int id)
{
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_printf(&b, "{\"type\":\"hello\",\"mode\":\"%s\",\"controls\":%s,\"component\":", v->live ? "live" : "log",
              v->auth ? "true" : "false");
    vj_str(&b, marie_component_name(v->c));
    marie_buf_puts(&b, ",\"channels\":{");
    for (int i = 0; i < P_NIN; i++) {
        marie_buf_puts(&b, i ? "," : "");
        vj_str(&b, viewer_ports[i].name);
        marie_buf_puts(&b, ":");
        vj_str(&b, marie_port_channel(marie_port(v->c, viewer_ports[i].name)));
    }
    marie_buf_puts(&b, "}}");
    viewer_send_json(v, id, &b, false);
    marie_buf_free(&b);
    if (v->map_json)
        viewer_send(v, id, v->map_json, strlen(v->map_json), false);
    if (!v->live) {
        if (v->summary)
            viewer_send(v, id, v->summary, v->summary_len, false);
        viewer_log_snapshot(v, id);
        viewer_log_send_player(v, id);
        return;
    }
    /* live: the present, from the caches */
    char head[96];
    int n = snprintf(head, sizeof head, "{\"type\":\"snap\",\"t\":%lld}", (long long)marie_wall_us());
    viewer_send(v, id, head, (size_t)n, false);
    marie_buf_reset(&b);
    for (int k = 0; k < 2; k++) {
        marie_buf_printf(&b, "%s\"%s\":[", k ? "," : "{\"type\":\"trail\",", k ? "truth" : "est");
        for (int j = 0; j < v->traj_n[k]; j++) {
            int idx = (v->traj_next[k] - v->traj_n[k] + j + 2048) % 2048;
            marie_buf_printf(&b, "%s[%.1f,%.3f,%.3f]", j ? "," : "", v->traj[k][idx][0], v->traj[k][idx][1],
                      v->traj[k][idx][2]);
        }
        marie_buf_puts(&b, "]");
    }
    marie_buf_puts(&b, "}");
    viewer_send_json(v, id, &b, false);
    marie_buf_free(&b);
    for (int i = 0; i < P_NIN; i++)
        if (v->chans[i].latest)
            viewer_send(v, id, v->chans[i].latest, strlen(v->chans[i].latest), false);
    for (int i = 0; i < v->ncomp; i++)
        if (v->comp_json[i])
            viewer_send(v, id, v->comp_json[i], strlen(v->comp_json[i]), false);
    for (int i = 0; i < v->ngoal; i++)
        if (v->goal_json[i])
            viewer_send(v, id, v->goal_json[i], strlen(v->goal_json[i]), false);
    for (int i = 0; i < RING; i++) {
        char *e = v->ev_ring[(v->ev_next + i) % RING];
        if (e)
            viewer_send(v, id, e, strlen(e), false);
    }
    for (int i = 0; i < RING; i++) {
        char *a = v->arb_ring[(v->arb_next + i) % RING];
        if (a)
            viewer_send(v, id, a, strlen(a), false);
    }
    n = snprintf(head, sizeof head, "{\"type\":\"snapend\",\"t\":%lld}", (long long)marie_wall_us());
    viewer_send(v, id, head, (size_t)n, false);
}

/* The page's controls (the viewer's table and the system graph): signed manager orders. */
static void do_order(viewer_t *v, int id, const char *cmd, const char *target, const char *host)
{
    int op = marie_am_op_parse(cmd);
    bool allowed = op == MARIE_AM_ORDER_T_OP_PAUSE || op == MARIE_AM_ORDER_T_OP_RESUME ||
                   op == MARIE_AM_ORDER_T_OP_RESTART || op == MARIE_AM_ORDER_T_OP_STOP ||
                   op == MARIE_AM_ORDER_T_OP_START || op == MARIE_AM_ORDER_T_OP_MOVE;
    if (!allowed || !target || !*target) {
        viewer_notice(v, id, "error", "unknown order");
        return;
    }
    if (op == MARIE_AM_ORDER_T_OP_MOVE && (!host || !*host)) {
        viewer_notice(v, id, "error", "move needs a host");
        return;
    }
    int64_t seq = marie_auth_next_seq(NULL);
    if (seq <= v->last_seq)
        seq = v->last_seq + 1;
    v->last_seq = seq;
    char *targets[1] = {(char *)target};
    marie_am_order_t o = {
        .utime = marie_wall_us(), .sender = v->sender, .seq = seq, .host = "*", .op = (int8_t)op,
        .ntargets = 1, .targets = targets, .arg = (char *)(op == MARIE_AM_ORDER_T_OP_MOVE ? host : ""),
        .system_path = "", .system_text = "",
    };
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    char msg[300];
    if (marie_auth_sign_order(v->auth, &o, mac) < 0 || marie_port_publish(marie_port(v->c, "order"), &o) < 0) {
        viewer_notice(v, id, "error", "cannot send the order");
        return;
    }
    snprintf(msg, sizeof msg, "order sent: %s %s%s%s (seq %lld)", cmd, target, op == MARIE_AM_ORDER_T_OP_MOVE ? " to " : "",
             op == MARIE_AM_ORDER_T_OP_MOVE ? host : "", (long long)seq);
    marie_info("viewer: %s", msg);
    viewer_notice(v, -1, "info", msg);
}

/* A goal from the page: a request signed with the key, which the mission obeys only if authentic. */
static void do_goal(viewer_t *v, int id, double x, double y, double th)
{
    int64_t seq = marie_auth_next_seq(NULL);
    v->last_seq = seq > v->last_seq ? seq : v->last_seq + 1;
    marie_goal_request_t r = {
        .utime = marie_wall_us(), .sender = v->sender, .seq = v->last_seq,
        .goal = {.utime = marie_wall_us(), .id = 900000 + ++v->goals_sent, .name = "viewer", .pose = {x, y, th},
                 .tolerance = viewer_params(v->c)->goal_tolerance, .priority = 0},
    };
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    if (marie_auth_sign_goal_request(v->auth, &r, mac) < 0 || marie_port_publish(marie_port(v->c, "request"), &r) < 0) {
        viewer_notice(v, id, "error", "cannot send the goal request");
        return;
    }
    char msg[200];
    snprintf(msg, sizeof msg, "goal %d requested on %s: (%.2f, %.2f, %.2f)", r.goal.id,
             marie_port_channel(marie_port(v->c, "request")), x, y, th);
    marie_info("viewer: %s", msg);
    viewer_notice(v, -1, "info", msg);
}

static void handle_cmd(void *user, int client, const char *addr, bool hello, const char *text, size_t len)
{
    viewer_t *v = user;
    if (hello) {
        send_hello(v, client);
        return;
    }
    vj_cmd_t cmd;
    if (vj_cmd_parse(&cmd, text, len) < 0 || !vj_cmd_str(&cmd, "op")) {
        marie_component_bad_input(v->c, "bad_command", "page command not understood (%zu bytes)", len);
        viewer_notice(v, client, "error", "command not understood");
        return;
    }
    const char *op = vj_cmd_str(&cmd, "op");
    double x = 0, y = 0, th = 0;
    if (strcmp(op, "ping") == 0) {
        char s[64];
        double t = 0;
        vj_cmd_num(&cmd, "t", &t);
        int n = snprintf(s, sizeof s, "{\"type\":\"pong\",\"t\":%.17g}", t);
        viewer_send(v, client, s, (size_t)n, false);
    } else if (strcmp(op, "goal") == 0 || strcmp(op, "order") == 0) {
        if (!v->auth) {
            viewer_notice(v, client, "error", "controls are disabled: start the viewer with --key-file");
        } else if (!webpin_allow(v->pins, v->c, v->web, client, addr, vj_cmd_str(&cmd, "pin"))) {
            return;         /* the page was told why */
        } else if (strcmp(op, "goal") == 0) {
            if (!vj_cmd_num(&cmd, "x", &x) || !vj_cmd_num(&cmd, "y", &y))
                viewer_notice(v, client, "error", "goal needs x and y");
            else {
                vj_cmd_num(&cmd, "th", &th);
                do_goal(v, client, x, y, th);
            }
        } else {
            do_order(v, client, vj_cmd_str(&cmd, "cmd") ? vj_cmd_str(&cmd, "cmd") : "",
                     vj_cmd_str(&cmd, "target"), vj_cmd_str(&cmd, "host"));
        }
    } else if (v->live) {
        viewer_notice(v, client, "error", "playback commands need a log");
    } else if (strcmp(op, "play") == 0) {
        if (v->play_t >= v->t1)
            viewer_log_seek(v, v->t0);
        v->playing = true;
        v->anchor_mono = marie_mono_us();
        viewer_log_send_player(v, -1);
    } else if (strcmp(op, "pause") == 0) {
        v->playing = false;
        /* decimation may have skipped the newest scan: show the exact state at the pause */
        viewer_log_snapshot(v, -1);
        viewer_log_send_player(v, -1);
    } else if (strcmp(op, "seek") == 0 && vj_cmd_num(&cmd, "t", &x)) {
        viewer_log_seek(v, (int64_t)x);
    } else if (strcmp(op, "speed") == 0 && vj_cmd_num(&cmd, "v", &x) && x > 0 && x <= 1000) {
        v->picked_speed = x;
        viewer_log_send_player(v, -1);
    } else {
        viewer_notice(v, client, "error", "unknown command");
    }
}

/* ---------------------------------------------------------------- map file */

/* A map.yaml given as a parameter, as a map frame, via the same encoder as the map port. */
#include "map/occmap.h"

static int load_map_file(viewer_t *v, const char *path)
{
    marie_errors_t errs = {0};
    occmap_t *m = occmap_load(path, &errs);
    if (!m) {
        marie_errors_print(&errs, stderr);
        marie_errors_clear(&errs);
        marie_component_fail_reason(v->c, "cannot load map %s", path);
        return -1;
    }
    marie_occupancy_grid_t g = {
        .utime = 0, .resolution = (float)m->resolution, .width = m->width, .height = m->height,
        .origin = {m->origin_x, m->origin_y, 0}, .ncells = m->width * m->height, .cells = m->cells,
    };
    int len = marie_type_occupancy_grid_t.encoded_size(&g);
    uint8_t *raw = len > 0 ? malloc((size_t)len) : NULL;
    int n = raw ? marie_type_occupancy_grid_t.encode(raw, 0, len, &g) : -1;
    occmap_destroy(m);
    marie_buf_t b;
    marie_buf_init(&b, 0);
    marie_buf_puts(&b, "{\"type\":\"msg\",\"ch\":");
    vj_str(&b, path);
    marie_buf_puts(&b, ",\"t\":0");
    int rc = n > 0 ? vj_message(&b, raw, (size_t)n, VJ_ROLE_OTHER) : -1;
    marie_buf_puts(&b, "}");
    free(raw);
    if (rc < 0 || b.failed) {
        marie_buf_free(&b);
        marie_component_fail_reason(v->c, "cannot encode map %s", path);
        return -1;
    }
    v->map_json = b.data;
    return 0;
}

/* ---------------------------------------------------------------- lifecycle */

static int find_www(viewer_t *v)
{
    const char *p = viewer_params(v->c)->www;
    char exe[PATH_MAX], cand[PATH_MAX + 64];
    if (p && *p) {
        snprintf(cand, sizeof cand, "%s/index.html", p);
        if (access(cand, R_OK) != 0) {
            marie_component_fail_reason(v->c, "www %s: no index.html there", p);
            return -1;
        }
        snprintf(v->www, sizeof v->www, "%s", p);
        return 0;
    }
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    exe[n > 0 ? n : 0] = 0;
    char *slash = strrchr(exe, '/');
    if (slash)
        *slash = 0;
    const char *rel[] = {"/../share/marie/viewer", "/../../tools/viewer/www", "/../../../tools/viewer/www"};
    for (size_t i = 0; i < sizeof rel / sizeof rel[0]; i++) {
        snprintf(cand, sizeof cand, "%s%s/index.html", exe, rel[i]);
        if (access(cand, R_OK) == 0) {
            snprintf(v->www, sizeof v->www, "%s%s", exe, rel[i]);
            return 0;
        }
    }
    if (access("tools/viewer/www/index.html", R_OK) == 0) {
        snprintf(v->www, sizeof v->www, "tools/viewer/www");
        return 0;
    }
    marie_component_fail_reason(v->c, "cannot find the page (tools/viewer/www): set the www parameter");
    return -1;
}

static int init_viewer(marie_component_t *c)
{
    viewer_t *v = marie_component_user(c);
    if (v->web)
        return 0;                       /* re-init after a stop: already serving */
    v->c = c;
    double speed = viewer_params(c)->speed;
    if (!(speed > 0 && speed <= 1000)) {
        marie_component_fail_reason(c, "speed must be in (0, 1000]");
        return -1;
    }
    double hz[P_NIN] = {0};
    hz[P_LASER] = viewer_params(c)->laser_hz;
    hz[P_POSE] = hz[P_TRUTH] = viewer_params(c)->pose_hz;
    hz[P_PARTICLES] = viewer_params(c)->particles_hz;
    double map_s = viewer_params(c)->map_period_s;
    for (int i = 0; i < P_NIN; i++)
        v->min_gap_us[i] = hz[i] > 0 ? (int64_t)(1e6 / hz[i]) : 0;
    v->min_gap_us[P_MAP] = map_s > 0 ? (int64_t)(map_s * 1e6) : 0;
    if (find_www(v) < 0)
        return -1;
    const char *key = viewer_params(c)->key_file;
    if (key && *key) {
        char err[256];
        if (!(v->auth = marie_auth_load(key, err, sizeof err))) {
            marie_component_fail_reason(c, "key file: %s", err);
            return -1;
        }
        char who[256];
        marie_am_sender(who, sizeof who);
        snprintf(v->sender, sizeof v->sender, "%s/viewer", who);
        const viewer_params_t *q = viewer_params(c);
        webpin_params_t wp = { q->pin, q->pin_digits, q->pin_max_failures, q->pin_max_failures_all, q->pin_lockout_s };
        if (!v->pins && !(v->pins = webpin_open(c, &wp, v->pin, sizeof v->pin)))
            return -1;
    }
    const char *map = viewer_params(c)->map;
    if (map && *map && load_map_file(v, map) < 0)
        return -1;
    const char *log = viewer_params(c)->log;
    v->live = !(log && *log);
    if (!v->live) {
        if (viewer_log_load(v, log) < 0)
            return -1;
        v->play_t = v->t0;
        v->playing = viewer_params(c)->autoplay && v->nrecs > 0;
        v->anchor_mono = marie_mono_us();
    } else {
        for (int i = 0; i < P_NIN; i++)
            if (marie_port_on_message(marie_port(c, viewer_ports[i].name), on_live) < 0) {
                marie_component_fail_reason(c, "cannot subscribe to %s", viewer_ports[i].name);
                return -1;
            }
    }
    if (v->live == false && marie_port_on_message(marie_port(c, "am_reply"), on_live) < 0)
        return -1;
    if (!marie_loop_add_wall_timer(marie_component_loop(c), 20000, viewer_log_tick, v)) {
        marie_component_fail_reason(c, "cannot set up the loop: %s", strerror(errno));
        return -1;
    }
    static const webserve_file_t files[] = {
        {"/", "index.html", "text/html; charset=utf-8"},
        {"/index.html", "index.html", "text/html; charset=utf-8"},
        {"/viewer.js", "viewer.js", "text/javascript; charset=utf-8"},
        {"/viewer.css", "viewer.css", "text/css; charset=utf-8"},
        {"/graph.html", "graph.html", "text/html; charset=utf-8"},
        {"/graph.js", "graph.js", "text/javascript; charset=utf-8"},
        {"/pin.js", "pin.js", "text/javascript; charset=utf-8"},
    };
    webserve_cfg_t wc = {
        .www = v->www, .files = files, .nfiles = sizeof files / sizeof files[0], .name = "viewer",
        .on_cmd = handle_cmd, .user = v, .comp = c,
    };
    char why[256];
    const viewer_params_t *q = viewer_params(c);
    if (!(v->web = webserve_start(marie_component_loop(c), q->bind, (int)q->http_port, &wc, why, sizeof why))) {
        marie_component_fail_reason(c, "%s", why);
        return -1;
    }
    char url[256], pin[sizeof v->pin + 8] = "";
    webserve_url(v->web, viewer_params(c)->url_file, url, sizeof url);
    if (v->pins)
        snprintf(pin, sizeof pin, "#pin=%s", v->pin);  /* the page takes it from there: not sent */
    if (v->live)
        printf("marie-view: following the bus at %s%s\n", url, pin);
    else
        printf("marie-view: playing %s at %s%s\n", log, url, pin);
    fflush(stdout);
    return 0;
}

/* Under a manager a failed init waits for orders; run by hand (`marie view`), the user wants
 * the reason and an exit status at once. */
static int init(marie_component_t *c)
{
    viewer_t *v = marie_component_user(c);
    int rc = init_viewer(c);
    if (rc < 0 && !marie_component_cfg(c)) {
        v->init_failed = true;
        marie_loop_quit(marie_component_loop(c));
    }
    return rc;
}

static void quit(marie_component_t *c)
{
    viewer_t *v = marie_component_user(c);
    MARIE_CLEAR(v->web, webserve_stop);
    MARIE_CLEAR(v->pins, pinguard_destroy);
    for (int i = 0; i < P_NIN; i++)
        free(v->chans[i].latest);
    livemap_free(&v->live_map);
    MARIE_CLEAR(v->map_raw, free);
    v->map_raw_cap = 0;
    for (int i = 0; i < RING; i++) {
        free(v->arb_ring[i]);
        free(v->ev_ring[i]);
    }
    for (int i = 0; i < v->ncomp; i++) {
        free(v->comp_name[i]);
        free(v->comp_json[i]);
    }
    for (int i = 0; i < v->ngoal; i++)
        free(v->goal_json[i]);
    for (size_t i = 0; i < v->nlchans; i++) {
        free(v->lchans[i].name);
        free(v->lchans[i].idx);
    }
    free(v->lchans);
    free(v->recs);
    free(v->summary);
    free(v->map_json);
    marie_buf_free(&v->corrupt_list);
    marie_buf_free(&v->jb);
    if (v->file)
        munmap(v->file, v->file_len);
    marie_auth_destroy(v->auth);
}

static const marie_component_def_t def = {
    .kind = "viewer", .ports = viewer_ports, .params = params, .params_size = sizeof(viewer_params_t),
    .on_init = init, .on_quit = quit,
};

int main(int argc, char **argv)
{
    static viewer_t v;
    signal(SIGPIPE, SIG_IGN);
    int rc = marie_main(&def, argc, argv, &v);
    return rc == 0 && v.init_failed ? 1 : rc;
}
