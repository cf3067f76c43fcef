/* vlms200: virtual LMS200 behind the master side of a pty; the driver under test opens the
 * slave exactly like /dev/ttyUSB0. */
#include "hw/lms200/vlms200.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <pty.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/err.h"
#include "core/loop.h"
#include "hw/lms200/serial.h"

#define OUT_CAP 65536
#define NGRID 361                   /* 0.5 deg grid over 180 deg */

struct vlms200 {
    vlms200_cfg_t cfg;
    lms200_unit_t unit;             /* cfg.units */
    char *link;
    int master, slave;
    char path[128];
    lms200_parser_t *parser;
    uint64_t seen_crc_errors;
    /* device state */
    int baud;
    int pending_baud;               /* takes effect once the reply has left */
    bool streaming;
    int angle_deg, res_cdeg;
    float ranges[NGRID];
    /* output */
    uint8_t out[OUT_CAP];
    size_t out_len;
    int64_t next_scan;
    int64_t release_at;             /* line_time: the queued bytes reach the host then */
    int64_t now;
    int64_t silent_until;
    int64_t back_at;                /* INT64_MAX: not scheduled */
    uint32_t rng;
    uint64_t scan_no;
    vlms200_scan_cb_t on_scan;
    void *on_scan_user;
    vlms200_stats_t st;
};

static void power_on(vlms200_t *v)
{
    v->baud = 9600;
    v->pending_baud = 0;
    v->streaming = false;
    v->angle_deg = 180;
    v->res_cdeg = 100;
    v->out_len = 0;
    v->next_scan = 0;
    v->release_at = 0;
    if (v->parser)
        lms200_parser_reset(v->parser);
}

static void on_command(void *user, const lms200_telegram_t *t);

vlms200_t *vlms200_create(const vlms200_cfg_t *cfg)
{
    static const vlms200_cfg_t defaults = VLMS200_DEFAULTS;
    cfg = cfg ? cfg : &defaults;
    if (!cfg->units || (strcmp(cfg->units, "mm") && strcmp(cfg->units, "cm")) || cfg->address < 0 ||
        cfg->address > 0x7f)
        return marie_fail_null(EINVAL);
    vlms200_t *v = calloc(1, sizeof *v);
    if (!v)
        return NULL;
    v->cfg = *cfg;
    v->cfg.units = NULL;        /* the caller's string is not kept: unit says it */
    v->unit = strcmp(cfg->units, "mm") == 0 ? LMS200_UNIT_MM : LMS200_UNIT_CM;
    if (v->cfg.rate_hz <= 0)
        v->cfg.rate_hz = 75;
    v->master = v->slave = -1;
    v->back_at = INT64_MAX;
    v->rng = 0x1234567u;
    v->parser = lms200_parser_create(on_command, NULL, v);
    if (!v->parser) {
        free(v);
        return NULL;
    }
    for (int i = 0; i < NGRID; i++)
        v->ranges[i] = 1.0f + 0.005f * (float)i;
    power_on(v);
    return v;
}

/* The link goes first, as udev removes /dev/ttyUSB0 and its by-id link with the adapter: left
 * behind, it names a freed pty number that the kernel gives to the next pty anyone opens, and a
 * driver reopening it talks to that program's device (another test's emulator, in a parallel
 * make test) instead of finding nothing until this one is back. */
static void close_pty(vlms200_t *v)
{
    if (v->link)
        unlink(v->link);
    if (v->master >= 0)
        close(v->master);
    if (v->slave >= 0)
        close(v->slave);
    v->master = v->slave = -1;
    v->path[0] = 0;
}

void vlms200_destroy(vlms200_t *v)
{
    if (!v)
        return;
    close_pty(v);
    free(v->link);
    lms200_parser_destroy(v->parser);
    free(v);
}

static int make_pty(vlms200_t *v)
{
    int m, s;
    if (openpty(&m, &s, v->path, NULL, NULL) < 0)
        return -1;
    /* Raw from the start: a canonical, echoing slave would bounce our scans back to us
     * before the driver has set its line up. We keep the slave open so that the master
     * never reads EIO while the driver reopens it. */
    if (lms200_serial_setup(s, 9600) < 0) {
        MARIE_KEEP_ERRNO(close(m); close(s));
        return -1;
    }
    fcntl(m, F_SETFL, fcntl(m, F_GETFL) | O_NONBLOCK);
    fcntl(m, F_SETFD, FD_CLOEXEC);
    fcntl(s, F_SETFD, FD_CLOEXEC);
    v->master = m;
    v->slave = s;
    if (v->link) {
        char tmp[512];
        snprintf(tmp, sizeof tmp, "%s.tmp%d", v->link, (int)getpid());
        unlink(tmp);
        if (symlink(v->path, tmp) < 0 || rename(tmp, v->link) < 0) {
            MARIE_KEEP_ERRNO(unlink(tmp); close_pty(v));
            return -1;
        }
    }
    power_on(v);
    return 0;
}

