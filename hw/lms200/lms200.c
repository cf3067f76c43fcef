/* lms200: SICK LMS200 telegram codec; no I/O, so every path is unit tested on byte strings. */
#include "hw/lms200/lms200.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"
#include "core/new.h"

uint16_t lms200_crc(const uint8_t *buf, size_t len)
{
    /* SICK's checksum from the LMS2xx telegram listing: shift the register left one bit per
     * byte (folding in the generator when the top bit falls out), then xor in the current
     * byte as the low half and the previous byte as the high half. */
    uint16_t crc = 0;
    uint8_t prev = 0;
    for (size_t i = 0; i < len; i++) {
        if (crc & 0x8000)
            crc = (uint16_t)(((crc & 0x7fff) << 1) ^ 0x8005);
        else
            crc = (uint16_t)(crc << 1);
        crc ^= (uint16_t)(buf[i] | (prev << 8));
        prev = buf[i];
    }
    return crc;
}

static uint16_t rd16(const uint8_t *b) { return (uint16_t)(b[0] | (b[1] << 8)); }
static void wr16(uint8_t *b, uint16_t v) { b[0] = (uint8_t)v; b[1] = (uint8_t)(v >> 8); }

/* ---- parser ---- */

#define PARSER_CAP 4096

struct lms200_parser {
    lms200_telegram_cb_t on_telegram;
    lms200_ack_cb_t on_ack;
    void *user;
    uint8_t buf[PARSER_CAP];
    size_t head, len;           /* held bytes are buf[head .. head+len) */
    uint64_t pos;               /* stream offset of buf[head] */
    bool fail_pending;          /* a candidate failed its CRC ... */
    uint64_t fail_end;          /* ... and claimed the bytes up to here, */
    uint8_t fail_addr;          /* with this address byte */
    size_t fail_len;            /* and length field */
    bool in_callback, reset_requested;
    lms200_parser_stats_t st;
};

lms200_parser_t *lms200_parser_create(lms200_telegram_cb_t on_telegram, lms200_ack_cb_t on_ack, void *user)
{
    return MARIE_NEW(lms200_parser_t, .on_telegram = on_telegram, .on_ack = on_ack, .user = user);
}

void lms200_parser_destroy(lms200_parser_t *p)
{
    free(p);
}

size_t lms200_parser_pending(const lms200_parser_t *p)
{
    return p->len;
}

const lms200_parser_stats_t *lms200_parser_stats(const lms200_parser_t *p)
{
    return &p->st;
}

static void drop_held(lms200_parser_t *p)
{
    if (p->fail_pending)
        p->st.crc_errors++;
    else if (p->len > 0 && p->buf[p->head] == LMS200_STX)
        p->st.truncated++;
    else
        p->st.garbage_bytes += p->len;
    p->pos += p->len;
    p->head = p->len = 0;
    p->fail_pending = false;
}

void lms200_parser_reset(lms200_parser_t *p)
{
    if (p->in_callback) {
        p->reset_requested = true;     /* done by feed once the callback returns */
        return;
    }
    drop_held(p);
}

static void consume(lms200_parser_t *p, size_t n)
{
    p->head += n;
    p->len -= n;
    p->pos += n;
    if (p->len == 0)
        p->head = 0;
}

/* A failed candidate is a CRC error unless a good telegram starts inside the bytes it
 * claimed: then it was a telegram cut short, and the one after it is intact. */
static void settle_failure(lms200_parser_t *p)
{
    if (p->fail_pending && p->pos >= p->fail_end) {
        p->st.crc_errors++;
        p->fail_pending = false;
    }
}

