/* ca: shared helpers of the Communication Adapters. */
#include "ca/ca.h"

#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/log.h"
#include "core/loop.h"
#include "core/time.h"

void ca_note(const ca_sink_t *s, ca_note_kind_t kind, const char *counter, int64_t n,
             const char *fmt, ...)
{
    if (!s || !s->note)
        return;
    char text[512];
    if (fmt) {
        MARIE_VFORMAT(text, fmt);
    }
    s->note(s->user, kind, counter, n, fmt ? text : NULL);
}

int ca_publish(const ca_sink_t *s, const char *channel, const void *buf, size_t len)
{
    if (s && s->publish)
        return s->publish(s->user, channel, buf, len);
    if (s && s->lcm)
        return marie_bus_publish(s->lcm, channel, buf, (unsigned int)len) < 0 ? -EIO : 0;
    return 0;
}

int ca_bad_request(const ca_sink_t *s, const char *where, const char *what, const void *buf, size_t len)
{
    ca_note(s, CA_NOTE_BAD_INPUT, "bad_request", 1, "%s%sundecodable %s (%zu bytes, fingerprint %016llx)",
            where ? where : "", where ? ": " : "", what, len,
            (unsigned long long)marie_payload_fingerprint(buf, len));
    return -EBADMSG;
}

int ca_fingerprint(const void *raw, size_t len, int64_t *fp)
{
    if (!raw || len < 8)
        return -EBADMSG;
    *fp = marie_payload_fingerprint(raw, len);
    return 0;
}

int ca_check_type(const marie_type_t *type, const void *raw, size_t len)
{
    int64_t fp;
    if (ca_fingerprint(raw, len, &fp) < 0)
        return -EBADMSG;
    if (type && fp != type->hash())
        return -EBADMSG;
    return 0;
}

int ca_payload_check(const marie_type_t *type, const void *raw, size_t len, const char **why)
{
    const char *dummy;
    why = why ? why : &dummy;
    *why = "bad_fingerprint";
    int64_t fp;
    if (ca_check_type(type, raw, len) < 0 || ca_fingerprint(raw, len, &fp) < 0)
        return -EBADMSG;
    /* An untyped CA can only check the types it knows; others pass on their fingerprint. */
    const marie_typeinfo_t *ti = marie_typeinfo_by_fingerprint(fp);
    if (!ti)
        return 0;
    int rc = marie_typeinfo_check_flags(ti, raw, len, MARIE_CHECK_FINITE);
    *why = rc == -EDOM ? "bad_nonfinite" : "bad_payload";
    return rc < 0 ? -EBADMSG : 0;
}

int ca_input_check(const ca_sink_t *s, const marie_type_t *type, const char *channel, const void *raw, size_t len)
{
    const char *why;
    if (ca_payload_check(type, raw, len, &why) == 0)
        return 0;
    int64_t fp = 0;
    ca_fingerprint(raw, len, &fp);
    const marie_type_t *t = type ? type : marie_type_by_fingerprint(fp);
    ca_note(s, CA_NOTE_BAD_INPUT, why, 1, "%s: payload of %zu bytes with fingerprint %016llx is not a well-formed, finite %s",
            channel, len, (unsigned long long)fp, t ? t->name : "LCM payload");
    return -EBADMSG;
}

char *ca_channel_pattern(const char *channel)
{
    size_t n = strlen(channel);
    char *out = malloc(2 * n + 1);
    if (!out)
        return NULL;
    char *o = out;
    for (const char *c = channel; *c; c++) {
        if (strchr(".^$|()[]{}*+?\\", *c))
            *o++ = '\\';
        *o++ = *c;
    }
    *o = 0;
    return out;
}

static void on_input_lcm(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    ca_input_t *in = user;
    in->fn(in->user, rbuf->data, rbuf->data_size, rbuf->recv_utime);
}

int ca_input_open(ca_input_t *in, lcm_t *lcm, const char *channel, ca_input_fn fn, void *user)
{
    *in = (ca_input_t){ .lcm = lcm, .fn = fn, .user = user };
    char *pat = ca_channel_pattern(channel);
    if (!pat)
        return -ENOMEM;
    in->sub = marie_bus_subscribe(lcm, pat, on_input_lcm, in);
    free(pat);
    return in->sub ? 0 : -EIO;
}