int vlms200_open(vlms200_t *v, const char *link)
{
    close_pty(v);
    free(v->link);
    v->link = link ? strdup(link) : NULL;
    if (link && !v->link)
        return marie_fail(ENOMEM);
    return make_pty(v);
}

const char *vlms200_path(const vlms200_t *v) { return v->path; }
int vlms200_fd(const vlms200_t *v) { return v->master; }
int vlms200_baud(const vlms200_t *v) { return v->baud; }
bool vlms200_streaming(const vlms200_t *v) { return v->streaming; }
int vlms200_res_cdeg(const vlms200_t *v) { return v->res_cdeg; }
const vlms200_stats_t *vlms200_stats(const vlms200_t *v) { return &v->st; }

/* What the host has not read: the slave's queue (the kernel's too, see marie_fd_unread) and the
 * bytes still held here because the line was full. */
int vlms200_host_unread(const vlms200_t *v)
{
    return v->slave < 0 ? 0 : marie_fd_unread(v->slave);
}

int vlms200_unread(const vlms200_t *v)
{
    return v->slave < 0 ? 0 : vlms200_host_unread(v) + (int)v->out_len;
}

short vlms200_events(const vlms200_t *v)
{
    if (v->master < 0)
        return 0;
    return (short)(POLLIN | (v->out_len ? POLLOUT : 0));
}

static uint32_t rnd(vlms200_t *v)
{
    v->rng = v->rng * 1103515245u + 12345u;
    return v->rng >> 8;
}

static bool host_rate_matches(vlms200_t *v)
{
    if (v->cfg.ignore_baud)
        return true;
    return lms200_serial_get_baud(v->master) == v->baud;
}

static void queue(vlms200_t *v, const uint8_t *b, size_t n)
{
    if (n > OUT_CAP - v->out_len)
        return;     /* the host stopped reading: a real device just keeps talking into the void */
    memcpy(v->out + v->out_len, b, n);
    v->out_len += n;
}

static void flush_out(vlms200_t *v)
{
    if (v->master < 0 || v->out_len == 0 || v->now < v->release_at)
        return;
    bool garble = !host_rate_matches(v);
    if (garble) {
        /* What a UART at another rate makes of our bytes; what does not fit is lost. */
        for (size_t i = 0; i < v->out_len; i++)
            v->out[i] ^= 0x55;
        v->st.baud_mismatch_bytes += (int64_t)v->out_len;
    }
    ssize_t n = write(v->master, v->out, v->out_len);
    if (garble || (n < 0 && errno == EAGAIN)) {
        /* A UART sends at its rate whether or not anyone listens: what the host's full
         * buffer (a dead or stalled host) does not take is lost, not queued for later. */
        if (!garble)
            v->st.lost_bytes += (int64_t)v->out_len;
        n = (ssize_t)v->out_len;
    }
    if (n > 0) {
        memmove(v->out, v->out + n, v->out_len - (size_t)n);
        v->out_len -= (size_t)n;
    }
    if (v->out_len == 0 && v->pending_baud) {
        v->baud = v->pending_baud;
        v->pending_baud = 0;
        v->st.baud_changes++;
    }
}

static uint16_t raw_value(const vlms200_t *v, double m)
{
    double scale = v->unit == LMS200_UNIT_MM ? 1000.0 : 100.0;
    if (!isfinite(m) || m < 0 || m * scale >= LMS200_VALUE_ERROR_MIN)
        return 0x1FFF;
    return (uint16_t)lround(m * scale);
}

double vlms200_expected_range(const vlms200_t *v, int i, int res_cdeg)
{
    int g = res_cdeg == 50 ? i : 2 * i;
    if (g < 0 || g >= NGRID)
        return NAN;
    uint16_t raw = raw_value(v, v->ranges[g]);
    return lms200_value_m(raw, v->unit);
}

