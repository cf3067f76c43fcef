/* marie-test-status: the status side of the managers' protocol for the marie ps tests: floods
 * status requests and counts the statuses a manager published meanwhile, or plays a manager
 * that does not know status requests (it only reports periodically). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <lcm/lcm.h>

#include "core/config.h"
#include "core/time.h"
#include "proto/am_proto.h"

static const char *watch_host;
static int64_t first_seq = -1, last_seq = -1;

static void on_status(const lcm_recv_buf_t *rbuf, const char *ch, const marie_am_status_t *st, void *user)
{
    if (strcmp(st->host, watch_host) != 0)
        return;
    if (first_seq < 0)
        first_seq = st->seq;
    if (st->seq > last_seq)
        last_seq = st->seq;
}

static void listen_until(lcm_t *lcm, int64_t end_mono)
{
    while (marie_mono_us() < end_mono)
        lcm_handle_timeout(lcm, 50);
}

/* One request and its answer, then n requests one every 3 ms (faster, the kernel drops them
 * before the manager reads them), then 1.5 s of listening. The manager's status seq numbers
 * count what it published meanwhile, even statuses lost on the way here. */
static int flood(lcm_t *lcm, int n)
{
    marie_am_status_t_subscription_t *sub = marie_am_status_t_subscribe(lcm, MARIE_CH_AM_STATUS, on_status, NULL);
    marie_am_status_request_t rq = {.utime = marie_wall_us(), .sender = "flood@test", .host = "*"};
    marie_am_status_request_t_publish(lcm, MARIE_CH_AM_STATUS_REQUEST, &rq);
    int64_t end = marie_mono_us() + 3000000;
    while (first_seq < 0 && marie_mono_us() < end)
        lcm_handle_timeout(lcm, 50);
    if (first_seq < 0) {
        printf("no status from %s\n", watch_host);
        marie_am_status_t_unsubscribe(lcm, sub);
        return 1;
    }
    int64_t seq0 = last_seq, t0 = marie_mono_us();
    for (int i = 0; i < n; i++) {
        rq.utime = marie_wall_us();
        marie_am_status_request_t_publish(lcm, MARIE_CH_AM_STATUS_REQUEST, &rq);
        lcm_handle_timeout(lcm, 3);
    }
    listen_until(lcm, marie_mono_us() + 1500000);
    printf("sent %d statuses %lld seconds %.1f\n", n, (long long)(last_seq - seq0),
           (double)(marie_mono_us() - t0) / 1e6);
    marie_am_status_t_unsubscribe(lcm, sub);
    return 0;
}

/* A manager from before status requests: a status every 0.5 s, never an answer. */
static int play_old(lcm_t *lcm, double seconds, int nhosts, char **hosts)
{
    marie_am_component_status_t comp = {
        .name = "legacy", .group = "", .state = "running", .comp_state = 2, .pid = getpid(),
        .config_hash = "", .heartbeat_age_us = 100000, .limits = "",
    };
    marie_am_status_t st = {
        .host = (char *)watch_host, .pid = getpid(), .system = "ps", .system_hash = "", .profile = "",
        .ncpu = 1, .nhosts = nhosts, .hosts = hosts, .ncomponents = 1, .components = &comp,
        .balance_leader = "", .balance_last = "",
    };
    int64_t t0 = marie_mono_us(), end = t0 + (int64_t)(seconds * 1e6);
    while (marie_mono_us() < end) {
        st.utime = marie_wall_us();
        st.seq++;
        st.uptime_us = marie_mono_us() - t0;
        comp.uptime_us = st.uptime_us;
        marie_am_status_t_publish(lcm, MARIE_CH_AM_STATUS, &st);
        usleep(500000);
    }
    return 0;
}

int main(int argc, char **argv)
{
    if (argc >= 4 && strcmp(argv[1], "flood") == 0) {
        watch_host = argv[3];
    } else if (argc >= 5 && strcmp(argv[1], "old") == 0) {
        watch_host = argv[2];
    } else {
        fprintf(stderr, "usage: marie-test-status flood N HOST | old HOST SECONDS HOST...\n");
        return 2;
    }
    lcm_t *lcm = lcm_create(marie_default_url());
    if (!lcm)
        return 1;
    int rc = argv[1][0] == 'f' ? flood(lcm, atoi(argv[2])) : play_old(lcm, atof(argv[3]), argc - 4, argv + 4);
    lcm_destroy(lcm);
    return rc;
}
