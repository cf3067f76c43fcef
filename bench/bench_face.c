/* bench_face: the touch page's latency, as processes. A request on the page's WebSocket until
 * the signed request and the mission's goal are on the bus (marie-face, marie-mission); then,
 * with the navigation stack on marie-sim as tests/face/test_face_sim.sh runs it, until the
 * first motor command that moves the robot toward the requested place. */
#include <math.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <signal.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <civetweb.h>
#include <lcm/lcm.h>

#include "bench/bench.h"
#include "core/auth.h"
#include "core/loop.h"
#include "core/time.h"
#include "lcmtypes/marie_types.h"

#define ROUNDS 40               /* requests to the mission alone */
#define TAPS 5                  /* requests that drive the simulated robot */
#define TAP_LIMIT_US 30000000   /* one tap: the robot reaches the previous place, then moves */
#define MAX_PIDS 12
#define MAX_CYCLES 4096

/* The place a request asks for, and when each step of its way was seen on the bus. */
typedef struct {
    char want[32];
    double x, y;
    int64_t t0, req_at, goal_at, path_at, motor_at;
} request_t;

static request_t rq;
static marie_loop_t *loop;
static const char *bin = "build";
static pid_t pids[MAX_PIDS];
static int npids;

/* The simulated robot as the bus shows it. */
static double rx, ry, rth;
static bool moving = true;
static int reached = -1;        /* goals of the mission, when all are reached; else -1 */
static int64_t last_cmd, cycle[MAX_CYCLES];
static int ncycles;

static void row(const char *metric, double value, const char *unit)
{
    bench_row("face", metric, value, unit, NAN);
}

static void on_req(const lcm_recv_buf_t *rb, const char *ch, const marie_goal_request_t *m, void *u)
{
    if (rq.t0 && !rq.req_at && strcmp(m->goal.name, rq.want) == 0)
        rq.req_at = marie_mono_us();
}

static void on_goal(const lcm_recv_buf_t *rb, const char *ch, const marie_goal_t *m, void *u)
{
    if (rq.t0 && !rq.goal_at && strcmp(m->name, rq.want) == 0)
        rq.goal_at = marie_mono_us();
}

static void on_path(const lcm_recv_buf_t *rb, const char *ch, const marie_path_t *m, void *u)
{
    if (!rq.t0 || rq.path_at || m->status != MARIE_PATH_T_STATUS_OK || m->nposes < 1)
        return;
    const marie_pose2d_t *end = &m->poses[m->nposes - 1];
    if (hypot(end->x - rq.x, end->y - rq.y) < 0.05)
        rq.path_at = marie_mono_us();
}

static void on_pose(const lcm_recv_buf_t *rb, const char *ch, const marie_pose_cov_t *m, void *u)
{
    rx = m->pose.x;
    ry = m->pose.y;
    rth = m->pose.theta;
}

/* Toward the place: the command shortens the distance, or turns the robot to face it (either
 * way when it faces away). */
static bool toward(double v, double w)
{
    double err = remainder(atan2(rq.y - ry, rq.x - rx) - rth, 2 * M_PI);
    return v * cos(err) > 0.01 || (fabs(w) > 0.05 && (w * err > 0 || fabs(err) > 3.0));
}

static void on_motor(const lcm_recv_buf_t *rb, const char *ch, const marie_motor_command_t *m, void *u)
{
    int64_t now = marie_mono_us();
    if (last_cmd && ncycles < MAX_CYCLES)
        cycle[ncycles++] = now - last_cmd;
    last_cmd = now;
    moving = fabs(m->v) > 1e-3 || fabs(m->omega) > 1e-3;
    if (rq.t0 && !rq.motor_at && toward(m->v, m->omega))
        rq.motor_at = now;
}

static void on_mission(const lcm_recv_buf_t *rb, const char *ch, const marie_mission_state_t *m, void *u)
{
    int done = 0;
    for (int i = 0; i < m->ngoals; i++)
        done += m->goal_states[i] >= MARIE_MISSION_STATE_T_STATE_REACHED;
    reached = m->ngoals > 0 && done == m->ngoals ? m->ngoals : -1;
}

static int on_ws(struct mg_connection *c, int bits, char *data, size_t len, void *u)
{
    return 1;
}

/* A component as a process, its output dropped; argv ends with NULL. */
static void spawn(const char *prog, ...)
{
    char exe[256], *argv[32];
    int n = 0;
    va_list ap;
    snprintf(exe, sizeof exe, "%s/bin/%s", bin, prog);
    argv[n++] = exe;
    va_start(ap, prog);
    while (n < 31 && (argv[n] = va_arg(ap, char *)))
        n++;
    va_end(ap);
    argv[n] = NULL;
    pid_t pid = fork();
    if (pid == 0) {
        freopen("/dev/null", "w", stdout);
        freopen("/dev/null", "w", stderr);
        execv(exe, argv);
        _exit(127);
    }
    if (pid > 0 && npids < MAX_PIDS)
        pids[npids++] = pid;
}

static void stop_all(void)
{
    for (int i = 0; i < npids; i++)
        kill(pids[i], SIGTERM);
    for (int i = 0; i < npids; i++)
        waitpid(pids[i], NULL, 0);
    npids = 0;
}