void vlms200_set_ranges(vlms200_t *v, const float *m, size_t n)
{
    if (n < 2)
        return;
    for (int g = 0; g < NGRID; g++) {
        double x = (double)g * (double)(n - 1) / (NGRID - 1);
        size_t k = (size_t)x;
        if (k >= n - 1) {
            v->ranges[g] = m[n - 1];
            continue;
        }
        double f = x - (double)k;
        v->ranges[g] = (float)(m[k] * (1 - f) + m[k + 1] * f);
    }
}

void vlms200_on_scan(vlms200_t *v, vlms200_scan_cb_t cb, void *user)
{
    v->on_scan = cb;
    v->on_scan_user = user;
}

/* What n bytes take on the line: 10 bits each at the current rate. */
static int64_t wire_us(const vlms200_t *v, size_t n)
{
    return lms200_wire_us(n, v->baud);
}

static void send_scan(vlms200_t *v)
{
    if (v->on_scan)
        v->on_scan(v->on_scan_user, v, v->now);
    uint16_t vals[NGRID];
    int n = v->res_cdeg == 50 ? 361 : v->res_cdeg == 25 ? 401 : 181;
    int step = v->res_cdeg == 100 ? 2 : 1;
    if (n > 361)
        n = 361;    /* 100 deg at 0.25 deg is accepted but sent as the 0.5 deg grid */
    for (int i = 0; i < n; i++)
        vals[i] = raw_value(v, v->ranges[i * step]);
    uint8_t tg[LMS200_MAX_TELEGRAM];
    size_t len = lms200_encode_scan(tg, sizeof tg, (uint8_t)v->cfg.address, v->unit, vals, (size_t)n, 0x10);
    uint64_t k = ++v->scan_no;
    if (v->cfg.garbage_every > 0 && k % (uint64_t)v->cfg.garbage_every == 0)
        vlms200_inject_garbage(v, 1 + rnd(v) % 32);
    if (v->cfg.corrupt_every > 0 && k % (uint64_t)v->cfg.corrupt_every == 0) {
        tg[len - 1] ^= 0x5a;
        v->st.corrupted++;
    }
    if (v->cfg.truncate_every > 0 && k % (uint64_t)v->cfg.truncate_every == 0) {
        len /= 2;
        v->st.truncated++;
    }
    queue(v, tg, len);
    if (v->cfg.line_time)
        v->release_at = v->now + wire_us(v, len);
    v->st.scans_sent++;
}

void vlms200_inject_garbage(vlms200_t *v, size_t n)
{
    uint8_t g[64];
    while (n > 0) {
        size_t k = n < sizeof g ? n : sizeof g;
        for (size_t i = 0; i < k; i++)
            g[i] = (uint8_t)rnd(v);
        queue(v, g, k);
        v->st.garbage_bytes += (int64_t)k;
        n -= k;
    }
}

static void reply_mode(vlms200_t *v, uint8_t result)
{
    uint8_t ack = LMS200_ACK, tg[16];
    queue(v, &ack, 1);
    queue(v, tg, lms200_encode_mode_reply(tg, sizeof tg, (uint8_t)v->cfg.address, result, 0x10));
}

static void nak(vlms200_t *v)
{
    uint8_t b = LMS200_NAK;
    queue(v, &b, 1);
    v->st.naks_sent++;
}