void ca_input_close(ca_input_t *in)
{
    marie_bus_unsubscribe(in->lcm, in->sub);
    in->sub = NULL;
}

marie_bus_sub_stats_t ca_input_stats(const ca_input_t *in)
{
    return marie_bus_sub_stats(in->lcm, in->sub);
}

static uint32_t crc_table[256];
static int crc_ready;

uint32_t ca_crc32(uint32_t crc, const void *buf, size_t len)
{
    if (!crc_ready) {
        for (uint32_t i = 0; i < 256; i++) {
            uint32_t c = i;
            for (int k = 0; k < 8; k++)
                c = (c & 1) ? 0xEDB88320u ^ (c >> 1) : c >> 1;
            crc_table[i] = c;
        }
        crc_ready = 1;
    }
    const uint8_t *p = buf;
    crc = ~crc;
    while (len--)
        crc = crc_table[(crc ^ *p++) & 0xff] ^ (crc >> 8);
    return ~crc;
}

int ca_fsync_dir(const char *path)
{
    char *copy = strdup(path);
    if (!copy)
        return -ENOMEM;
    int fd = open(dirname(copy), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    free(copy);
    if (fd < 0)
        return -errno;
    int rc = fsync(fd) < 0 ? -errno : 0;
    close(fd);
    return rc;
}

int ca_write_file_atomic(const char *path, const void *buf, size_t len)
{
    char tmp[4096];
    if (snprintf(tmp, sizeof tmp, "%s.tmp", path) >= (int)sizeof tmp)
        return -ENAMETOOLONG;
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0)
        return -errno;
    const uint8_t *p = buf;
    size_t off = 0;
    int rc = 0;
    while (off < len) {
        ssize_t w = write(fd, p + off, len - off);
        if (w < 0) {
            if (errno == EINTR)
                continue;
            rc = -errno;
            goto err_close;
        }
        off += (size_t)w;
    }
    if (fsync(fd) < 0) {
        rc = -errno;
        goto err_close;
    }
    close(fd);
    if (rename(tmp, path) < 0) {
        rc = -errno;
        goto err_unlink;
    }
    return ca_fsync_dir(path);

err_close:
    close(fd);
err_unlink:
    unlink(tmp);
    return rc;
}

typedef struct {
    int64_t i;          /* integers; count of 'B' and 'S' */
    const void *p;      /* 's': the string; 'B': the bytes; 'S': the first length prefix */
} field_t;

static int64_t be(const uint8_t *p, int n)
{
    uint64_t v = 0;
    for (int k = 0; k < n; k++)
        v = v << 8 | p[k];
    if (n == 4)
        return (int32_t)(uint32_t)v;
    if (n == 1)
        return (int8_t)v;
    return (int64_t)v;
}

/* Validate buf against schema and, when f is given, record each field. */
static int walk(const marie_type_t *type, const char *schema, const void *buf, size_t len, field_t *f)
{
    const uint8_t *p = buf;
    if (ca_check_type(type, buf, len) < 0)
        return -EBADMSG;
    size_t pos = 8;
    int64_t count = 0;
    for (const char *s = schema; *s; s++, f = f ? f + 1 : NULL) {
        size_t left = len - pos;
        switch (*s) {
        case 'l': case 'd':
            if (left < 8) return -EBADMSG;
            if (f) f->i = be(p + pos, 8);
            pos += 8;
            break;
        case 'i':
            if (left < 4) return -EBADMSG;
            count = be(p + pos, 4);
            if (f) f->i = count;
            pos += 4;
            break;
        case 'b':
            if (left < 1) return -EBADMSG;
            if (f) f->i = be(p + pos, 1);
            pos += 1;
            break;
        case 'B':
            if (count < 0 || (uint64_t)count > left) return -EBADMSG;
            if (f) {
                f->i = count;
                f->p = count ? p + pos : (const void *)"";
            }
            pos += (size_t)count;
            break;
        case 's': case 'S': {
            int64_t n = *s == 's' ? 1 : count;
            if (n < 0) return -EBADMSG;
            if (f) {
                f->i = n;
                f->p = *s == 's' ? p + pos + 4 : p + pos;
            }
            for (int64_t k = 0; k < n; k++) {
                left = len - pos;
                if (left < 4) return -EBADMSG;
                int32_t sl = (int32_t)((uint32_t)p[pos] << 24 | (uint32_t)p[pos + 1] << 16 | (uint32_t)p[pos + 2] << 8 | p[pos + 3]);
                pos += 4;
                if (sl < 1 || (size_t)sl > left - 4 || p[pos + (size_t)sl - 1] != 0) return -EBADMSG;
                pos += (size_t)sl;
            }
            break;
        }
        default:
            return -EINVAL;
        }
    }
    return pos == len ? 0 : -EBADMSG;
}