/* civetweb's client writes a frame's header and its payload in two segments with Nagle on, so
 * the payload waits for the server's delayed ACK (40 ms); a browser sends a frame at once
 * (Chromium sets TCP_NODELAY). The client does not expose its socket: find it by its peer. */
static void nodelay_to(int port)
{
    for (int fd = 3; fd < 1024; fd++) {
        struct sockaddr_in peer;
        socklen_t len = sizeof peer;
        int type = 0, one = 1;
        socklen_t tlen = sizeof type;
        if (getsockopt(fd, SOL_SOCKET, SO_TYPE, &type, &tlen) == 0 && type == SOCK_STREAM &&
            getpeername(fd, (struct sockaddr *)&peer, &len) == 0 && peer.sin_family == AF_INET &&
            ntohs(peer.sin_port) == port)
            setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    }
}

static struct mg_connection *ws_connect(int port)
{
    struct mg_connection *ws = NULL;
    char err[256] = "";
    for (int i = 0; i < 100 && !ws; i++) {
        usleep(100000);
        ws = mg_connect_websocket_client("127.0.0.1", port, 0, err, sizeof err, "/ws", NULL, on_ws, NULL, NULL);
    }
    if (!ws)
        fprintf(stderr, "bench_face: no WebSocket on port %d: %s\n", port, err);
    else
        nodelay_to(port);
    return ws;
}

/* Runs the loop until *at is set or limit_us have passed; true when it was set. */
static bool wait_stamp(const int64_t *at, int64_t limit_us)
{
    int64_t end = marie_mono_us() + limit_us;
    while (!*at && marie_mono_us() < end)
        marie_loop_run_once(loop, 20);
    return *at != 0;
}

static void run_for(int64_t us)
{
    int64_t end = marie_mono_us() + us;
    while (marie_mono_us() < end)
        marie_loop_run_once(loop, (int)((end - marie_mono_us()) / 1000) + 1);
}

/* The robot has reached every goal of the mission (goals of them, at least) and stands. */
static bool wait_at_rest(int goals, int64_t limit_us)
{
    int64_t end = marie_mono_us() + limit_us;
    while ((reached < goals || moving) && marie_mono_us() < end)
        marie_loop_run_once(loop, 20);
    return reached >= goals && !moving;
}

static void go(struct mg_connection *ws, int place, const char *name, double x, double y)
{
    memset(&rq, 0, sizeof rq);
    snprintf(rq.want, sizeof rq.want, "%s", name);
    rq.x = x;
    rq.y = y;
    char cmd[64];
    int len = snprintf(cmd, sizeof cmd, "{\"op\":\"go\",\"place\":%d,\"pin\":\"1357\"}", place);
    rq.t0 = marie_mono_us();
    mg_websocket_client_write(ws, MG_WEBSOCKET_OPCODE_TEXT, cmd, (size_t)len);
}

/* Rows WHAT_p50 and, with `max`, WHAT_max of n latencies in us, as ms (sorts v). */
static void ms_rows(const char *what, int64_t *v, int n, bool max)
{
    char metric[96];
    snprintf(metric, sizeof metric, "%s_p50", what);
    row(metric, bench_percentile(v, n, 0.5) / 1e3, "ms");
    if (max) {
        snprintf(metric, sizeof metric, "%s_max", what);
        row(metric, bench_percentile(v, n, 1.0) / 1e3, "ms");
    }
}

/* The page, the server's signature and the mission's goal, 40 requests alternating 2 places. */
static int mission_only(const char *keyp)
{
    spawn("marie-face", "--param", "http_port=8141", "--param", keyp, "--param", "pin=1357", "--param",
          "places=[{name: p0, x: 1, y: 1}, {name: p1, x: 2, y: 2}]", (char *)NULL);
    spawn("marie-mission", "--param", "sharedmap=false", "--param", keyp, "--param",
          "goals=[{name: waiting, x: 50, y: 50}]", (char *)NULL);
    struct mg_connection *ws = ws_connect(8141);
    if (!ws)
        return -1;
    sleep(1);                   /* the mission subscribed and started */
    int64_t lat[ROUNDS], sig[ROUNDS];
    int n = 0;
    for (int r = 0; r < ROUNDS; r++) {
        char name[8];
        snprintf(name, sizeof name, "p%d", r % 2);
        go(ws, r % 2, name, 0, 0);
        if (wait_stamp(&rq.goal_at, 2000000) && rq.req_at) {
            sig[n] = rq.req_at - rq.t0;
            lat[n++] = rq.goal_at - rq.t0;
        }
        usleep(50000);
    }
    mg_close_connection(ws);
    stop_all();
    row("tap_to_mission_goal_answered", n, "of 40");
    if (n) {
        ms_rows("tap_to_signed_request", sig, n, false);
        ms_rows("tap_to_mission_goal", lat, n, true);
    }
    return n == ROUNDS ? 0 : -1;
}

/* The navigation stack on the simulator in real time; taps alternate between two places 2.5 m
 * apart in the corridor, each once the robot stands at the previous one. */
