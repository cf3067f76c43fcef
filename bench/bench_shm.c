/* bench_shm: one-way latency of 8 KB and 900 KB messages through the shared-memory transport
 * (ring + notice on LCM) against plain LCM in the same run, and loss at 30 Hz with three
 * subscribers on each. */
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench/bench.h"
#include "core/config.h"
#include "core/bus/shm_bus.h"
#include "core/time.h"

#define NSUB 3

typedef struct {
    int64_t lat[4096];
    int n;
    int64_t t0;
    long got[NSUB];
} sink_t;

static sink_t shm_sink, lcm_sink;

static void on_shm(const void *data, size_t len, void *user)
{
    long *got = user;
    (*got)++;
    if (got == &shm_sink.got[0] && shm_sink.n < 4096)
        shm_sink.lat[shm_sink.n++] = marie_mono_us() - shm_sink.t0;
}

static void on_lcm(const lcm_recv_buf_t *rb, const char *ch, void *user)
{
    long *got = user;
    (*got)++;
    if (got == &lcm_sink.got[0] && lcm_sink.n < 4096)
        lcm_sink.lat[lcm_sink.n++] = marie_mono_us() - lcm_sink.t0;
}

static long torn;

static void on_verdict(bool ok, void *user)
{
    if (!ok)
        torn++;
}

static double pct(sink_t *s, double p) { return bench_percentile(s->lat, s->n, p); }

static void row(const char *metric, double v, const char *unit, double base)
{
    bench_row("shm", metric, v, unit, base);
}

typedef struct {
    lcm_t *tx, *rx[NSUB];
    marie_shm_pub_t *pub;
    bool loaned;                /* shared memory published through a loan */
} bus_t;

static void drain(bus_t *b, int timeout_ms)
{
    for (int k = 0; k < NSUB; k++)
        while (lcm_handle_timeout(b->rx[k], k == 0 ? timeout_ms : 0) > 0)
            if (k == 0)
                break;
}

/* One message at a time, waiting for the first subscriber to have it. */
static void latency(bus_t *b, int shm, const uint8_t *msg, size_t size, int n)
{
    sink_t *s = shm ? &shm_sink : &lcm_sink;
    for (int i = 0; i < n; i++) {
        long before = s->got[0];
        if (shm && b->loaned)   /* the message made in the slot before the clock starts */
            memcpy(marie_shm_pub_loan(b->pub), msg, size);
        s->t0 = marie_mono_us();
        if (shm && b->loaned)
            marie_shm_pub_commit(b->pub, size);
        else if (shm)
            marie_shm_pub_publish(b->pub, msg, size);
        else
            lcm_publish(b->tx, "BENCH_SHM_RAW", msg, (unsigned)size);
        for (int64_t end = marie_mono_us() + 200000; s->got[0] == before && marie_mono_us() < end;)
            lcm_handle_timeout(b->rx[0], 20);
        for (int k = 1; k < NSUB; k++)
            while (lcm_handle_timeout(b->rx[k], 0) > 0)
                ;
    }
}

static void run_size(bus_t *b, const char *label, size_t size, int n)
{
    uint8_t *msg = calloc(1, size);
    msg[0] = 0x12;              /* a fingerprint, as a real payload starts with */
    for (int pass = 0; pass < 2; pass++) {
        shm_sink.n = lcm_sink.n = 0;
        for (int blk = 0; blk < 10; blk++) {  /* interleaved: drift hits both alike */
            latency(b, 1, msg, size, n / 10);
            latency(b, 0, msg, size, n / 10);
        }
        if (pass == 0)
            continue;
        char m[64];
        snprintf(m, sizeof m, "latency_p50_%s", label);
        row(m, pct(&shm_sink, 0.50), "us", pct(&lcm_sink, 0.50));
        snprintf(m, sizeof m, "latency_p99_%s", label);
        row(m, pct(&shm_sink, 0.99), "us", pct(&lcm_sink, 0.99));
    }
    free(msg);
}