int ca_lcm_check(const marie_type_t *type, const char *schema, const void *buf, size_t len)
{
    return walk(type, schema, buf, len, NULL);
}

#define S(k) ((char *)f[k].p)

int ca_view_pull_request(const void *buf, size_t len, marie_pull_request_t *out)
{
    field_t f[6];
    if (walk(&marie_type_pull_request_t, CA_SCHEMA_PULL_REQUEST, buf, len, f) < 0)
        return -EBADMSG;
    *out = (marie_pull_request_t){ f[0].i, f[1].i, S(2), S(3), S(4), (int32_t)f[5].i };
    return 0;
}

int ca_view_pull_reply(const void *buf, size_t len, marie_pull_reply_t *out)
{
    field_t f[8];
    if (walk(&marie_type_pull_reply_t, CA_SCHEMA_PULL_REPLY, buf, len, f) < 0)
        return -EBADMSG;
    *out = (marie_pull_reply_t){ f[0].i, f[1].i, S(2), (int8_t)f[3].i, f[4].i, f[5].i,
                                 (int32_t)f[6].i, (uint8_t *)f[7].p };
    return 0;
}

int ca_view_sharedmap_request(const void *buf, size_t len, marie_sharedmap_request_t *out)
{
    field_t f[9];
    if (walk(&marie_type_sharedmap_request_t, CA_SCHEMA_SHAREDMAP_REQUEST, buf, len, f) < 0)
        return -EBADMSG;
    *out = (marie_sharedmap_request_t){ f[0].i, f[1].i, S(2), S(3), (int8_t)f[4].i, S(5), S(6),
                                        (int32_t)f[7].i, (uint8_t *)f[8].p };
    return 0;
}

int ca_view_sharedmap_reply(const void *buf, size_t len, marie_sharedmap_reply_t *out)
{
    field_t f[13];
    if (walk(&marie_type_sharedmap_reply_t, CA_SCHEMA_SHAREDMAP_REPLY, buf, len, f) < 0)
        return -EBADMSG;
    size_t n = (size_t)f[12].i;
    char **keys = malloc((n ? n : 1) * sizeof *keys);
    if (!keys)
        return -ENOMEM;
    const uint8_t *p = f[12].p;
    for (size_t k = 0; k < n; k++) {
        keys[k] = (char *)p + 4;
        p += 4 + (size_t)be(p, 4);
    }
    *out = (marie_sharedmap_reply_t){ f[0].i, f[1].i, S(2), (int8_t)f[3].i, (int8_t)f[4].i, S(5),
                                      f[6].i, S(7), f[8].i, (int32_t)f[9].i, (uint8_t *)f[10].p,
                                      (int32_t)n, keys };
    return 0;
}

int ca_view_switch_select(const void *buf, size_t len, marie_switch_select_t *out)
{
    field_t f[4];
    if (walk(&marie_type_switch_select_t, CA_SCHEMA_SWITCH_SELECT, buf, len, f) < 0)
        return -EBADMSG;
    *out = (marie_switch_select_t){ f[0].i, f[1].i, S(2), S(3) };
    return 0;
}

