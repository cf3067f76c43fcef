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

#include "core/err.h"
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
        return marie_bus_publish(s->lcm, channel, buf, (unsigned int)len) < 0 ? marie_fail(EIO) : 0;
    return 0;
}

int ca_bad_request(const ca_sink_t *s, const char *where, const char *what, const void *buf, size_t len)
{
    ca_note(s, CA_NOTE_BAD_INPUT, "bad_request", 1, "%s%sundecodable %s (%zu bytes, fingerprint %016llx)",
            where ? where : "", where ? ": " : "", what, len,
            (unsigned long long)marie_payload_fingerprint(buf, len));
    return marie_fail(EBADMSG);
}

int ca_fingerprint(const void *raw, size_t len, int64_t *fp)
{
    if (!raw || len < 8)
        return marie_fail(EBADMSG);
    *fp = marie_payload_fingerprint(raw, len);
    return 0;
}

int ca_check_type(const marie_type_t *type, const void *raw, size_t len)
{
    int64_t fp;
    if (ca_fingerprint(raw, len, &fp) < 0)
        return marie_fail(EBADMSG);
    if (type && fp != type->hash())
        return marie_fail(EBADMSG);
    return 0;
}

int ca_payload_check(const marie_type_t *type, const void *raw, size_t len, const char **why)
{
    const char *dummy;
    why = why ? why : &dummy;
    *why = "bad_fingerprint";
    int64_t fp;
    if (ca_check_type(type, raw, len) < 0 || ca_fingerprint(raw, len, &fp) < 0)
        return marie_fail(EBADMSG);
    /* An untyped CA can only check the types it knows; others pass on their fingerprint. */
    const marie_typeinfo_t *ti = marie_typeinfo_by_fingerprint(fp);
    if (!ti)
        return 0;
    int rc = marie_typeinfo_check_flags(ti, raw, len, MARIE_CHECK_FINITE);
    *why = rc < 0 && errno == EDOM ? "bad_nonfinite" : "bad_payload";
    return rc < 0 ? marie_fail(EBADMSG) : 0;
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
    return marie_fail(EBADMSG);
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
        return marie_fail(ENOMEM);
    in->sub = marie_bus_subscribe(lcm, pat, on_input_lcm, in);
    free(pat);
    return in->sub ? 0 : marie_fail(EIO);
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
        return marie_fail(ENOMEM);
    int fd = open(dirname(copy), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    free(copy);
    if (fd < 0)
        return -1;
    int rc = fsync(fd) < 0 ? -1 : 0;
    MARIE_KEEP_ERRNO(close(fd));
    return rc;
}

int ca_write_file_atomic(const char *path, const void *buf, size_t len)
{
    char tmp[4096];
    if (snprintf(tmp, sizeof tmp, "%s.tmp", path) >= (int)sizeof tmp)
        return marie_fail(ENAMETOOLONG);
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0)
        return -1;
    const uint8_t *p = buf;
    size_t off = 0;
    while (off < len) {
        ssize_t w = write(fd, p + off, len - off);
        if (w < 0) {
            if (errno == EINTR)
                continue;
            goto err_close;
        }
        off += (size_t)w;
    }
    if (fsync(fd) < 0)
        goto err_close;
    close(fd);
    if (rename(tmp, path) < 0)
        goto err_unlink;
    return ca_fsync_dir(path);

err_close:
    MARIE_KEEP_ERRNO(close(fd));
err_unlink:
    MARIE_KEEP_ERRNO(unlink(tmp));
    return -1;
}
