/* driver: LMS200 init sequence and stream supervision over one serial fd (no threads, no sleeps,
 * no blocking writes: the caller's loop feeds it fd events and deadlines). */
#include "hw/lms200/driver.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <poll.h>
#include <sys/ioctl.h>

#include "core/err.h"
#include "hw/lms200/serial.h"
#include "core/log.h"

#define MAX_PROBE 6
/* Extra probe rounds at a rate where the line talks but the device has not answered yet
 * (it finishes the telegram it is sending first: 0.76 s for 361 values at 9600 baud). */
#define MAX_STAY 3
#define READ_CHUNK 4096
#define READ_MAX (16 * READ_CHUNK)         /* what one read_input takes at most */
#define PERIOD_GAPS 15              /* single arrivals whose median gap is the period */
#define BATCH_MAX 8                 /* scans of one read stamped together; a longer backlog goes out in turns */
/* Damaged scan telegrams in a row that do not yet make a silent line (see data_timeout_us). */
#define LOST_TELEGRAMS 2
#define DATA_MARGIN_US 200000

struct lms200_driver {
    lms200_driver_cfg_t cfg;
    int res_cdeg;                   /* the resolution in 1/100 degree: 50 or 100 */
    char *device;
    lms200_driver_ops_t ops;
    void *user;
    lms200_parser_t *parser;
    lms200_parser_stats_t seen;     /* parser counters already reported */
    int fd;
    uint8_t out[64];                /* command bytes the line had no room for yet */
    size_t nout;
    int baud;                       /* the line's current rate */
    lms200_drv_state_t state;
    int64_t deadline;
    int64_t now;                    /* time of the event being handled */
    int tries;                      /* sends of the current command */
    int probe[MAX_PROBE], nprobe, probe_idx;
    bool lost;                      /* streaming was lost: the next stream is a reconnect */
    bool open_failed_reported;
    bool nak_seen;
    /* Evidence about the rate being probed: a device left streaming talks all the time, so
     * a good telegram proves the rate and a flood of garbage disproves it. */
    bool rate_heard;
    int64_t rate_bytes, rate_garbage;
    int stay;
    bool running;                   /* between start and stop */
    bool degraded;
    int64_t last_good;              /* last good scan (or the start), for degraded_ms */
    /* Scans completed by one read: stamped together once it is done (see deliver()). */
    lms200_scan_t batch[BATCH_MAX];
    int nbatch;
    int64_t period_us;              /* the device's scan period as the arrivals show it; 0: not yet */
    int32_t gaps[PERIOD_GAPS];      /* the last gaps between single arrivals, for period_us */
    int ngaps;
    int read_expected, read_done;   /* scans the line held at this read, and those delivered */
    int64_t last_arrival, last_stamp;
    lms200_driver_stats_t st;
};

static const char *state_names[] = { "closed", "probe", "variant", "baud", "start", "stream" };

static const char *lms200_driver_state_name(lms200_drv_state_t s)
{
    return (unsigned)s < sizeof state_names / sizeof state_names[0] ? state_names[s] : "?";
}

