/* bench_viewer: marie-viewer-server following a demo-like bus at full rate (laser and pose
 * 10 Hz, ground truth 50 Hz, particles 2 Hz, decisions 5 Hz, heartbeats, an office-sized map):
 * its CPU and memory, and the latency from publishing to the frame reaching a WebSocket
 * client, against the bus alone measured in the same run; then STALL_SECONDS more with 40
 * half requests and 3 pages that never read beside the client, against the quiet part. */
#include <fcntl.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <unistd.h>

#include <civetweb.h>
#include <lcm/lcm.h>

#include "bench/bench.h"
#include "core/loop.h"
#include "core/procstat.h"
#include "core/time.h"
#include "lcmtypes/marie_types.h"

#define PORT 8121
#define SECONDS 10
#define STALL_SECONDS 5
#define MAXSEQ 4096

static int64_t pub_mono[MAXSEQ];
static int64_t seq_lat[MAXSEQ], bus_lat[MAXSEQ];     /* seq_lat: by probe, 0 if none */
static int n_ws, n_bus;
static int64_t ws_frames, ws_bytes;
static pthread_mutex_t mu = PTHREAD_MUTEX_INITIALIZER;
static volatile int connected;

static void row(const char *metric, double value, const char *unit, double baseline)
{
    bench_row("bench_viewer", metric, value, unit, baseline);
}

/* The bench's events carry their sequence number in the text: "bench N". */
static int seq_of(const char *p, size_t len)
{
    const char *k = memmem(p, len, "\"text\":\"bench ", 14);
    return k ? atoi(k + 14) : -1;
}

static int on_ws(struct mg_connection *conn, int bits, char *data, size_t len, void *user)
{
    int64_t now = marie_mono_us();
    pthread_mutex_lock(&mu);
    ws_frames++;
    ws_bytes += (int64_t)len;
    if (memmem(data, len, "\"type\":\"hello\"", 14))
        connected = 1;
    int s = memmem(data, len, "\"k\":\"event\"", 11) ? seq_of(data, len) : -1;
    if (s >= 0 && s < MAXSEQ && pub_mono[s] && !seq_lat[s]) {
        seq_lat[s] = now - pub_mono[s];
        n_ws++;
    }
    pthread_mutex_unlock(&mu);
    return 1;
}

static void on_ws_close(const struct mg_connection *conn, void *user)
{
    connected = 0;
}

static void on_bus_event(const lcm_recv_buf_t *rb, const char *ch, const marie_event_t *e, void *user)
{
    int64_t now = marie_mono_us();
    int s = strncmp(e->text, "bench ", 6) == 0 ? atoi(e->text + 6) : -1;
    pthread_mutex_lock(&mu);
    if (s >= 0 && s < MAXSEQ && pub_mono[s] && n_bus < MAXSEQ)
        bus_lat[n_bus++] = now - pub_mono[s];
    pthread_mutex_unlock(&mu);
}

static volatile int stop_listener;

/* The bus alone, heard on a loop of the listener thread's own. */
static void *listener(void *arg)
{
    marie_loop_t *loop = arg;
    while (!stop_listener)
        marie_loop_run_once(loop, 100);
    return NULL;
}

static int cmp64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return x < y ? -1 : x > y;
}

static double pct(int64_t *v, int n, double p)
{
    if (n == 0)
        return -1;
    qsort(v, (size_t)n, sizeof *v, cmp64);
    int i = (int)(p * (n - 1) + 0.5);
    return v[i] / 1000.0;
}


static void publish(lcm_t *l, const char *ch, const marie_type_t *t, const void *msg)
{
    int n = t->encoded_size(msg);
    void *buf = malloc((size_t)n);
    if (buf && t->encode(buf, 0, n, msg) >= 0)
        lcm_publish(l, ch, buf, (unsigned)n);
    free(buf);
}

/* The probes [from, to) that reached the client, their latencies into out: how many. */
static int probes(int from, int to, int64_t *out)
{
    int n = 0;
    for (int s = from; s < to; s++)
        if (seq_lat[s])
            out[n++] = seq_lat[s];
    return n;
}

