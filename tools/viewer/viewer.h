/* viewer: what marie-viewer-server's two files share: the ports, the server's state, sending
 * to the pages, and the log player (viewer_log.c). Private to tools/viewer. */
#ifndef TOOLS_VIEWER_H
#define TOOLS_VIEWER_H

#include <limits.h>
#include <stdbool.h>
#include <stdint.h>

#include "core/auth.h"
#include "tools/webcommon/pinguard.h"
#include "core/component.h"
#include "map/livemap.h"
#include "tools/viewer/viewer_params.h"
#include "tools/webcommon/vjson.h"
#include "tools/webcommon/webserve.h"

/* Inputs: one per thing the page shows; the channel is the port's binding. */
enum {
    P_MAP, P_POSE, P_TRUTH, P_PARTICLES, P_LASER, P_PATH, P_GOAL, P_ARB, P_EVENT, P_HB,
    P_AM_STATUS, P_AM_REPLY, P_TAGS, P_LANDMARKS, P_MAP_UPDATE, P_NIN,
};

extern const marie_port_spec_t viewer_ports[];
/* The type each input must carry; anything else on its channel is bad input. */
extern const marie_type_t *const viewer_port_type[P_NIN];

/* Per-channel decimation and the latest message kept for live snapshots. */
static inline const viewer_params_t *viewer_params(const marie_component_t *c) { return marie_component_params(c); }

typedef struct {
    int64_t last_sent_mono;
    char *latest;               /* JSON of the newest message (live mode) */
} chan_state_t;

#define RING 32
#define MAXCOMP 64

typedef struct {
    int64_t t;
    uint32_t chan;              /* index in log_chans */
    uint32_t len;
    uint64_t off;               /* payload offset in the file */
} rec_t;

typedef struct {
    char *name;
    int port;                   /* P_* or -1 */
    const marie_type_t *type;   /* of the first payload */
    int64_t count;
    uint32_t *idx;              /* indices into recs, ascending */
    size_t n, cap;
} log_chan_t;

typedef struct viewer {
    marie_component_t *c;
    webserve_t *web;
    bool live;
    char www[PATH_MAX];

    chan_state_t chans[P_NIN];
    int64_t min_gap_us[P_NIN];
    uint64_t map_hash;          /* of the last map sent */
    livemap_t live_map;         /* live: the last MAP with the MAP_UPDATE rectangles since */
    uint8_t *map_raw;           /* live_map encoded again, as a MAP message */
    size_t map_raw_cap;
    /* live snapshots */
    char *arb_ring[RING];
    int arb_next;
    char *ev_ring[RING];
    int ev_next;
    char *comp_name[MAXCOMP], *comp_json[MAXCOMP];
    int ncomp;
    char *goal_json[MAXCOMP];
    int goal_id[MAXCOMP], ngoal;
    float traj[2][2048][3];     /* est/truth trail: t (s), x, y */
    int traj_n[2], traj_next[2];
    int64_t traj_last[2], live_t0;

    /* log mode */
    uint8_t *file;
    size_t file_len;
    rec_t *recs;
    size_t nrecs, recs_cap;
    log_chan_t *lchans;
    size_t nlchans;
    int64_t t0, t1, last_t;
    int64_t corrupt, bad_payloads;
    marie_buf_t corrupt_list;
    int ncorrupt_listed;
    char *summary;
    size_t summary_len;
    bool playing;
    double picked_speed;        /* playback speed chosen on the page; 0: the speed parameter's */
    size_t cursor;              /* next record to play */
    int64_t play_t;             /* log time at anchor_mono */
    int64_t anchor_mono;
    int64_t last_player_msg;

    /* map from a file (map param) */
    char *map_json;

    /* stats */
    int64_t msgs_in, last_rx_mono;

    /* controls */
    marie_auth_t *auth;
    pinguard_t *pins;           /* the controls' PIN (with auth) */
    char pin[80];
    char sender[300];
    int64_t last_seq;
    int goals_sent;

    marie_buf_t jb;                /* scratch */
    bool init_failed;
} viewer_t;

/* The log's playback speed: the one chosen on the page, else the speed parameter. */
static inline double viewer_speed(const viewer_t *v)
{
    return v->picked_speed > 0 ? v->picked_speed : viewer_params(v->c)->speed;
}

/* Sending to page `id` (every page when id < 0). */
void viewer_send(viewer_t *v, int id, const char *data, size_t len, bool droppable);
void viewer_send_json(viewer_t *v, int id, marie_buf_t *b, bool droppable);
void viewer_notice(viewer_t *v, int id, const char *level, const char *text);
/* Messages: which input a channel is, its page frame, the rate limits. */
int viewer_port_of_channel(viewer_t *v, const char *ch);
/* A payload of input pi is its port's type, well formed and finite (bad live ones counted). */
bool viewer_payload_ok(viewer_t *v, int pi, const char *ch, const void *data, size_t len);
/* The page frame of a checked payload into b; false when it cannot be written. */
bool viewer_encode_msg(viewer_t *v, marie_buf_t *b, int pi, const char *ch, int64_t utime, const void *data, size_t len);
bool viewer_decimated(int pi);
bool viewer_pass_rate(viewer_t *v, int pi, int64_t now, const void *raw, size_t len);

/* Log mode (viewer_log.c): index a log, the player's state, a snapshot at the play time,
 * seeking, and the player's timer. */
int viewer_log_load(viewer_t *v, const char *path);
void viewer_log_send_player(viewer_t *v, int id);
void viewer_log_snapshot(viewer_t *v, int id);
void viewer_log_seek(viewer_t *v, int64_t t);
void viewer_log_tick(marie_loop_t *loop, marie_timer_t *tm, int64_t overruns, void *user);

#endif
