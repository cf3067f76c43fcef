/* bench_ca: hop latency through each CA process against a plain LCM relay process measured in
 * the same run, the Mailbox pull round trip, and acknowledged SharedMap writes per second. */
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "bench/bench.h"
#include "ca/ca.h"
#include "ca/sharedmap_client.h"
#include "core/time.h"
#include "lcmtypes/marie_pose2d_t.h"
#include "tests/ca/ca_test.h"

#define BLOCKS 200
#define PER_BLOCK 20

typedef struct {
    const char *name;
    const char *out;          /* channel the hop comes back on */
    int64_t *lat;
    int n;
    int64_t got_id;           /* id of the message that came back */
    int64_t got_at;
} path_t;

static int cmp64(const void *a, const void *b)
{
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return x < y ? -1 : x > y;
}

static int64_t pct(path_t *p, double q)
{
    qsort(p->lat, (size_t)p->n, sizeof *p->lat, cmp64);
    int i = (int)(q * (p->n - 1) + 0.5);
    return p->n ? p->lat[i] : 0;
}

/* Both hops and pull replies carry the id in the payload: a pose with x = id. */
static void on_out(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    path_t *p = user;
    marie_pose2d_t m;
    if (marie_pose2d_t_decode(rbuf->data, 0, (int)rbuf->data_size, &m) < 0)
        return;
    p->got_id = (int64_t)m.x;
    p->got_at = marie_mono_us();
}

static void on_pull_reply(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    path_t *p = user;
    marie_pull_reply_t r;
    if (marie_decode_checked(&marie_type_pull_reply_t, rbuf->data, rbuf->data_size, &r) < 0)
        return;
    marie_pull_reply_t_decode_cleanup(&r);
    if (r.status != 0)
        return;
    p->got_id = r.request_id;
    p->got_at = marie_mono_us();
}

static void on_sm_reply(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    path_t *p = user;
    marie_sharedmap_reply_t r;
    if (marie_decode_checked(&marie_type_sharedmap_reply_t, rbuf->data, rbuf->data_size, &r) < 0)
        return;
    marie_sharedmap_reply_t_decode_cleanup(&r);
    if (r.status != 0)
        return;
    p->got_id = r.request_id;
    p->got_at = marie_mono_us();
}

static bool arrived(void *user) { path_t *p = user; return p->got_id == p->n + 1; }

static pid_t spawn_relay(const char *in, const char *out)
{
    char prog[512];
    const char *b = getenv("B");
    snprintf(prog, sizeof prog, "%s/bench/ca-lcm-relay", b && *b ? b : "build");
    pid_t pid = fork();
    if (pid == 0) {
        execl(prog, prog, in, out, (char *)NULL);
        _exit(127);
    }
    return pid;
}

enum { HOP, PULL, GET };

/* One message through a path: publish on `in` (or a request), wait for it back. */
static int one(cat_bus_t *bus, path_t *p, const char *in, int how)
{
    int64_t id = p->n + 1;
    int64_t t0 = marie_mono_us();
    if (how == GET) {
        marie_sharedmap_request_t req = { .request_id = id, .client = "bench", .reply_channel = "SM_REPLY",
                                          .op = MARIE_SHAREDMAP_REQUEST_T_OP_GET, .key = "bench/7", .type = "",
                                          .data = (uint8_t *)"" };
        marie_sharedmap_request_t_publish(cat_lcm(bus), "SHAREDMAP", &req);
    } else if (how == PULL) {
        marie_pull_request_t req = { .utime = 0, .request_id = id, .requester = "bench", .channel = "MB_IN",
                                     .reply_channel = "MB_REPLY", .timeout_ms = 500 };
        marie_pull_request_t_publish(cat_lcm(bus), "MB_IN.PULL", &req);
    } else {
        marie_pose2d_t m = { .x = (double)id };
        marie_pose2d_t_publish(cat_lcm(bus), in, &m);
    }
    if (!cat_spin(bus, 1000, arrived, p))
        return -1;
    p->lat[p->n++] = p->got_at - t0;
    return 0;
}

static void row(const char *metric, double v, const char *unit, double base)
{
    bench_row("bench_ca", metric, v, unit, base);
}