/* A client that stalls: half a request, or a page with a 2 KB window that is never read. */
static int stall_client(bool page)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0), small = 2048;
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons(PORT)};
    inet_pton(AF_INET, "127.0.0.1", &sa.sin_addr);
    if (connect(fd, (struct sockaddr *)&sa, sizeof sa) < 0)
        return fd;
    static const char half[] = "GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n";
    static const char ws[] = "GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                             "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n";
    const char *req = page ? ws : half;
    (void)!send(fd, req, strlen(req), MSG_NOSIGNAL);    /* and nothing is ever read */
    return fd;
}

/* Server CPU while playing a 60 s synthetic mission log at `speed` to one WebSocket client. */
static double log_cpu(const char *b, const char *log, double speed, double *frames_per_s)
{
    char exe[256], logp[300], speedp[64], portp[64];
    snprintf(exe, sizeof exe, "%s/bin/marie-viewer-server", b);
    snprintf(logp, sizeof logp, "log=%s", log);
    snprintf(speedp, sizeof speedp, "speed=%g", speed);
    snprintf(portp, sizeof portp, "http_port=%d", PORT + 1);
    pid_t srv = fork();
    if (srv == 0) {
        int fd = open("/dev/null", O_WRONLY);
        if (fd >= 0)
            dup2(fd, 1);
        execl(exe, exe, "--name", "viewer-log", "--param", portp, "--param", logp, "--param", speedp,
              "--param", "autoplay=false", (char *)NULL);
        _exit(127);
    }
    struct mg_connection *ws = NULL;
    char err[256];
    for (int i = 0; i < 100 && !ws; i++) {
        usleep(100000);
        ws = mg_connect_websocket_client("127.0.0.1", PORT + 1, 0, err, sizeof err, "/ws", NULL, on_ws, NULL, NULL);
    }
    double cpu = -1;
    if (ws) {
        usleep(500000);
        const char *play = "{\"op\":\"play\"}";
        mg_websocket_client_write(ws, MG_WEBSOCKET_OPCODE_TEXT, play, strlen(play));
        int64_t t0 = 0, t1 = 0, rss;
        pthread_mutex_lock(&mu);
        int64_t f0 = ws_frames;
        pthread_mutex_unlock(&mu);
        marie_proc_usage(srv, &t0, &rss);
        int64_t start = marie_mono_us();
        usleep(5000000);
        marie_proc_usage(srv, &t1, &rss);
        double wall = (marie_mono_us() - start) / 1e6;
        pthread_mutex_lock(&mu);
        *frames_per_s = (ws_frames - f0) / wall;
        pthread_mutex_unlock(&mu);
        cpu = (t1 - t0) / 1e4 / wall;
        mg_close_connection(ws);
    }
    kill(srv, SIGTERM);
    waitpid(srv, NULL, 0);
    return cpu;
}