static int to_motor(const char *keyp)
{
    static const struct { const char *name; double x, y; } place[2] = { { "east", 4.5, 15.0 }, { "west", 2.0, 15.0 } };
    const char *map = "map=sim/worlds/office.yaml";
    spawn("marie-sim", "--name", "sim", "--param", "world=sim/worlds/office.yaml", "--param", "speed=1", (char *)NULL);
    spawn("marie-odometry", "--name", "odometry", "--clock", "sim", (char *)NULL);
    spawn("marie-localizer", "--name", "localizer", "--clock", "sim", "--param", map, "--param", "init_x=2",
          "--param", "init_y=15", (char *)NULL);
    spawn("marie-planner", "--name", "planner", "--clock", "sim", "--param", map, (char *)NULL);
    spawn("marie-ca", "mailbox", "--name", "mailboxes", "--param", "channel=POSE", "--param",
          "channels=[PATH, LASER, ESTOP]", "--param", "depth=2", (char *)NULL);
    spawn("marie-behaviours", "--name", "behaviours", "--clock", "sim", "--param", "input_mode=pull", (char *)NULL);
    spawn("marie-mission", "--name", "mission", "--clock", "sim", "--param", "sharedmap=false", "--param", keyp,
          "--param", "tolerance=0.35", "--param", "goals=[{name: start, x: 2.0, y: 15.0}]", (char *)NULL);
    spawn("marie-face", "--name", "face", "--param", "http_port=8142", "--param", keyp, "--param", "pin=1357",
          "--param", "places=[{name: east, x: 4.5, y: 15.0}, {name: west, x: 2.0, y: 15.0}]", (char *)NULL);
    struct mg_connection *ws = ws_connect(8142);
    int64_t motor[TAPS], goal[TAPS], path[TAPS], wait[TAPS];
    int n = 0;
    if (ws && !wait_at_rest(1, 60000000))
        fprintf(stderr, "bench_face: the mission did not finish its own goal\n");
    for (int t = 0; ws && t < TAPS && reached >= 1 + t && !moving; t++) {
        /* The robot is seen at rest right after a behaviours' cycle: a person's tap is not. */
        run_for((int64_t)(drand48() * 400000));
        go(ws, t % 2, place[t % 2].name, place[t % 2].x, place[t % 2].y);
        if (!wait_stamp(&rq.motor_at, 5000000)) {
            fprintf(stderr, "bench_face: tap %d (%s): no motor command toward it\n", t, rq.want);
            break;
        }
        motor[n] = rq.motor_at - rq.t0;
        goal[n] = rq.goal_at ? rq.goal_at - rq.t0 : 0;
        path[n] = rq.path_at && rq.goal_at ? rq.path_at - rq.goal_at : 0;
        wait[n++] = rq.path_at ? rq.motor_at - rq.path_at : 0;
        fprintf(stderr, "bench_face: tap %d (%s): goal %.1f ms, path +%.1f ms, motor command +%.1f ms: %.1f ms\n", t,
                rq.want, goal[n - 1] / 1e3, path[n - 1] / 1e3, wait[n - 1] / 1e3, motor[n - 1] / 1e3);
        wait_at_rest(2 + t, TAP_LIMIT_US);
    }
    if (ws)
        mg_close_connection(ws);
    stop_all();
    row("tap_to_motor_command_answered", n, "of 12");
    if (n) {
        ms_rows("tap_to_motor_command", motor, n, true);
        ms_rows("sim_tap_to_mission_goal", goal, n, false);
        ms_rows("goal_to_path", path, n, false);
        ms_rows("path_to_motor_command", wait, n, true);
    }
    if (ncycles)
        ms_rows("behaviours_period", cycle, ncycles, false);
    return n == TAPS ? 0 : -1;
}

int main(void)
{
    if (getenv("B"))
        bin = getenv("B");
    char key[] = "/tmp/bench_face_key_XXXXXX", keyp[300];
    int fd = mkstemp(key);
    close(fd);
    unlink(key);
    if (marie_auth_keygen(key) < 0)
        return 1;
    snprintf(keyp, sizeof keyp, "key_file=%s", key);
    lcm_t *lcm = lcm_create(NULL);
    loop = marie_loop_create();
    if (!lcm || !loop || marie_loop_add_bus(loop, lcm, 8) < 0)
        return 1;
    marie_goal_t_subscribe(lcm, "GOAL", on_goal, NULL);
    marie_goal_request_t_subscribe(lcm, "GOAL_REQUEST", on_req, NULL);
    marie_path_t_subscribe(lcm, "PATH", on_path, NULL);
    marie_pose_cov_t_subscribe(lcm, "POSE", on_pose, NULL);
    marie_motor_command_t_subscribe(lcm, "MOTOR_COMMAND", on_motor, NULL);
    marie_mission_state_t_subscribe(lcm, "MISSION_STATE", on_mission, NULL);
    mg_init_library(0);
    srand48(getpid());
    int rc = mission_only(keyp);
    rc |= to_motor(keyp);
    unlink(key);
    marie_loop_destroy(loop);
    lcm_destroy(lcm);
    return rc < 0 ? 1 : 0;
}