/* Decode what is held; returns telegrams delivered, stops early on a reset request. */
static int parse_held(lms200_parser_t *p)
{
    int delivered = 0;
    while (p->len > 0 && !p->reset_requested) {
        settle_failure(p);
        const uint8_t *b = p->buf + p->head;
        if (b[0] != LMS200_STX) {
            if (p->fail_pending) {
                /* inside a broken telegram: its bytes are neither garbage nor ACKs */
            } else if (b[0] == LMS200_ACK || b[0] == LMS200_NAK) {
                if (b[0] == LMS200_ACK)
                    p->st.acks++;
                else
                    p->st.naks++;
                if (p->on_ack) {
                    p->in_callback = true;
                    p->on_ack(p->user, b[0]);
                    p->in_callback = false;
                }
            } else {
                p->st.garbage_bytes++;
            }
            consume(p, 1);
            continue;
        }
        if (p->len < LMS200_HEADER_LEN)
            break;
        size_t l = rd16(b + 2);
        if (l == 0 || l > LMS200_MAX_LEN) {
            if (!p->fail_pending) {
                if (l == 0)
                    p->st.garbage_bytes++;
                else
                    p->st.oversized++;
            }
            consume(p, 1);
            continue;
        }
        size_t total = LMS200_HEADER_LEN + l + LMS200_CRC_LEN;
        if (p->len < total)
            break;
        uint16_t want = rd16(b + total - 2);
        if (lms200_crc(b, total - 2) != want) {
            /* The header of a telegram like the failed one, inside its bytes: that one was cut
             * short by this one (a device sending the same telegram over and over). Any other
             * STX in there may be a value's byte, and waits for the end of the failed one. */
            if (p->fail_pending && b[1] == p->fail_addr && l == p->fail_len) {
                p->st.truncated++;
                p->fail_pending = false;
            }
            if (!p->fail_pending) {
                p->fail_pending = true;
                p->fail_end = p->pos + total;
                p->fail_addr = b[1];
                p->fail_len = l;
            }
            consume(p, 1);
            continue;
        }
        if (p->fail_pending) {
            p->st.truncated++;
            p->fail_pending = false;
        }
        lms200_telegram_t t = {
            .addr = b[1], .cmd = b[4], .raw = b, .raw_len = total,
        };
        t.has_status = (t.addr & LMS200_REPLY_BIT) && l >= 2;
        t.data = b + 5;
        t.data_len = l - 1 - (t.has_status ? 1 : 0);
        t.status = t.has_status ? b[4 + l - 1] : 0;
        p->st.telegrams++;
        delivered++;
        p->in_callback = true;
        p->on_telegram(p->user, &t);
        p->in_callback = false;
        consume(p, total);
    }
    return delivered;
}

int lms200_parser_feed(lms200_parser_t *p, const uint8_t *buf, size_t len)
{
    int delivered = 0;
    while (len > 0) {
        if (p->head > 0 && p->head + p->len == PARSER_CAP) {
            memmove(p->buf, p->buf + p->head, p->len);
            p->head = 0;
        }
        size_t room = PARSER_CAP - (p->head + p->len);
        size_t n = len < room ? len : room;
        memcpy(p->buf + p->head + p->len, buf, n);
        p->len += n;
        buf += n;
        len -= n;
        delivered += parse_held(p);
        if (p->reset_requested) {
            /* The rest of this chunk belongs to the old line settings: drop it too. */
            p->reset_requested = false;
            drop_held(p);
            p->pos += len;
            break;
        }
    }
    return delivered;
}

/* ---- encoders ---- */

size_t lms200_encode(uint8_t *out, size_t cap, uint8_t addr, uint8_t cmd,
                     const uint8_t *data, size_t data_len, int status)
{
    size_t l = 1 + data_len + (status >= 0 ? 1 : 0);
    size_t total = LMS200_HEADER_LEN + l + LMS200_CRC_LEN;
    if (l > LMS200_MAX_LEN || total > cap)
        return 0;
    out[0] = LMS200_STX;
    out[1] = addr;
    wr16(out + 2, (uint16_t)l);
    out[4] = cmd;
    if (data_len)
        memcpy(out + 5, data, data_len);
    if (status >= 0)
        out[5 + data_len] = (uint8_t)status;
    wr16(out + total - 2, lms200_crc(out, total - 2));
    return total;
}

size_t lms200_encode_mode(uint8_t *out, size_t cap, uint8_t addr, uint8_t mode, const char *password)
{
    uint8_t d[9] = { mode };
    size_t n = 1;
    if (mode == LMS200_MODE_INSTALL) {
        const char *pw = password ? password : LMS200_PASSWORD;
        size_t pl = strlen(pw);
        if (pl != 8)
            return 0;
        memcpy(d + 1, pw, 8);
        n = 9;
    }
    return lms200_encode(out, cap, addr, LMS200_CMD_MODE, d, n, -1);
}

size_t lms200_encode_variant(uint8_t *out, size_t cap, uint8_t addr, uint16_t angle_deg, uint16_t res_cdeg)
{
    uint8_t d[4];
    wr16(d, angle_deg);
    wr16(d + 2, res_cdeg);
    return lms200_encode(out, cap, addr, LMS200_CMD_VARIANT, d, sizeof d, -1);
}

size_t lms200_encode_request(uint8_t *out, size_t cap, uint8_t addr)
{
    uint8_t d[1] = { 0x01 };       /* all values of one scan */
    return lms200_encode(out, cap, addr, LMS200_CMD_REQUEST, d, 1, -1);
}