int main(int argc, char **argv)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    char exe[256], portp[64];
    snprintf(exe, sizeof exe, "%s/bin/marie-viewer-server", b);
    snprintf(portp, sizeof portp, "http_port=%d", PORT);
    pid_t srv = fork();
    if (srv == 0) {
        int fd = open("/dev/null", 1);
        if (fd >= 0)
            dup2(fd, 1);
        execl(exe, exe, "--name", "viewer", "--param", portp, (char *)NULL);
        _exit(127);
    }
    mg_init_library(0);
    struct mg_connection *ws = NULL;
    char err[256];
    for (int i = 0; i < 100 && !ws; i++) {
        usleep(100000);
        ws = mg_connect_websocket_client("127.0.0.1", PORT, 0, err, sizeof err, "/ws", NULL, on_ws, on_ws_close, NULL);
    }
    if (!ws) {
        fprintf(stderr, "bench_viewer: cannot connect to the viewer: %s\n", err);
        kill(srv, SIGTERM);
        return 1;
    }
    for (int i = 0; i < 50 && !connected; i++)
        usleep(100000);

    lcm_t *pub = lcm_create(NULL), *sub = lcm_create(NULL);
    marie_loop_t *sub_loop = marie_loop_create();
    if (!pub || !sub || !sub_loop || marie_loop_add_bus(sub_loop, sub, 1) < 0)
        return 1;
    marie_event_t_subscribe(sub, "MARIE_EVENT", on_bus_event, NULL);
    pthread_t th;
    pthread_create(&th, NULL, listener, sub_loop);

    /* the demo's data: office map 800x600, 181-beam laser, 2000 particles */
    enum { MW = 800, MH = 600, NP = 2000 };
    int8_t *cells = calloc(MW * MH, 1);
    for (int i = 0; i < MW * MH; i += 7)
        cells[i] = (int8_t)(i % 3 ? 0 : 100);
    float ranges[181], px[NP], py[NP], pt[NP], pw[NP];
    for (int i = 0; i < 181; i++)
        ranges[i] = 2.0f + (float)(i % 17) * 0.1f;
    for (int i = 0; i < NP; i++) {
        px[i] = 5 + (float)(i % 40) * 0.01f;
        py[i] = 5 + (float)(i / 40) * 0.01f;
        pt[i] = 0;
        pw[i] = 1.0f / NP;
    }
    marie_behaviour_vote_t votes[4] = {{"estop", 100, 0, 0, 0, "released"}, {"teleop", 50, 0, 0, 0, "no joystick"},
                                       {"avoid", 20, 0, 0, 0, "clear"}, {"follow_path", 10, 1, 0.8, 0.1, "tracking path"}};
    marie_input_age_t ins[3] = {{"pose", 0.04}, {"path", 0.6}, {"scan", 0.05}};
    marie_pose2d_t path_pts[40];
    for (int i = 0; i < 40; i++)
        path_pts[i] = (marie_pose2d_t){i * 0.5, 3, 0};
    const char *comps[8] = {"sim", "odometry", "localizer", "planner", "behaviours", "mission", "mailbox", "sharedmap"};

    int64_t t0_us = 0, t1_us = 0, rss = 0, frames = 0, bytes = 0;
    marie_proc_usage(srv, &t0_us, &rss);
    int64_t start = marie_mono_us();
    double wall_s = 0;
    int seq = 0, quiet_seq = 0, stalled[43];
    for (int k = 0; k < (SECONDS + STALL_SECONDS) * 50; k++) {    /* 50 Hz master tick */
        if (k == SECONDS * 50) {                /* the quiet part's figures; then the stalls */
            wall_s = (marie_mono_us() - start) / 1e6;
            marie_proc_usage(srv, &t1_us, &rss);
            pthread_mutex_lock(&mu);
            frames = ws_frames;
            bytes = ws_bytes;
            pthread_mutex_unlock(&mu);
            quiet_seq = seq;
            for (int i = 0; i < 43; i++)
                stalled[i] = stall_client(i >= 40);
        }
        int64_t due = start + (int64_t)k * 20000, now = marie_mono_us();
        if (due > now)
            usleep((useconds_t)(due - now));
        int64_t ut = marie_wall_us();
        double x = 5 + k * 0.01;
        marie_pose_cov_t truth = {.utime = ut, .frame = "map", .pose = {x, 5, 0.1}};
        publish(pub, "SIM_TRUTH", &marie_type_pose_cov_t, &truth);
        if (k % 5 == 0) {
            marie_pose_cov_t est = {.utime = ut, .frame = "map", .pose = {x + 0.03, 5.02, 0.1}, .cov = {0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.001}};
            publish(pub, "POSE", &marie_type_pose_cov_t, &est);
            marie_laser_scan_t scan = {.utime = ut, .angle_min = -1.5708f, .angle_increment = 0.017453f,
                                       .range_min = 0.05f, .range_max = 8, .nranges = 181, .ranges = ranges};
            publish(pub, "LASER", &marie_type_laser_scan_t, &scan);
        }
        if (k % 10 == 0) {
            marie_arbitration_t a = {.utime = ut, .cycle = k / 10, .nvotes = 4, .votes = votes, .winner = "follow_path",
                                     .v = 0.8, .omega = 0.1, .ninputs = 3, .inputs = ins};
            publish(pub, "ARBITRATION", &marie_type_arbitration_t, &a);
            /* the latency probe: an event (never decimated), 5 Hz */
            char text[32];
            snprintf(text, sizeof text, "bench %d", seq);
            marie_event_t e = {.utime = ut, .source = "bench", .seq = seq, .severity = 1, .kind = "probe", .text = text};
            pthread_mutex_lock(&mu);
            pub_mono[seq] = marie_mono_us();
            pthread_mutex_unlock(&mu);
            publish(pub, "MARIE_EVENT", &marie_type_event_t, &e);
            seq++;
        }
        if (k % 25 == 0) {
            marie_particle_cloud_t pc = {.utime = ut, .frame = "map", .n = NP, .x = px, .y = py, .theta = pt, .weight = pw};
            publish(pub, "PARTICLES", &marie_type_particle_cloud_t, &pc);
        }
        if (k % 50 == 0) {
            marie_path_t p = {.utime = ut, .goal_id = 1, .nposes = 40, .poses = path_pts};
            publish(pub, "PATH", &marie_type_path_t, &p);
            marie_goal_t g = {.utime = ut, .id = 1, .name = "room1", .pose = {20, 3, 0}, .tolerance = 0.3};
            publish(pub, "GOAL", &marie_type_goal_t, &g);
            for (int i = 0; i < 8; i++) {
                marie_heartbeat_t hb = {.utime = ut, .component = (char *)comps[i], .host = "pc1", .pid = 100 + i,
                                        .seq = k, .state = 2, .reason = "", .uptime_us = k * 20000};
                publish(pub, "MARIE_HEARTBEAT", &marie_type_heartbeat_t, &hb);
            }
        }
        if (k % 250 == 0) {
            marie_occupancy_grid_t g = {.utime = ut, .resolution = 0.05f, .width = MW, .height = MH,
                                        .origin = {0, 0, 0}, .ncells = MW * MH, .cells = cells};
            publish(pub, "MAP", &marie_type_occupancy_grid_t, &g);
        }
    }
    usleep(300000);                             /* the last frames in flight */
    for (int i = 0; i < 43; i++)
        close(stalled[i]);

    stop_listener = 1;
    pthread_join(th, NULL);
    mg_close_connection(ws);
    kill(srv, SIGTERM);
    waitpid(srv, NULL, 0);

    pthread_mutex_lock(&mu);
    double cpu = (t1_us - t0_us) / 1e4 / wall_s;
    row("server_cpu_live_full_rate", cpu, "%core", 0);
    row("server_rss", rss / 1048576.0, "MiB", 0);
    row("frames_to_browser", frames / wall_s, "frames/s", 0);
    row("bytes_to_browser", bytes / wall_s / 1024.0, "KiB/s", 0);
    double bus50 = pct(bus_lat, n_bus, 0.5), bus99 = pct(bus_lat, n_bus, 0.99);
    static int64_t lat[MAXSEQ];
    int nq = probes(0, quiet_seq, lat);
    double q50 = pct(lat, nq, 0.5), q99 = pct(lat, nq, 0.99);
    row("bus_to_browser_latency_p50", q50, "ms", bus50);
    row("bus_to_browser_latency_p99", q99, "ms", bus99);
    row("probes_received", nq, "of", quiet_seq);
    int ns = probes(quiet_seq, seq, lat);
    row("latency_p50_beside_stalled_clients", pct(lat, ns, 0.5), "ms", q50);
    row("latency_p99_beside_stalled_clients", pct(lat, ns, 0.99), "ms", q99);
    row("probes_received_beside_stalled", ns, "of", seq - quiet_seq);
    pthread_mutex_unlock(&mu);
    marie_loop_destroy(sub_loop);
    lcm_destroy(pub);
    lcm_destroy(sub);
    free(cells);

    /* the same server playing a recorded mission: at recorded speed and 10x */
    char gen[256], log[64], cmd[400];
    snprintf(gen, sizeof gen, "%s/tests/bin/viewer-gen", b);
    snprintf(log, sizeof log, "/tmp/bench_viewer.%d.lcmlog", (int)getpid());
    snprintf(cmd, sizeof cmd, "%s log %s --seconds 60", gen, log);
    if (system(cmd) == 0) {
        double fps = 0, c1 = log_cpu(b, log, 1, &fps);
        row("server_cpu_log_play_1x", c1, "%core", 0);
        row("frames_to_browser_log_1x", fps, "frames/s", 0);
        double c10 = log_cpu(b, log, 10, &fps);
        row("server_cpu_log_play_10x", c10, "%core", c1);
        row("frames_to_browser_log_10x", fps, "frames/s", 0);
    }
    unlink(log);
    return n_ws > 0 ? 0 : 1;
}