/* 900 KB at 30 Hz for 2 s; every subscriber should get every message. */
static void loss_30hz(bus_t *b)
{
    const size_t size = 900 * 1024;
    const int n = 60;
    uint8_t *msg = calloc(1, size);
    msg[0] = 0x12;
    for (int shm = 1; shm >= 0; shm--) {
        sink_t *s = shm ? &shm_sink : &lcm_sink;
        for (int64_t end = marie_mono_us() + 200000; marie_mono_us() < end;)
            drain(b, 1);        /* what the latency runs left queued is not counted here */
        memset(s->got, 0, sizeof s->got);
        int64_t next = marie_mono_us();
        for (int i = 0; i < n; i++) {
            if (shm)
                marie_shm_pub_publish(b->pub, msg, size);
            else
                lcm_publish(b->tx, "BENCH_SHM_RAW", msg, (unsigned)size);
            next += 33333;
            while (marie_mono_us() < next)
                drain(b, 1);
        }
        for (int64_t end = marie_mono_us() + 200000; marie_mono_us() < end;)
            drain(b, 1);
    }
    long shm_lost = 0, lcm_lost = 0;
    for (int k = 0; k < NSUB; k++) {
        shm_lost += n - shm_sink.got[k];
        lcm_lost += n - lcm_sink.got[k];
    }
    row("lost_900KB_30Hz_3subs",
        (double)shm_lost, "msgs", (double)lcm_lost);
    free(msg);
}

int main(void)
{
    bus_t b = {0};
    const char *url = marie_default_url();
    b.tx = lcm_create(url);
    for (int k = 0; k < NSUB; k++)
        b.rx[k] = lcm_create(url);
    b.pub = b.tx ? marie_shm_pub_create(b.tx, "BENCH_SHM", 1024 * 1024, 8) : NULL;
    if (!b.pub || !b.rx[0] || !b.rx[1] || !b.rx[2]) {
        fprintf(stderr, "bench_shm: cannot set up LCM or the ring\n");
        return 1;
    }
    marie_shm_sub_t *subs[NSUB];
    for (int k = 0; k < NSUB; k++) {
        subs[k] = marie_shm_sub_create(b.rx[k], "BENCH_SHM", 1024 * 1024, on_shm, &shm_sink.got[k]);
        lcm_subscription_t *raw = lcm_subscribe(b.rx[k], "BENCH_SHM_RAW", on_lcm, &lcm_sink.got[k]);
        lcm_subscription_set_queue_capacity(raw, 256);
        if (!subs[k])
            return 1;
    }
    printf("# bench\tmetric\tvalue\tunit\tbaseline (plain LCM, same run)\tratio\n");
    run_size(&b, "8KB", 8 * 1024, 400);
    run_size(&b, "900KB", 900 * 1024, 200);
    loss_30hz(&b);
    /* In place: the subscriber's callback sees the bytes in the ring (one copy less). */
    for (int k = 0; k < NSUB; k++)
        marie_shm_sub_in_place(subs[k], on_verdict);
    run_size(&b, "900KB_in_place", 900 * 1024, 200);
    loss_30hz(&b);
    /* And a loan: the writer makes the message in the slot, so no copy is left at all. */
    b.loaned = true;
    run_size(&b, "900KB_loaned_in_place", 900 * 1024, 200);
    b.loaned = false;
    fprintf(stderr, "bench_shm: %ld in-place deliveries found overwritten afterwards\n", torn);
    long lost = 0;
    for (int k = 0; k < NSUB; k++)
        lost += marie_shm_sub_stats(subs[k])->lost;
    fprintf(stderr, "bench_shm: %ld shared-memory messages overwritten before they were read\n", lost);
    for (int k = 0; k < NSUB; k++)
        marie_shm_sub_destroy(subs[k]);
    marie_shm_pub_destroy(b.pub);
    for (int k = 0; k < NSUB; k++)
        lcm_destroy(b.rx[k]);
    lcm_destroy(b.tx);
    return 0;
}
