/* bench_send: what one publish costs the caller, marie's sender (marie_bus_publish on a bus of
 * marie_bus_create) against liblcm's (lcm_publish on a bus of lcm_create) in the same run, for
 * 64 B, 8 KB and 900 KB, interleaved in blocks of a tenth. A marie reader subscribed to the
 * channel on the host is emptied after each message (untimed): the kernel hands it each
 * datagram within the sending call, as it would a component's. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench/bench.h"
#include "core/bus/bus.h"
#include "core/time.h"

#define URL "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608"
#define MAXN 20000

static int64_t lat[2][MAXN];

static int64_t now_ns(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

static void on_msg(const lcm_recv_buf_t *rb, const char *ch, void *user) { ++*(int *)user; }

static void drain(lcm_t *rx, int *got, int want)
{
    for (int64_t end = marie_mono_us() + 200000; *got < want && marie_mono_us() < end;)
        marie_bus_handle(rx, 64);
}

static void run_size(lcm_t *mine, lcm_t *lib, lcm_t *rx, int *got, const char *label, size_t size, int n)
{
    uint8_t *buf = calloc(1, size);
    int k[2] = {0, 0};
    for (int pass = 0; pass < 2; pass++) {  /* the first pass warms caches and sockets */
        k[0] = k[1] = 0;
        for (int blk = 0; blk < 20; blk++) {
            int who = blk % 2;
            for (int i = 0; i < n / 10; i++) {
                int want = *got + 1;
                int64_t t = now_ns();
                if (who == 0)
                    marie_bus_publish(mine, "BENCH_SEND", buf, (unsigned)size);
                else
                    lcm_publish(lib, "BENCH_SEND", buf, (unsigned)size);
                lat[who][k[who]++] = now_ns() - t;
                drain(rx, got, want);
            }
        }
    }
    free(buf);
    char m[64];
    snprintf(m, sizeof m, "publish_p50_%s", label);
    bench_row("send", m, bench_percentile(lat[0], k[0], 0.5) / 1000, "us", bench_percentile(lat[1], k[1], 0.5) / 1000);
    snprintf(m, sizeof m, "publish_p99_%s", label);
    bench_row("send", m, bench_percentile(lat[0], k[0], 0.99) / 1000, "us", bench_percentile(lat[1], k[1], 0.99) / 1000);
}

int main(void)
{
    lcm_t *mine = marie_bus_create(URL), *lib = lcm_create(URL), *rx = marie_bus_create(URL);
    int got = 0;
    if (!mine || !lib || !rx || !marie_bus_subscribe(rx, "BENCH_SEND", on_msg, &got)) {
        fprintf(stderr, "bench_send: no bus\n");
        return 1;
    }
    if (!marie_bus_sends(mine))
        printf("# send: marie does not send on its bus here (MARIE_LCM_SEND or MARIE_LCM_RECEIVE set)\n");
    run_size(mine, lib, rx, &got, "64B", 64, MAXN);
    run_size(mine, lib, rx, &got, "8KB", 8192, MAXN / 2);
    run_size(mine, lib, rx, &got, "900KB", 921600, 400);
    marie_bus_destroy(rx);
    lcm_destroy(lib);
    marie_bus_destroy(mine);
    return 0;
}
