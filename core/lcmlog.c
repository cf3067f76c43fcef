/* lcmlog: pure reader of LCM log files; corrupt stretches are reported and skipped by
 * scanning for the next sync word, so one bad byte never loses the rest of a log. */
#include "core/lcmlog.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"
#include "core/new.h"

struct lcmlog_parser {
    lcmlog_event_cb_t on_event;
    lcmlog_corrupt_cb_t on_corrupt;
    void *user;
    uint8_t *buf;               /* bytes not yet consumed, starting at stream offset buf_off */
    size_t len, cap;
    uint64_t buf_off;
    int in_garbage;             /* inside a corrupt stretch that began at garbage_off */
    uint64_t garbage_off;
    const char *garbage_reason;
    lcmlog_stats_t stats;
};

static uint32_t be32(const uint8_t *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

static uint64_t be64(const uint8_t *p)
{
    return (uint64_t)be32(p) << 32 | be32(p + 4);
}

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = v >> 24; p[1] = v >> 16; p[2] = v >> 8; p[3] = v;
}

static void put64(uint8_t *p, uint64_t v)
{
    put32(p, v >> 32);
    put32(p + 4, (uint32_t)v);
}

lcmlog_parser_t *lcmlog_parser_create(lcmlog_event_cb_t on_event, lcmlog_corrupt_cb_t on_corrupt, void *user)
{
    return MARIE_NEW(lcmlog_parser_t, .on_event = on_event, .on_corrupt = on_corrupt, .user = user);
}

void lcmlog_parser_destroy(lcmlog_parser_t *p)
{
    if (!p)
        return;
    free(p->buf);
    free(p);
}

const lcmlog_stats_t *lcmlog_parser_stats(const lcmlog_parser_t *p)
{
    return &p->stats;
}

static void garbage_begin(lcmlog_parser_t *p, uint64_t off, const char *reason)
{
    if (p->in_garbage)
        return;
    p->in_garbage = 1;
    p->garbage_off = off;
    p->garbage_reason = reason;
}

static void garbage_end(lcmlog_parser_t *p, uint64_t end)
{
    if (!p->in_garbage)
        return;
    p->in_garbage = 0;
    p->stats.corrupt++;
    p->stats.skipped_bytes += end - p->garbage_off;
    if (p->on_corrupt) {
        char msg[160];
        snprintf(msg, sizeof msg, "%s (%llu bytes skipped)", p->garbage_reason,
                 (unsigned long long)(end - p->garbage_off));
        p->on_corrupt(p->user, p->garbage_off, msg);
    }
}

static int channel_ok(const uint8_t *c, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (c[i] < 0x20 || c[i] > 0x7e)
            return 0;
    return 1;
}

/* Parses records from b[0..n) at stream offset off; returns the bytes consumed. When `final`,
 * nothing more will come: an incomplete record is corruption, not a reason to wait. */
static size_t process(lcmlog_parser_t *p, const uint8_t *b, size_t n, uint64_t off, int final)
{
    size_t i = 0;
    while (i < n) {
        size_t left = n - i;
        if (left < 4 || be32(b + i) != LCMLOG_SYNC) {
            if (left < 4 && !final)
                break;
            garbage_begin(p, off + i, left < 4 ? "record cut short" : "no sync word");
            /* Scan for the next sync word; keep a possible partial one for the next feed. */
            size_t j = i + 1;
            while (j + 4 <= n && be32(b + j) != LCMLOG_SYNC)
                j++;
            if (j + 4 > n)
                j = final ? n : (n >= 3 ? n - 3 : 0);
            if (j <= i)
                break;
            i = j;
            continue;
        }
        if (left < LCMLOG_HEADER_LEN && !final)
            break;
        uint32_t clen = 0, dlen = 0;
        if (left >= LCMLOG_HEADER_LEN) {
            clen = be32(b + i + 20);
            dlen = be32(b + i + 24);
        }
        if (left < LCMLOG_HEADER_LEN || clen == 0 || clen > LCMLOG_MAX_CHANNEL || dlen > LCMLOG_MAX_DATA) {
            garbage_begin(p, off + i, left < LCMLOG_HEADER_LEN ? "record cut short" : "bad record header");
            i++;
            continue;
        }
        size_t total = (size_t)LCMLOG_HEADER_LEN + clen + dlen;
        if (left < total) {
            if (!final)
                break;
            garbage_begin(p, off + i, "record cut short (or its length is wrong)");
            i++;
            continue;
        }
        const uint8_t *chan = b + i + LCMLOG_HEADER_LEN;
        if (!channel_ok(chan, clen)) {
            garbage_begin(p, off + i, "bad channel name");
            i++;
            continue;
        }
        garbage_end(p, off + i);
        lcmlog_event_t ev = {
            .eventnum = (int64_t)be64(b + i + 4), .utime = (int64_t)be64(b + i + 12),
            .channel = (const char *)chan, .channel_len = clen,
            .data = chan + clen, .data_len = dlen, .offset = off + i,
        };
        p->stats.events++;
        if (p->on_event)
            p->on_event(p->user, &ev);
        i += total;
    }
    return i;
}

static int keep(lcmlog_parser_t *p, const uint8_t *b, size_t n)
{
    if (n == 0)
        return 0;
    if (p->len + n > p->cap) {
        size_t cap = p->cap ? p->cap : 4096;
        while (cap < p->len + n)
            cap *= 2;
        uint8_t *nb = realloc(p->buf, cap);
        if (!nb)
            return marie_fail(ENOMEM);
        p->buf = nb;
        p->cap = cap;
    }
    memcpy(p->buf + p->len, b, n);
    p->len += n;
    return 0;
}

int lcmlog_parser_feed(lcmlog_parser_t *p, const void *data, size_t n)
{
    const uint8_t *b = data;
    if (n == 0)
        return 0;
    if (p->len == 0) {
        /* Nothing pending: parse straight from the caller's bytes, keep only the tail. */
        size_t used = process(p, b, n, p->buf_off, 0);
        p->buf_off += used;
        return keep(p, b + used, n - used);
    }
    int rc = keep(p, b, n);
    if (rc < 0)
        return rc;
    size_t used = process(p, p->buf, p->len, p->buf_off, 0);
    memmove(p->buf, p->buf + used, p->len - used);
    p->len -= used;
    p->buf_off += used;
    return 0;
}

void lcmlog_parser_finish(lcmlog_parser_t *p)
{
    size_t used = process(p, p->buf, p->len, p->buf_off, 1);
    p->buf_off += used;
    p->len = 0;
    garbage_end(p, p->buf_off);
}

long lcmlog_encode(void *out, size_t cap, int64_t eventnum, int64_t utime, const char *channel,
                   const void *data, size_t data_len)
{
    size_t clen = strlen(channel);
    size_t total = LCMLOG_HEADER_LEN + clen + data_len;
    if (total > cap)
        return marie_fail(ENOSPC);
    uint8_t *b = out;
    put32(b, LCMLOG_SYNC);
    put64(b + 4, (uint64_t)eventnum);
    put64(b + 12, (uint64_t)utime);
    put32(b + 20, (uint32_t)clen);
    put32(b + 24, (uint32_t)data_len);
    memcpy(b + LCMLOG_HEADER_LEN, channel, clen);
    if (data_len)
        memcpy(b + LCMLOG_HEADER_LEN + clen, data, data_len);
    return (long)total;
}