static void emit(lms200_driver_t *d, int sev, const char *kind, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void emit(lms200_driver_t *d, int sev, const char *kind, const char *fmt, ...)
{
    if (!d->ops.on_event)
        return;
    char text[256];
    MARIE_VFORMAT(text, fmt);
    d->ops.on_event(d->user, sev, kind, text);
}

static void count(lms200_driver_t *d, const char *name, int64_t *field, int64_t delta, bool bad)
{
    *field += delta;
    if (d->ops.on_count && delta)
        d->ops.on_count(d->user, name, delta, bad);
}

static void set_fd(lms200_driver_t *d, int fd)
{
    int old = d->fd;
    d->fd = fd;
    if (old != fd && d->ops.on_fd)
        d->ops.on_fd(d->user, old, fd);
}

static void enter(lms200_driver_t *d, lms200_drv_state_t s);

static void close_line(lms200_driver_t *d)
{
    int fd = d->fd;
    if (fd < 0)
        return;
    set_fd(d, -1);
    close(fd);
    d->nout = 0;
    lms200_parser_reset(d->parser);
}

static void hangup(lms200_driver_t *d, const char *why)
{
    count(d, "disconnects", &d->st.disconnects, 1, false);
    emit(d, 2, "laser_disconnected", "%s: %s (state %s); reopening every %lld ms",
         d->device, why, lms200_driver_state_name(d->state), (long long)d->cfg.reopen_ms);
    d->lost = true;
    close_line(d);
    d->state = LMS200_DRV_CLOSED;
    d->deadline = d->now + (int64_t)d->cfg.reopen_ms * 1000;
}

/* Candidate rates, the likeliest first, without duplicates. */
static void build_probe(lms200_driver_t *d, int first)
{
    const int cand[] = { first, 9600, (int)d->cfg.baud, 38400, 19200, 500000 };
    d->nprobe = 0;
    for (size_t i = 0; i < sizeof cand / sizeof cand[0]; i++) {
        bool dup = false;
        for (int k = 0; k < d->nprobe; k++)
            dup |= d->probe[k] == cand[i];
        if (!dup && lms200_serial_speed(cand[i]))
            d->probe[d->nprobe++] = cand[i];
    }
    d->probe_idx = 0;
}

/* Forget what was heard at the previous rate (the line's input is flushed with it). */
static void new_rate(lms200_driver_t *d)
{
    d->rate_heard = false;
    d->rate_bytes = d->rate_garbage = 0;
    d->stay = 0;
    d->nak_seen = false;
}

static int set_line_baud(lms200_driver_t *d, int baud)
{
    int r = lms200_serial_set_baud(d->fd, baud);
    if (r == 0)
        d->baud = baud;
    d->nout = 0;                    /* a command meant for the old rate */
    MARIE_KEEP_ERRNO(lms200_parser_reset(d->parser); new_rate(d));
    return r;
}

/* Bytes flow at this rate but none of them ever formed a telegram: the device streams at
 * another rate. (A telegram cut by our switching in is at most one telegram of garbage.) */
static bool wrong_rate(const lms200_driver_t *d)
{
    return !d->rate_heard && d->rate_garbage > LMS200_MAX_TELEGRAM;
}

/* Worth more probe rounds at this rate: the device was heard, or bytes flow that may still
 * turn out to be its telegrams. */
static bool rate_promising(const lms200_driver_t *d)
{
    return d->rate_heard || (d->rate_bytes > 0 && !wrong_rate(d));
}

static void write_failed(lms200_driver_t *d)
{
    char why[96];
    snprintf(why, sizeof why, "write failed: %s", strerror(errno));
    hangup(d, why);
}

/* Send what is held, as far as the line takes it now. */
static void flush_out(lms200_driver_t *d)
{
    if (d->nout == 0)
        return;
    ssize_t r = lms200_serial_write(d->fd, d->out, d->nout);
    if (r < 0) {
        write_failed(d);
        return;
    }
    memmove(d->out, d->out + r, d->nout - (size_t)r);
    d->nout -= (size_t)r;
}

/* A command goes out behind what is held; the rest waits for POLLOUT (lms200_driver_events).
 * A command with no room left is dropped: its reply timeout sends it again. */
static void write_out(lms200_driver_t *d, const uint8_t *buf, size_t n)
{
    flush_out(d);
    if (d->fd < 0)
        return;
    ssize_t r = 0;
    if (d->nout == 0 && (r = lms200_serial_write(d->fd, buf, n)) < 0) {
        write_failed(d);
        return;
    }
    size_t rest = n - (size_t)r;
    if (rest > 0 && d->nout + rest <= sizeof d->out) {
        memcpy(d->out + d->nout, buf + r, rest);
        d->nout += rest;
    }
}

static void send_current(lms200_driver_t *d)
{
    uint8_t out[32];
    size_t n = 0;
    switch (d->state) {
    case LMS200_DRV_PROBE:
        n = lms200_encode_mode(out, sizeof out, (uint8_t)d->cfg.address, LMS200_MODE_STOP, NULL);
        break;
    case LMS200_DRV_VARIANT:
        n = lms200_encode_variant(out, sizeof out, (uint8_t)d->cfg.address, 180, (uint16_t)d->res_cdeg);
        break;
    case LMS200_DRV_BAUD:
        n = lms200_encode_mode(out, sizeof out, (uint8_t)d->cfg.address, (uint8_t)lms200_baud_mode((int)d->cfg.baud), NULL);
        break;
    case LMS200_DRV_START:
        n = lms200_encode_mode(out, sizeof out, (uint8_t)d->cfg.address, LMS200_MODE_CONTINUOUS, NULL);
        break;
    default:
        return;
    }
    d->tries++;
    int wait_ms = d->state == LMS200_DRV_PROBE ? d->cfg.reply_timeout_ms : d->cfg.config_timeout_ms;
    d->deadline = d->now + (int64_t)wait_ms * 1000;
    write_out(d, out, n);
}

/* No good scan for this long while streaming: the line is silent. One damaged telegram leaves
 * two telegram times between good scans (1.52 s for 361 values at 9600 baud), longer than a
 * fixed second: the wait is data_timeout_ms, or LOST_TELEGRAMS + 1 telegram times at the
 * line's rate (and a margin) where that is longer. */
static int64_t data_timeout_us(const lms200_driver_t *d)
{
    size_t bytes = lms200_scan_telegram_len(d->res_cdeg == 50 ? 361 : 181);
    int64_t derived = (LOST_TELEGRAMS + 1) * lms200_wire_us(bytes, d->baud) + DATA_MARGIN_US;
    int64_t fixed = (int64_t)d->cfg.data_timeout_ms * 1000;
    return derived > fixed ? derived : fixed;
}

static void enter(lms200_driver_t *d, lms200_drv_state_t s)
{
    d->state = s;
    d->tries = 0;
    if (s == LMS200_DRV_STREAM) {
        d->deadline = d->now + data_timeout_us(d);
        return;
    }
    send_current(d);
}

/* Start over from "stop continuous output" at the rate the line has now. */
static void reinit(lms200_driver_t *d)
{
    d->ngaps = 0;               /* the stream that comes may have another period */
    d->last_arrival = 0;
    build_probe(d, d->baud);
    lms200_parser_reset(d->parser);
    new_rate(d);
    enter(d, LMS200_DRV_PROBE);
}

static void try_open(lms200_driver_t *d)
{
    int fd = lms200_serial_open(d->device);
    if (fd < 0) {
        if (!d->open_failed_reported)
            emit(d, 2, "laser_open_failed", "cannot open %s: %s; retrying every %lld ms",
                 d->device, strerror(errno), (long long)d->cfg.reopen_ms);
        d->open_failed_reported = true;
        d->deadline = d->now + (int64_t)d->cfg.reopen_ms * 1000;
        return;
    }
    d->open_failed_reported = false;
    d->baud = 9600;
    lms200_parser_reset(d->parser);
    new_rate(d);
    set_fd(d, fd);
    build_probe(d, 9600);
    enter(d, LMS200_DRV_PROBE);
}

static void streaming_started(lms200_driver_t *d)
{
    d->st.inits++;
    if (d->lost) {
        count(d, "reconnects", &d->st.reconnects, 1, false);
        emit(d, 1, "laser_reconnected", "%s streaming again at %d baud, %s deg resolution",
             d->device, d->baud, d->res_cdeg == 50 ? "0.5" : "1");
    } else {
        emit(d, 1, "laser_streaming", "%s streaming at %d baud, %s deg resolution",
             d->device, d->baud, d->res_cdeg == 50 ? "0.5" : "1");
    }
    d->lost = false;
    enter(d, LMS200_DRV_STREAM);
}

static void on_mode_reply(lms200_driver_t *d, uint8_t result)
{
    if (d->state != LMS200_DRV_PROBE && d->state != LMS200_DRV_BAUD && d->state != LMS200_DRV_START)
        return;
    if (result != LMS200_MODE_OK) {
        emit(d, 2, "laser_mode_refused", "%s refused the %s step (result %u); retrying",
             d->device, lms200_driver_state_name(d->state), result);
        return;     /* the reply timeout resends */
    }
    switch (d->state) {
    case LMS200_DRV_PROBE:
        enter(d, LMS200_DRV_VARIANT);
        break;
    case LMS200_DRV_BAUD: {
        /* The device answered at the old rate and now listens at the new one. */
        int r = set_line_baud(d, (int)d->cfg.baud);
        if (r < 0) {
            emit(d, 3, "laser_baud_failed", "cannot set %s to %d baud: %s", d->device, (int)d->cfg.baud, strerror(errno));
            reinit(d);
            break;
        }
        enter(d, LMS200_DRV_START);
        break;
    }
    case LMS200_DRV_START:
        streaming_started(d);
        break;
    default:
        break;
    }
}

static void on_variant_reply(lms200_driver_t *d, const lms200_variant_t *v)
{
    if (d->state != LMS200_DRV_VARIANT)
        return;
    if (!v->ok || v->angle_deg != 180 || v->res_cdeg != d->res_cdeg) {
        emit(d, 3, "laser_variant_refused", "%s refused variant 180 deg / %d cdeg (answered ok=%d %u/%u)",
             d->device, d->res_cdeg, v->ok, v->angle_deg, v->res_cdeg);
        return;
    }
    if (d->baud == (int)d->cfg.baud)
        enter(d, LMS200_DRV_START);
    else
        enter(d, LMS200_DRV_BAUD);
}

static void deliver(lms200_driver_t *d);

static void on_scan(lms200_driver_t *d, const lms200_telegram_t *t)
{
    if (d->state != LMS200_DRV_STREAM)
        return;     /* the tail of an earlier stream while re-initialising */
    if (d->nbatch == BATCH_MAX)
        deliver(d);
    lms200_scan_t *scan = &d->batch[d->nbatch];
    int want = d->res_cdeg == 50 ? 361 : 181;
    if (lms200_decode_scan(t, scan) < 0 || scan->n != want || scan->partial) {
        count(d, "bad_scans", &d->st.bad_scans, 1, true);
        return;
    }
    d->nbatch++;
    d->st.scans++;
    d->deadline = d->now + data_timeout_us(d);
    d->last_good = d->now;
    if (d->degraded) {
        d->degraded = false;
        if (d->ops.on_health) {
            char why[160];
            snprintf(why, sizeof why, "%s: scans again at %d baud", d->device, d->baud);
            d->ops.on_health(d->user, false, why);
        }
    }
}

static int cmp_gap(const void *a, const void *b)
{
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

/* The period is the median gap of the last PERIOD_GAPS single arrivals: a read late makes one
 * gap long and the next short, a damaged telegram one gap double, and neither moves a median.
 * It used to start at the first gap and follow only gaps within half to twice it: a first scan
 * read 15 ms late on a loaded machine left a 5 ms period for good, and a backlog stamped 5 ms
 * apart. */
static void learn_period(lms200_driver_t *d, int64_t dt)
{
    if (dt <= 0 || dt > INT32_MAX)
        return;
    d->gaps[d->ngaps++ % PERIOD_GAPS] = (int32_t)dt;
    int n = d->ngaps < PERIOD_GAPS ? d->ngaps : PERIOD_GAPS;
    int32_t g[PERIOD_GAPS];
    memcpy(g, d->gaps, (size_t)n * sizeof g[0]);
    qsort(g, (size_t)n, sizeof g[0], cmp_gap);
    d->period_us = g[n / 2];
}

/* The scans one read completed. A device streams at its own fixed period, so when a read
 * brings several (the driver was late: a loaded machine, a stalled loop) they were sent one
 * period apart and only the last arrived just now: each is stamped back from the read by the
 * period the single arrivals show, never at or before the scan delivered before it (which
 * would put two scans of a turning robot at one instant). */
static void deliver(lms200_driver_t *d)
{
    int n = d->nbatch;
    d->nbatch = 0;
    if (n == 0)
        return;
    if (n == 1 && d->last_arrival > 0)
        learn_period(d, d->now - d->last_arrival);
    d->last_arrival = d->now;
    /* A read that brings more than a batch is delivered in turns: the scans still to come in
     * it (as the bytes the line held at the read count them) go after this batch. Stamped back
     * from the read alone, each batch after the first was pushed a period past the one before,
     * into the future (40 ms ahead of the clock after 250 ms held). */
    int later = d->read_expected - d->read_done - n;
    later = later > 0 ? later : 0;
    d->read_done += n;
    for (int i = 0; i < n; i++) {
        int64_t at = d->now - (int64_t)(n - 1 - i + later) * d->period_us;
        if (d->last_stamp && at <= d->last_stamp && d->last_stamp - at < 1000000)
            at = d->last_stamp + (d->period_us > 0 ? d->period_us : 1);
        d->last_stamp = at;
        if (d->ops.on_scan)
            d->ops.on_scan(d->user, &d->batch[i], d->res_cdeg, at);
    }
}

static void on_telegram(void *user, const lms200_telegram_t *t)
{
    lms200_driver_t *d = user;
    if (!(t->addr & LMS200_REPLY_BIT) || (t->addr & 0x7f) != (uint8_t)d->cfg.address)
        return;     /* our own echo, or another device on a shared RS-422 line */
    d->rate_heard = true;
    switch (t->cmd) {
    case LMS200_REPLY_MODE: {
        uint8_t res;
        if (lms200_decode_mode_reply(t, &res) == 0)
            on_mode_reply(d, res);
        break;
    }
    case LMS200_REPLY_VARIANT: {
        lms200_variant_t v;
        if (lms200_decode_variant_reply(t, &v) == 0)
            on_variant_reply(d, &v);
        break;
    }
    case LMS200_REPLY_SCAN:
        on_scan(d, t);
        break;
    default:
        break;
    }
}

static void on_ack(void *user, uint8_t b)
{
    lms200_driver_t *d = user;
    if (b == LMS200_NAK && d->state != LMS200_DRV_STREAM && d->state != LMS200_DRV_CLOSED) {
        count(d, "naks", &d->st.naks, 1, false);
        d->nak_seen = true;
    }
}

static void report_parser(lms200_driver_t *d)
{
    const lms200_parser_stats_t *s = lms200_parser_stats(d->parser);
    count(d, "crc_errors", &d->st.crc_errors, (int64_t)(s->crc_errors - d->seen.crc_errors), true);
    count(d, "truncated", &d->st.truncated, (int64_t)(s->truncated - d->seen.truncated), true);
    count(d, "oversized", &d->st.oversized, (int64_t)(s->oversized - d->seen.oversized), true);
    count(d, "garbage_bytes", &d->st.garbage_bytes, (int64_t)(s->garbage_bytes - d->seen.garbage_bytes), true);
    d->rate_garbage += (int64_t)(s->garbage_bytes - d->seen.garbage_bytes);
    d->seen = *s;
}

/* The resolution in 1/100 degree, -1 for one the device has not. */
static int res_cdeg(double deg)
{
    return fabs(deg - 0.5) < 1e-6 ? 50 : fabs(deg - 1.0) < 1e-6 ? 100 : -1;
}

static bool cfg_ok(const lms200_driver_cfg_t *c)
{
    return c->device && c->baud > 0 && c->baud <= 500000 && lms200_baud_mode((int)c->baud) >= 0 &&
           lms200_serial_speed((int)c->baud) && res_cdeg(c->resolution) > 0 && c->address >= 0 &&
           c->address <= 0x7f && c->reply_timeout_ms > 0 && c->config_timeout_ms > 0 && c->retries > 0 &&
           c->data_timeout_ms > 0 && c->reopen_ms > 0 && c->degraded_ms > 0;
}

lms200_driver_t *lms200_driver_create(const lms200_driver_cfg_t *cfg, const lms200_driver_ops_t *ops, void *user)
{
    if (!cfg_ok(cfg))
        return marie_fail_null(EINVAL);
    lms200_driver_t *d = calloc(1, sizeof *d);
    if (!d)
        return NULL;
    d->cfg = *cfg;
    d->res_cdeg = res_cdeg(cfg->resolution);
    if (ops)
        d->ops = *ops;
    d->user = user;
    d->fd = -1;
    d->baud = 9600;
    d->deadline = INT64_MAX;
    d->device = strdup(cfg->device);
    d->parser = lms200_parser_create(on_telegram, on_ack, d);
    if (!d->device || !d->parser)
        goto err;
    d->cfg.device = d->device;
    return d;
err:
    lms200_parser_destroy(d->parser);
    free(d->device);
    free(d);
    return marie_fail_null(ENOMEM);
}

void lms200_driver_destroy(lms200_driver_t *d)
{
    if (!d)
        return;
    if (d->fd >= 0)
        close(d->fd);
    lms200_parser_destroy(d->parser);
    free(d->device);
    free(d);
}

void lms200_driver_start(lms200_driver_t *d, int64_t now_us)
{
    d->now = now_us;
    d->running = true;
    d->last_good = now_us;
    if (d->fd >= 0)
        return;
    d->state = LMS200_DRV_CLOSED;
    try_open(d);
}

void lms200_driver_stop(lms200_driver_t *d)
{
    if (d->fd >= 0) {
        /* Best effort, as the line is closed right after: what it has no room for is lost,
         * and the next start stops the stream first anyway. */
        uint8_t out[16];
        size_t n = lms200_encode_mode(out, sizeof out, (uint8_t)d->cfg.address, LMS200_MODE_STOP, NULL);
        flush_out(d);
        if (d->fd >= 0 && d->nout == 0)
            (void)lms200_serial_write(d->fd, out, n);
        close_line(d);
    }
    d->state = LMS200_DRV_CLOSED;
    d->deadline = INT64_MAX;
    d->running = false;
    if (d->degraded) {
        d->degraded = false;
        if (d->ops.on_health)
            d->ops.on_health(d->user, false, "stopped");
    }
}

int lms200_driver_fd(const lms200_driver_t *d) { return d->fd; }
short lms200_driver_events(const lms200_driver_t *d) { return POLLIN | (d->nout > 0 ? POLLOUT : 0); }
bool lms200_driver_degraded(const lms200_driver_t *d) { return d->degraded; }

int64_t lms200_driver_deadline(const lms200_driver_t *d)
{
    if (d->running && !d->degraded && d->last_good + (int64_t)d->cfg.degraded_ms * 1000 < d->deadline)
        return d->last_good + (int64_t)d->cfg.degraded_ms * 1000;
    return d->deadline;
}
lms200_drv_state_t lms200_driver_state(const lms200_driver_t *d) { return d->state; }
int lms200_driver_baud(const lms200_driver_t *d) { return d->baud; }
int lms200_driver_data_timeout_ms(const lms200_driver_t *d) { return (int)(data_timeout_us(d) / 1000); }
const lms200_driver_stats_t *lms200_driver_stats(const lms200_driver_t *d) { return &d->st; }

static void read_input(lms200_driver_t *d, short revents);

/* How many whole scan telegrams the line holds now with what the parser has of one (what one
 * read_input can take): for the stamps of a read delivered in turns. */
static void count_waiting(lms200_driver_t *d)
{
    int avail = 0;
    size_t tlen = lms200_scan_telegram_len(d->res_cdeg == 50 ? 361 : 181);
    if (d->fd < 0 || ioctl(d->fd, FIONREAD, &avail) < 0 || avail < 0)
        avail = 0;
    avail = avail < READ_MAX ? avail : READ_MAX;
    d->read_expected = (int)(((size_t)avail + lms200_parser_pending(d->parser)) / tlen);
    d->read_done = 0;
}

void lms200_driver_io(lms200_driver_t *d, short revents, int64_t now_us)
{
    d->now = now_us;
    count_waiting(d);
    read_input(d, revents);
    deliver(d);
}

static void read_input(lms200_driver_t *d, short revents)
{
    if (d->fd < 0)
        return;
    if (revents & POLLOUT)
        flush_out(d);
    if (d->fd >= 0 && (revents & POLLIN)) {
        uint8_t buf[READ_CHUNK];
        for (int round = 0; round < READ_MAX / READ_CHUNK && d->fd >= 0; round++) {
            ssize_t n = read(d->fd, buf, sizeof buf);
            if (n > 0) {
                d->rate_bytes += n;
                lms200_parser_feed(d->parser, buf, (size_t)n);
                report_parser(d);
                if (d->state == LMS200_DRV_PROBE && wrong_rate(d))
                    d->deadline = d->now;   /* no use waiting here: the next tick moves on */
                if (d->nak_seen && d->fd >= 0) {
                    /* The device saw our command damaged: send again, but within the
                     * retries, since at a wrong rate any byte may read as a NAK. */
                    d->nak_seen = false;
                    if (d->tries < d->cfg.retries)
                        send_current(d);
                }
                if ((size_t)n < sizeof buf)
                    return;
                continue;
            }
            if (n < 0 && errno == EINTR)
                continue;
            if (n < 0 && errno == EAGAIN)
                return;
            /* 0 or EIO: the line is gone (a pty whose other end closed, a USB adapter pulled). */
            hangup(d, n == 0 ? "end of file" : strerror(errno));
            return;
        }
        return;
    }
    if (d->fd >= 0 && (revents & (POLLHUP | POLLERR | POLLNVAL)))
        hangup(d, revents & POLLHUP ? "hang-up" : "poll error");
}

/* No good scan for degraded_ms while started: say so once, until scans flow again. */
static void check_health(lms200_driver_t *d)
{
    if (!d->running || d->degraded || d->now - d->last_good < (int64_t)d->cfg.degraded_ms * 1000)
        return;
    d->degraded = true;
    count(d, "degraded", &d->st.degraded, 1, false);
    if (d->ops.on_health) {
        char why[200];
        snprintf(why, sizeof why, "no valid scan from %s for %lld ms (%s at %d baud)", d->device,
                 (long long)d->cfg.degraded_ms, lms200_driver_state_name(d->state), d->baud);
        d->ops.on_health(d->user, true, why);
    }
}

/* While streaming, a deadline or the health check due is judged on what the line holds by now,
 * not on what the driver had read before. A driver that could not run for longer than its data timeout (a
 * loaded machine, a real-time task holding the CPU) finds the scans the device sent meanwhile
 * waiting, and marie's loop runs its timers before it reads its fds: it declared a streaming
 * laser silent and re-initialised it, losing seconds of scans. */
static void read_due(lms200_driver_t *d, int64_t now_us)
{
    bool health_due = d->running && !d->degraded && now_us - d->last_good >= (int64_t)d->cfg.degraded_ms * 1000;
    if (d->fd < 0 || d->state != LMS200_DRV_STREAM || (now_us < d->deadline && !health_due))
        return;
    /* Only what is there: a raw line (VMIN 0, VTIME 0) reads 0 bytes when it has none, which
     * read_input takes for the end of the line (a pulled adapter). */
    int avail = 0;
    if (ioctl(d->fd, FIONREAD, &avail) < 0 || avail <= 0)
        return;
    count_waiting(d);
    read_input(d, POLLIN);
    deliver(d);
}

void lms200_driver_tick(lms200_driver_t *d, int64_t now_us)
{
    d->now = now_us;
    read_due(d, now_us);
    check_health(d);
    if (now_us < d->deadline)
        return;
    switch (d->state) {
    case LMS200_DRV_CLOSED:
        if (d->deadline != INT64_MAX)
            try_open(d);
        break;
    case LMS200_DRV_PROBE:
        if (d->tries < d->cfg.retries && !wrong_rate(d)) {
            send_current(d);
            break;
        }
        if (rate_promising(d) && d->stay < MAX_STAY) {
            d->stay++;
            d->tries = 0;
            send_current(d);
            break;
        }
        for (;;) {
            if (++d->probe_idx >= d->nprobe) {
                count(d, "timeouts", &d->st.timeouts, 1, false);
                emit(d, 2, "laser_not_found", "no LMS200 answer on %s at any rate; reopening", d->device);
                d->lost = true;
                close_line(d);
                d->state = LMS200_DRV_CLOSED;
                d->deadline = d->now + (int64_t)d->cfg.reopen_ms * 1000;
                return;
            }
            if (set_line_baud(d, d->probe[d->probe_idx]) == 0)
                break;
        }
        enter(d, LMS200_DRV_PROBE);
        break;
    case LMS200_DRV_VARIANT:
    case LMS200_DRV_BAUD:
    case LMS200_DRV_START:
        if (d->tries < d->cfg.retries) {
            send_current(d);
            break;
        }
        count(d, "timeouts", &d->st.timeouts, 1, false);
        emit(d, 2, "laser_init_timeout", "%s: no reply in step %s; starting over",
             d->device, lms200_driver_state_name(d->state));
        reinit(d);
        break;
    case LMS200_DRV_STREAM:
        count(d, "timeouts", &d->st.timeouts, 1, false);
        emit(d, 2, "laser_silent", "%s: no scan for %lld ms (%d baud); re-initialising", d->device,
             (long long)(data_timeout_us(d) / 1000), d->baud);
        d->lost = true;
        reinit(d);
        break;
    }
}