int main(void)
{
    cat_bus_t *bus = cat_bus_create();
    if (!bus)
        return 1;
    char dir[256];
    cat_tmpdir(dir, sizeof dir);
    char sm_state[400], sw_state[400];
    snprintf(sm_state, sizeof sm_state, "state_file=%s/map.log", dir);
    snprintf(sw_state, sizeof sw_state, "state_file=%s/sw.sel", dir);

    pid_t relay = spawn_relay("R_IN", "R_OUT");
    const char *sp_args[] = { "splitter", "--name", "b_sp", "--param", "type=marie.pose2d_t",
                              "--param", "input=SP_IN", "--param", "outputs=[SP_OUT]", NULL };
    const char *sw_args[] = { "switch", "--name", "b_sw", "--param", "type=marie.pose2d_t",
                              "--param", "output=SW_OUT", "--param", "inputs={a: SW_IN, b: SW_OTHER}",
                              "--param", "initial=a", "--param", sw_state, NULL };
    const char *mb_args[] = { "mailbox", "--name", "b_mb", "--param", "type=marie.pose2d_t",
                              "--param", "channel=MB_IN", "--param", "depth=4", NULL };
    const char *sm_args[] = { "sharedmap", "--name", "b_sm", "--param", sm_state, NULL };
    pid_t sp = cat_spawn(sp_args), sw = cat_spawn(sw_args), mb = cat_spawn(mb_args), sm = cat_spawn(sm_args);
    bool up = cat_wait_running(bus, "b_sp", 5000) && cat_wait_running(bus, "b_sw", 5000) &&
              cat_wait_running(bus, "b_mb", 5000) && cat_wait_running(bus, "b_sm", 5000);
    int status = up ? 0 : 1;

    enum { NP = 5 };
    path_t paths[NP] = {
        { .name = "relay", .out = "R_OUT" }, { .name = "splitter", .out = "SP_OUT" },
        { .name = "switch", .out = "SW_OUT" }, { .name = "mailbox_pull", .out = "MB_REPLY" },
        { .name = "sharedmap_get", .out = "SM_REPLY" },
    };
    const char *ins[NP] = { "R_IN", "SP_IN", "SW_IN", NULL, NULL };
    const int how[NP] = { HOP, HOP, HOP, PULL, GET };
    lcm_msg_handler_t handlers[NP] = { on_out, on_out, on_out, on_pull_reply, on_sm_reply };
    for (int i = 0; i < NP; i++) {
        paths[i].lat = calloc(BLOCKS * PER_BLOCK, sizeof(int64_t));
        lcm_subscribe(cat_lcm(bus), paths[i].out, handlers[i], &paths[i]);
    }
    marie_pose2d_t seed = { .x = 1 };
    marie_pose2d_t_publish(cat_lcm(bus), "MB_IN", &seed);
    sharedmap_client_t *seeder = sharedmap_client_create(cat_lcm(bus), NULL, "bench-seed");
    if (up && sharedmap_client_set(seeder, "bench/7", &marie_type_pose2d_t, &seed, 2000) != 0)
        up = false;
    sharedmap_client_destroy(seeder);
    /* the relay has no heartbeat: wait until it passes messages */
    for (int i = 0; i < 50 && up; i++) {
        paths[0].n = 0;
        if (one(bus, &paths[0], "R_IN", HOP) == 0)
            break;
    }
    /* warm up, then interleave blocks so load changes on this machine hit every path alike */
    for (int i = 0; i < NP; i++) {
        for (int k = 0; up && k < 50; k++)
            one(bus, &paths[i], ins[i], how[i]);
        paths[i].n = 0;
    }
    int lost = 0;
    for (int b = 0; up && b < BLOCKS; b++)
        for (int i = 0; i < NP; i++)
            for (int k = 0; k < PER_BLOCK; k++)
                if (one(bus, &paths[i], ins[i], how[i]) < 0)
                    lost++;
    if (up) {
        double base50 = (double)pct(&paths[0], 0.5), base99 = (double)pct(&paths[0], 0.99);
        row("relay_hop_p50", base50, "us", 0);
        row("relay_hop_p99", base99, "us", 0);
        for (int i = 1; i < NP; i++) {
            char m[64];
            snprintf(m, sizeof m, "%s_%s_p50", paths[i].name, how[i] != HOP ? "rtt" : "hop");
            row(m, (double)pct(&paths[i], 0.5), "us", base50);
            snprintf(m, sizeof m, "%s_%s_p99", paths[i].name, how[i] != HOP ? "rtt" : "hop");
            row(m, (double)pct(&paths[i], 0.99), "us", base99);
        }
        if (lost)
            fprintf(stderr, "bench_ca: %d messages not back within 1 s\n", lost);

        /* acknowledged writes with fdatasync on every one */
        sharedmap_client_t *cl = sharedmap_client_create(cat_lcm(bus), NULL, "bench");
        marie_pose2d_t v = { 0 };
        int n = 0, failed = 0;
        int64_t t0 = marie_mono_us();
        while (marie_mono_us() - t0 < 3000000) {
            char key[32];
            snprintf(key, sizeof key, "bench/%d", n % 100);
            v.x = n;
            if (sharedmap_client_set(cl, key, &marie_type_pose2d_t, &v, 1000) == 0)
                n++;
            else
                failed++;
        }
        double secs = (marie_mono_us() - t0) / 1e6;
        row("sharedmap_acked_writes", n / secs, "writes/s", 0);

        if (failed)
            fprintf(stderr, "bench_ca: %d SharedMap writes not acknowledged\n", failed);
        sharedmap_client_destroy(cl);
    }
    cat_stop(sp, SIGTERM);
    cat_stop(sw, SIGTERM);
    cat_stop(mb, SIGTERM);
    cat_stop(sm, SIGTERM);
    kill(relay, SIGTERM);
    waitpid(relay, NULL, 0);
    for (int i = 0; i < NP; i++)
        free(paths[i].lat);
    cat_rmdir(dir);
    cat_bus_destroy(bus);
    return status;
}
