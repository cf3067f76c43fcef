/* ca-lcm-relay: the plain LCM baseline for the CA benchmarks: subscribe to IN, publish on OUT. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>

#include <lcm/lcm.h>

#include "ca/ca.h"
#include "core/config.h"

static volatile sig_atomic_t quit;
static void on_signal(int s) { quit = 1; }

static void relay(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    struct { lcm_t *lcm; const char *out; } *ctx = user;
    lcm_publish(ctx->lcm, ctx->out, rbuf->data, rbuf->data_size);
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: ca-lcm-relay IN OUT\n");
        return 2;
    }
    lcm_t *lcm = lcm_create(marie_default_url());
    if (!lcm)
        return 1;
    struct { lcm_t *lcm; const char *out; } ctx = { lcm, argv[2] };
    char *pat = ca_channel_pattern(argv[1]);
    lcm_subscribe(lcm, pat, relay, &ctx);
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    while (!quit)
        lcm_handle_timeout(lcm, 100);
    free(pat);
    lcm_destroy(lcm);
    return 0;
}