size_t lms200_encode_mode_reply(uint8_t *out, size_t cap, uint8_t addr, uint8_t result, uint8_t status)
{
    return lms200_encode(out, cap, addr | LMS200_REPLY_BIT, LMS200_REPLY_MODE, &result, 1, status);
}

size_t lms200_encode_variant_reply(uint8_t *out, size_t cap, uint8_t addr, bool ok,
                                   uint16_t angle_deg, uint16_t res_cdeg, uint8_t status)
{
    uint8_t d[5] = { ok ? 1 : 0 };
    wr16(d + 1, angle_deg);
    wr16(d + 3, res_cdeg);
    return lms200_encode(out, cap, addr | LMS200_REPLY_BIT, LMS200_REPLY_VARIANT, d, sizeof d, status);
}

size_t lms200_encode_scan(uint8_t *out, size_t cap, uint8_t addr, lms200_unit_t unit,
                          const uint16_t *values, size_t n, uint8_t status)
{
    if (n > LMS200_MAX_VALUES)
        return 0;
    uint8_t d[2 + 2 * LMS200_MAX_VALUES];
    wr16(d, (uint16_t)(n | ((unsigned)unit << 14)));
    for (size_t i = 0; i < n; i++)
        wr16(d + 2 + 2 * i, values[i]);
    return lms200_encode(out, cap, addr | LMS200_REPLY_BIT, LMS200_REPLY_SCAN, d, 2 + 2 * n, status);
}

size_t lms200_scan_telegram_len(size_t n)
{
    /* header, reply code, count word, the values, status, CRC */
    return LMS200_HEADER_LEN + 1 + 2 + 2 * n + 1 + LMS200_CRC_LEN;
}

int64_t lms200_wire_us(size_t bytes, int baud) { return (int64_t)bytes * 10 * 1000000 / (baud > 0 ? baud : 9600); }

int lms200_baud_mode(int baud)
{
    switch (baud) {
    case 9600: return LMS200_MODE_BAUD_9600;
    case 19200: return LMS200_MODE_BAUD_19200;
    case 38400: return LMS200_MODE_BAUD_38400;
    case 500000: return LMS200_MODE_BAUD_500000;
    default: return -1;
    }
}

int lms200_mode_baud(uint8_t mode)
{
    switch (mode) {
    case LMS200_MODE_BAUD_9600: return 9600;
    case LMS200_MODE_BAUD_19200: return 19200;
    case LMS200_MODE_BAUD_38400: return 38400;
    case LMS200_MODE_BAUD_500000: return 500000;
    default: return 0;
    }
}

/* ---- decoders ---- */

int lms200_decode_mode_reply(const lms200_telegram_t *t, uint8_t *result)
{
    if (t->cmd != LMS200_REPLY_MODE || t->data_len < 1)
        return marie_fail(EBADMSG);
    *result = t->data[0];
    return 0;
}

int lms200_decode_variant_reply(const lms200_telegram_t *t, lms200_variant_t *v)
{
    if (t->cmd != LMS200_REPLY_VARIANT || t->data_len < 5)
        return marie_fail(EBADMSG);
    v->ok = t->data[0] == 1;
    v->angle_deg = rd16(t->data + 1);
    v->res_cdeg = rd16(t->data + 3);
    return 0;
}

int lms200_decode_scan(const lms200_telegram_t *t, lms200_scan_t *s)
{
    if (t->cmd != LMS200_REPLY_SCAN || t->data_len < 2)
        return marie_fail(EBADMSG);
    uint16_t w = rd16(t->data);
    size_t n = w & 0x03ff;
    if (n > LMS200_MAX_VALUES || t->data_len < 2 + 2 * n)
        return marie_fail(EBADMSG);
    unsigned unit = w >> 14;
    if (unit > LMS200_UNIT_MM)
        return marie_fail(EBADMSG);        /* 10 cm units belong to other LMS2xx variants */
    s->n = (uint16_t)n;
    s->unit = (lms200_unit_t)unit;
    s->partial = (w >> 13) & 1;
    s->partial_index = (w >> 11) & 3;
    for (size_t i = 0; i < n; i++) {
        uint16_t v = rd16(t->data + 2 + 2 * i);
        s->values[i] = v & LMS200_VALUE_MASK;
        s->flags[i] = (uint8_t)(v >> 13);
    }
    s->status = t->status;
    return 0;
}

double lms200_value_m(uint16_t value, lms200_unit_t unit)
{
    value &= LMS200_VALUE_MASK;
    if (value >= LMS200_VALUE_ERROR_MIN)
        return INFINITY;
    return unit == LMS200_UNIT_MM ? value * 0.001 : value * 0.01;
}
