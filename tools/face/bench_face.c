/* bench_face: time from a request on the touch page's WebSocket to the signed request and to
 * the mission's goal on the bus (page -> marie-face signs -> GOAL_REQUEST -> marie-mission
 * checks -> GOAL), as processes. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include <civetweb.h>
#include <lcm/lcm.h>

#include "core/auth.h"
#include "core/time.h"
#include "lcmtypes/marie_types.h"

#define ROUNDS 40

static char want[32];
static int64_t got_at, req_at;

static void on_req(const lcm_recv_buf_t *rb, const char *ch, const marie_goal_request_t *m, void *u)
{
    if (!req_at && strcmp(m->goal.name, want) == 0)
        req_at = marie_mono_us();
}

static void on_goal(const lcm_recv_buf_t *rb, const char *ch, const marie_goal_t *m, void *u)
{
    if (!got_at && strcmp(m->name, want) == 0)
        got_at = marie_mono_us();
}

static int on_ws(struct mg_connection *c, int bits, char *data, size_t len, void *u)
{
    return 1;
}

static pid_t spawn(char *const argv[])
{
    pid_t pid = fork();
    if (pid == 0) {
        freopen("/dev/null", "w", stdout);
        freopen("/dev/null", "w", stderr);
        execv(argv[0], argv);
        _exit(127);
    }
    return pid;
}

static int cmp(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

int main(void)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    char key[] = "/tmp/bench_face_key_XXXXXX", face[256], mission[256], keyp[300], keym[300];
    int fd = mkstemp(key);
    close(fd);
    unlink(key);
    if (marie_auth_keygen(key) < 0)
        return 1;
    snprintf(face, sizeof face, "%s/bin/marie-face", b);
    snprintf(mission, sizeof mission, "%s/bin/marie-mission", b);
    snprintf(keyp, sizeof keyp, "key_file=%s", key);
    snprintf(keym, sizeof keym, "key_file=%s", key);
    char *fa[] = { face, "--param", "http_port=8141", "--param", keyp, "--param", "pin=1",
                   "--param", "places=[{name: p0, x: 1, y: 1}, {name: p1, x: 2, y: 2}]", NULL };
    char *ma[] = { mission, "--param", "sharedmap=false", "--param", keym, "--param",
                   "goals=[{name: waiting, x: 50, y: 50}]", NULL };
    pid_t pf = spawn(fa), pm = spawn(ma);
    lcm_t *lcm = lcm_create(NULL);
    marie_goal_t_subscribe(lcm, "GOAL", on_goal, NULL);
    marie_goal_request_t_subscribe(lcm, "GOAL_REQUEST", on_req, NULL);
    mg_init_library(0);
    struct mg_connection *ws = NULL;
    char err[256];
    for (int i = 0; i < 100 && !ws; i++) {
        usleep(100000);
        ws = mg_connect_websocket_client("127.0.0.1", 8141, 0, err, sizeof err, "/ws", NULL, on_ws, NULL, NULL);
    }
    if (!ws) {
        fprintf(stderr, "bench_face: no WebSocket: %s\n", err);
        return 1;
    }
    sleep(1);                   /* the mission subscribed and started */
    int64_t lat[ROUNDS], sig[ROUNDS];
    int n = 0;
    for (int r = 0; r < ROUNDS; r++) {
        snprintf(want, sizeof want, "p%d", r % 2);
        got_at = req_at = 0;
        char cmd[64];
        int len = snprintf(cmd, sizeof cmd, "{\"op\":\"go\",\"place\":%d,\"pin\":\"1\"}", r % 2);
        int64_t t0 = marie_mono_us();
        mg_websocket_client_write(ws, MG_WEBSOCKET_OPCODE_TEXT, cmd, (size_t)len);
        while (!got_at && marie_mono_us() - t0 < 2000000)
            lcm_handle_timeout(lcm, 20);
        if (got_at && req_at) {
            sig[n] = req_at - t0;
            lat[n++] = got_at - t0;
        }
        usleep(50000);
    }
    mg_close_connection(ws);
    kill(pf, SIGTERM);
    kill(pm, SIGTERM);
    waitpid(pf, NULL, 0);
    waitpid(pm, NULL, 0);
    unlink(key);
    lcm_destroy(lcm);
    qsort(lat, (size_t)n, sizeof lat[0], cmp);
    qsort(sig, (size_t)n, sizeof sig[0], cmp);
    if (n)
        printf("face_tap_to_signed_request\tp50\t%.2f\tms\t-\t-\n", sig[n / 2] / 1e3);
    printf("face_tap_to_mission_goal\tanswered\t%d\tof %d\t-\t-\n", n, ROUNDS);
    if (n) {
        printf("face_tap_to_mission_goal\tp50\t%.2f\tms\t-\t-\n", lat[n / 2] / 1e3);
        printf("face_tap_to_mission_goal\tmax\t%.2f\tms\t-\t-\n", lat[n - 1] / 1e3);
    }
    return n == ROUNDS ? 0 : 1;
}