static void on_command(void *user, const lms200_telegram_t *t)
{
    vlms200_t *v = user;
    if ((t->addr & LMS200_REPLY_BIT) || t->addr != (uint8_t)v->cfg.address)
        return;     /* another device's telegram, or a reply looped back */
    v->st.commands++;
    switch (t->cmd) {
    case LMS200_CMD_MODE: {
        if (t->data_len < 1) {
            nak(v);
            return;
        }
        uint8_t mode = t->data[0];
        int baud = lms200_mode_baud(mode);
        if (mode == LMS200_MODE_INSTALL) {
            bool ok = t->data_len == 9 && memcmp(t->data + 1, LMS200_PASSWORD, 8) == 0;
            reply_mode(v, ok ? LMS200_MODE_OK : LMS200_MODE_BAD_PASSWORD);
        } else if (mode == LMS200_MODE_CONTINUOUS) {
            reply_mode(v, LMS200_MODE_OK);
            v->streaming = true;
            v->next_scan = v->now;
        } else if (mode == LMS200_MODE_STOP) {
            reply_mode(v, LMS200_MODE_OK);
            v->streaming = false;
        } else if (baud) {
            reply_mode(v, LMS200_MODE_OK);
            v->pending_baud = baud;     /* the reply still goes out at the old rate */
        } else {
            reply_mode(v, LMS200_MODE_NOT_POSSIBLE);
        }
        break;
    }
    case LMS200_CMD_VARIANT: {
        if (t->data_len < 4) {
            nak(v);
            return;
        }
        int angle = t->data[0] | (t->data[1] << 8);
        int res = t->data[2] | (t->data[3] << 8);
        bool ok = (angle == 180 && (res == 100 || res == 50)) ||
                  (angle == 100 && (res == 100 || res == 50 || res == 25));
        if (ok) {
            v->angle_deg = angle;
            v->res_cdeg = res;
        }
        uint8_t ack = LMS200_ACK, tg[24];
        queue(v, &ack, 1);
        queue(v, tg, lms200_encode_variant_reply(tg, sizeof tg, (uint8_t)v->cfg.address, ok,
                                                 (uint16_t)v->angle_deg, (uint16_t)v->res_cdeg, 0x10));
        break;
    }
    case LMS200_CMD_REQUEST: {
        uint8_t ack = LMS200_ACK;
        queue(v, &ack, 1);
        send_scan(v);
        break;
    }
    default:
        nak(v);
        break;
    }
}

void vlms200_io(vlms200_t *v, short revents, int64_t now_us)
{
    v->now = now_us;
    if (v->master < 0)
        return;
    if (revents & POLLIN) {
        uint8_t buf[1024];
        ssize_t n;
        while ((n = read(v->master, buf, sizeof buf)) > 0) {
            if (now_us < v->silent_until)
                continue;
            if (!host_rate_matches(v)) {
                v->st.baud_mismatch_bytes += n;
                continue;
            }
            lms200_parser_feed(v->parser, buf, (size_t)n);
            uint64_t crc = lms200_parser_stats(v->parser)->crc_errors;
            if (crc != v->seen_crc_errors) {
                v->seen_crc_errors = crc;
                nak(v);
            }
        }
    }
    if (now_us >= v->silent_until)
        flush_out(v);
}

void vlms200_tick(vlms200_t *v, int64_t now_us)
{
    v->now = now_us;
    if (v->master < 0) {
        if (now_us >= v->back_at) {
            v->back_at = INT64_MAX;
            if (make_pty(v) < 0)
                v->back_at = now_us + 100000;   /* out of ptys: try again shortly */
        }
        return;
    }
    if (now_us < v->silent_until) {
        v->out_len = 0;
        return;
    }
    if (v->streaming && now_us >= v->next_scan) {
        /* The line limits the rate too: 10 bits per byte at the current speed. */
        int n = v->res_cdeg == 100 ? 181 : 361;
        int64_t wire = wire_us(v, 4 + 4 + 2 * (size_t)n + 2);
        int64_t period = (int64_t)(1e6 / v->cfg.rate_hz);
        if (period < wire)
            period = wire;
        if (v->out_len < LMS200_MAX_TELEGRAM)
            send_scan(v);
        else
            v->st.dropped_scans++;
        v->next_scan += period;
        if (v->next_scan < now_us)
            v->next_scan = now_us + period;
    }
    flush_out(v);
}

int64_t vlms200_deadline(const vlms200_t *v)
{
    if (v->master < 0)
        return v->back_at;
    if (v->now < v->silent_until)
        return v->silent_until;
    int64_t d = v->streaming ? v->next_scan : INT64_MAX;
    return v->out_len && v->release_at > v->now && v->release_at < d ? v->release_at : d;
}

bool vlms200_sends_at(const vlms200_t *v, int64_t now_us)
{
    if (v->master < 0 || now_us < v->silent_until)
        return false;
    if (v->out_len && now_us >= v->release_at)
        return true;
    return v->streaming && now_us >= v->next_scan && !v->cfg.line_time;
}

void vlms200_silence(vlms200_t *v, int64_t until_us)
{
    v->silent_until = until_us;
}

void vlms200_unplug(vlms200_t *v, int64_t now_us, int64_t back_after_us)
{
    close_pty(v);
    v->st.unplugs++;
    v->streaming = false;
    v->out_len = 0;
    v->back_at = back_after_us < 0 ? INT64_MAX : now_us + back_after_us;
}
