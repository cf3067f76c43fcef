/* sharedmap: sorted in-memory map, append-only log with fdatasync per change, compaction by
 * atomic rename, recovery from a damaged log, and the request protocol. */
#include "ca/sharedmap.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "ca/sharedmap_log.h"
#include "core/err.h"
#include "core/loop.h"
#include "core/time.h"
#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_sharedmap_reply_t.h"
#include "lcmtypes/marie_sharedmap_snapshot_t.h"

typedef struct {
    char *key;
    char *type;
    uint8_t *data;
    size_t len;
    int64_t version, set_utime;
} entry_t;

struct sharedmap {
    char *path;
    int fd;                     /* O_APPEND log, -1 when memory only */
    int lock_fd;                /* flock()ed PATH.lock: one SharedMap per log */
    off_t log_size;
    int64_t nrecords;           /* records in the log file */
    int64_t seq;                /* sequence number of the last record in the log file */
    unsigned flags;             /* SHAREDMAP_STRICT */
    sharedmap_replay_t loaded;  /* what the scan at open found */
    char *aside;                /* where a damaged log was kept, NULL if none */
    int64_t compact_min;
    entry_t *entries;           /* sorted by key */
    size_t n, cap;
    int64_t version;
    ca_sink_t sink;
    uint8_t *buf;               /* encode buffer (records, replies, snapshots) */
    size_t buf_cap;
    char *snap_channel, *snap_source;
    int64_t snap_min_interval, snap_last;
    int snap_due;
    lcm_t *lcm;
    marie_bus_sub_t *sub;
    sharedmap_stats_t stats;
};

static int grow(sharedmap_t *sm, size_t need)
{
    if (need <= sm->buf_cap)
        return 0;
    size_t cap = sm->buf_cap ? sm->buf_cap : 4096;
    while (cap < need)
        cap *= 2;
    uint8_t *nb = realloc(sm->buf, cap);
    if (!nb)
        return marie_fail(ENOMEM);
    sm->buf = nb;
    sm->buf_cap = cap;
    return 0;
}

static ssize_t find(const sharedmap_t *sm, const char *key, int *found)
{
    size_t lo = 0, hi = sm->n;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        int c = strcmp(sm->entries[mid].key, key);
        if (c == 0) {
            *found = 1;
            return (ssize_t)mid;
        }
        if (c < 0)
            lo = mid + 1;
        else
            hi = mid;
    }
    *found = 0;
    return (ssize_t)lo;
}

static void entry_free(entry_t *e)
{
    free(e->key);
    free(e->type);
    free(e->data);
}

/* Apply a change to memory only. */
static int mem_set(sharedmap_t *sm, const char *key, const char *type, const void *data,
                   size_t len, int64_t version, int64_t set_utime)
{
    int found;
    size_t i = (size_t)find(sm, key, &found);
    char *t = strdup(type ? type : "");
    uint8_t *d = malloc(len ? len : 1);
    if (!t || !d)
        goto err;
    memcpy(d, data, len);
    if (found) {
        entry_t *e = &sm->entries[i];
        free(e->type);
        free(e->data);
        *e = (entry_t){ e->key, t, d, len, version, set_utime };
        return 0;
    }
    if (sm->n == sm->cap) {
        size_t cap = sm->cap ? sm->cap * 2 : 16;
        entry_t *ne = realloc(sm->entries, cap * sizeof *ne);
        if (!ne)
            goto err;
        sm->entries = ne;
        sm->cap = cap;
    }
    char *k = strdup(key);
    if (!k)
        goto err;
    memmove(&sm->entries[i + 1], &sm->entries[i], (sm->n - i) * sizeof *sm->entries);
    sm->entries[i] = (entry_t){ k, t, d, len, version, set_utime };
    sm->n++;
    return 0;
err:
    free(t);
    free(d);
    return marie_fail(ENOMEM);
}

static int mem_delete(sharedmap_t *sm, const char *key)
{
    int found;
    size_t i = (size_t)find(sm, key, &found);
    if (!found)
        return marie_fail(ENOENT);
    entry_free(&sm->entries[i]);
    memmove(&sm->entries[i], &sm->entries[i + 1], (sm->n - i - 1) * sizeof *sm->entries);
    sm->n--;
    return 0;
}

static int replay_record(void *user, const sharedmap_log_rec_t *r)
{
    sharedmap_t *sm = user;
    if (r->op == SHAREDMAP_LOG_SET) {
        if (mem_set(sm, r->key, r->type, r->data, r->len, r->version, r->set_utime) < 0)
            return marie_fail(ENOMEM);
    } else if (r->op == SHAREDMAP_LOG_DEL) {
        mem_delete(sm, r->key);
    }
    if (r->version > sm->version)
        sm->version = r->version;
    sm->nrecords++;
    sm->seq = r->seq;
    sm->stats.records_loaded++;
    return 0;
}

int sharedmap_replay(sharedmap_t *sm, const void *image, size_t len, sharedmap_replay_t *rep)
{
    sharedmap_replay_t local;
    return sharedmap_log_scan(image, len, replay_record, sm, rep ? rep : &local);
}

const sharedmap_replay_t *sharedmap_load_report(const sharedmap_t *sm) { return &sm->loaded; }
const char *sharedmap_kept_aside(const sharedmap_t *sm) { return sm->aside; }

static int read_all(int fd, uint8_t **out, size_t *len)
{
    struct stat st;
    if (fstat(fd, &st) < 0)
        return -1;
    size_t n = (size_t)st.st_size, got = 0;
    uint8_t *b = malloc(n ? n : 1);
    if (!b)
        return marie_fail(ENOMEM);
    while (got < n) {
        ssize_t r = read(fd, b + got, n - got);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            break;
        got += (size_t)r;
    }
    *out = b;
    *len = got;
    return 0;
}

static int lock(sharedmap_t *sm)
{
    char lp[4096];
    if (snprintf(lp, sizeof lp, "%s.lock", sm->path) >= (int)sizeof lp)
        return marie_fail(ENAMETOOLONG);
    sm->lock_fd = open(lp, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (sm->lock_fd < 0)
        return -1;
    /* The kernel drops the lock when the holder dies, even by SIGKILL. */
    if (flock(sm->lock_fd, LOCK_EX | LOCK_NB) < 0)
        return errno == EWOULDBLOCK ? marie_fail(EBUSY) : -1;
    return 0;
}

/* PATH.lock also holds the SharedMap's note of the last record it acknowledged, with the log's
 * device and inode (a compaction makes a new file): "acked DEV INO SEQ", padded. Rewritten
 * after every fdatasync, never synced itself: it survives a SIGKILL or a clean stop, not
 * always a power loss (then it is older, or absent, and a torn tail is taken for the write
 * the crash cut short, as without a note). */
#define NOTE_LEN 64

static void note_write(sharedmap_t *sm)
{
    struct stat st;
    if (sm->lock_fd < 0 || sm->fd < 0 || fstat(sm->fd, &st) < 0)
        return;
    char note[NOTE_LEN + 1];
    int n = snprintf(note, sizeof note, "acked %llu %llu %lld", (unsigned long long)st.st_dev,
                     (unsigned long long)st.st_ino, (long long)sm->seq);
    memset(note + n, ' ', NOTE_LEN - 1 - (size_t)n);
    note[NOTE_LEN - 1] = '\n';
    (void)!pwrite(sm->lock_fd, note, NOTE_LEN, 0);
}

/* The sequence number the note says was acknowledged last in the log now at PATH; 0 when
 * unknown (no note, or a note about another file). */
static int64_t note_acked(const sharedmap_t *sm)
{
    char note[NOTE_LEN + 1] = "";
    unsigned long long dev, ino;
    long long seq;
    struct stat st;
    ssize_t n = pread(sm->lock_fd, note, NOTE_LEN, 0);
    if (n <= 0 || stat(sm->path, &st) < 0)
        return 0;
    note[n] = 0;
    if (sscanf(note, "acked %llu %llu %lld", &dev, &ino, &seq) != 3 || dev != st.st_dev || ino != st.st_ino ||
        seq < 0)
        return 0;
    return seq;
}

/* Keeps the damaged log as PATH.corrupt-TIMESTAMP, the bytes as found, before it is
 * rewritten: a hard link, or a copy where the filesystem has none. */
static int keep_aside(sharedmap_t *sm, const uint8_t *buf, size_t len)
{
    char stamp[32], name[4200];
    time_t t = time(NULL);
    struct tm tm;
    strftime(stamp, sizeof stamp, "%Y%m%dT%H%M%SZ", gmtime_r(&t, &tm));
    for (int i = 1; i < 1000; i++) {
        int n = i == 1 ? snprintf(name, sizeof name, "%s.corrupt-%s", sm->path, stamp)
                       : snprintf(name, sizeof name, "%s.corrupt-%s-%d", sm->path, stamp, i);
        if (n >= (int)sizeof name)
            return marie_fail(ENAMETOOLONG);
        int rc;
        if (link(sm->path, name) == 0)
            rc = ca_fsync_dir(sm->path);
        else if (errno == EEXIST)
            continue;
        else
            rc = ca_write_file_atomic(name, buf, len);    /* no hard links here */
        if (rc == 0 && !(sm->aside = strdup(name)))
            rc = marie_fail(ENOMEM);
        return rc;
    }
    return marie_fail(EEXIST);
}

/* Damage found at open: refuse (strict), or report it and keep the file aside; the caller
 * then writes a fresh log from the intact records. */
static int on_damage(sharedmap_t *sm, const uint8_t *buf, size_t len)
{
    const sharedmap_replay_t *rep = &sm->loaded;
    char what[600];
    sharedmap_log_describe(rep, what, sizeof what);
    if (sm->flags & SHAREDMAP_STRICT) {
        ca_note(&sm->sink, CA_NOTE_EVENT, "sharedmap_log_damaged", MARIE_EVENT_T_SEV_ERROR,
                "%s: damaged log (%s); left as it is, not started (strict)", sm->path, what);
        return marie_fail(EBADMSG);
    }
    int rc = keep_aside(sm, buf, len);
    if (rc < 0) {
        MARIE_KEEP_ERRNO(ca_note(&sm->sink, CA_NOTE_EVENT, "sharedmap_io_error", MARIE_EVENT_T_SEV_ERROR,
                                 "%s: damaged log (%s) cannot be kept aside: %s", sm->path, what, strerror(errno)));
        return -1;
    }
    sm->stats.records_skipped = rep->records_skipped;
    sm->stats.bytes_skipped = rep->bytes_skipped;
    ca_note(&sm->sink, CA_NOTE_COUNT, "log_records_skipped", rep->records_skipped, NULL);
    ca_note(&sm->sink, CA_NOTE_EVENT, "sharedmap_log_damaged", MARIE_EVENT_T_SEV_WARN,
            "%s: damaged log: %s; %lld intact records kept; damaged file kept as %s",
            sm->path, what, (long long)rep->records, sm->aside);
    return 0;
}

static int load(sharedmap_t *sm)
{
    int rc = lock(sm);
    if (rc < 0)
        return rc;
    int fd = open(sm->path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0)
        return -1;
    uint8_t *buf = NULL;
    size_t len = 0;
    if ((rc = read_all(fd, &buf, &len)) < 0)
        goto err_close;
    const size_t ml = SHAREDMAP_LOG_MAGIC_LEN;
    if (len < ml && memcmp(buf, sharedmap_log_magic, len) == 0) {
        /* New file, or one whose creation was cut short: start it. */
        if (ftruncate(fd, 0) < 0 || pwrite(fd, sharedmap_log_magic, ml, 0) != (ssize_t)ml || fsync(fd) < 0)
            goto err_free;
        if ((rc = ca_fsync_dir(sm->path)) < 0)
            goto err_free;
        sm->loaded = (sharedmap_replay_t){ .format = 2, .end = (int64_t)ml };
    } else if ((rc = sharedmap_log_scan_acked(buf, len, note_acked(sm), replay_record, sm, &sm->loaded)) < 0) {
        goto err_free;      /* EINVAL: not a SharedMap log, never overwrite it */
    }
    const sharedmap_replay_t *rep = &sm->loaded;
    int damaged = sharedmap_log_damaged(rep);
    if (damaged && (rc = on_damage(sm, buf, len)) < 0)
        goto err_free;
    if (rep->torn_bytes > 0 && !damaged && rep->format == 2) {
        /* The torn tail of a write that was never acknowledged. */
        sm->stats.tail_bytes_dropped = rep->torn_bytes;
        if (ftruncate(fd, (off_t)rep->end) < 0 || fsync(fd) < 0)
            goto err_free;
    }
    free(buf);
    close(fd);
    sm->fd = open(sm->path, O_WRONLY | O_APPEND | O_CLOEXEC);
    if (sm->fd < 0)
        return -1;
    sm->log_size = (off_t)rep->end;
    /* A damaged log is replaced by its intact records; an old one is rewritten as today's. */
    if (damaged || rep->format == 1) {
        sm->stats.tail_bytes_dropped = rep->torn_bytes;
        return sharedmap_compact(sm);
    }
    note_write(sm);
    return 0;

err_free:
    MARIE_KEEP_ERRNO(free(buf));
err_close:
    MARIE_KEEP_ERRNO(close(fd));
    return -1;
}

sharedmap_t *sharedmap_open(const char *path, const ca_sink_t *sink)
{
    return sharedmap_open_flags(path, 0, sink);
}

sharedmap_t *sharedmap_open_flags(const char *path, unsigned flags, const ca_sink_t *sink)
{
    sharedmap_t *sm = calloc(1, sizeof *sm);
    if (!sm)
        return NULL;
    sm->flags = flags;
    sm->fd = -1;
    sm->lock_fd = -1;
    sm->compact_min = SHAREDMAP_COMPACT_MIN;
    if (sink)
        sm->sink = *sink;
    if (path) {
        sm->path = strdup(path);
        if (!sm->path || load(sm) < 0) {
            MARIE_KEEP_ERRNO(sharedmap_close(sm));
            return NULL;
        }
    }
    return sm;
}

void sharedmap_close(sharedmap_t *sm)
{
    if (!sm)
        return;
    sharedmap_detach(sm);
    if (sm->fd >= 0)
        close(sm->fd);
    if (sm->lock_fd >= 0)
        close(sm->lock_fd);
    for (size_t i = 0; i < sm->n; i++)
        entry_free(&sm->entries[i]);
    free(sm->entries);
    free(sm->buf);
    free(sm->path);
    free(sm->aside);
    free(sm->snap_channel);
    free(sm->snap_source);
    free(sm);
}

/* Append one record and make it durable. On failure the log is cut back to its last
 * acknowledged record, so a failed write cannot reappear at the next start. */
static int log_append(sharedmap_t *sm, const uint8_t *rec, size_t len)
{
    if (sm->fd < 0)
        return 0;
    size_t off = 0;
    while (off < len) {
        ssize_t w = write(sm->fd, rec + off, len - off);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            goto err;
        off += (size_t)w;
    }
    if (fdatasync(sm->fd) < 0)
        goto err;
    sm->stats.fsyncs++;
    sm->log_size += (off_t)len;
    sm->nrecords++;
    sm->seq++;
    note_write(sm);
    return 0;
err:;
    int e = errno ? errno : EIO;
    sm->stats.io_errors++;
    if (ftruncate(sm->fd, sm->log_size) == 0)
        fdatasync(sm->fd);
    ca_note(&sm->sink, CA_NOTE_EVENT, "sharedmap_io_error", 3, "%s: write failed: %s", sm->path,
            strerror(e));
    return marie_fail(EIO);
}

static void maybe_compact(sharedmap_t *sm)
{
    if (sm->fd >= 0 && sm->nrecords > 2 * (int64_t)sm->n + sm->compact_min)
        sharedmap_compact(sm);
}

void sharedmap_set_compaction(sharedmap_t *sm, int64_t min_records)
{
    sm->compact_min = min_records < 0 ? 0 : min_records;
}

int sharedmap_set(sharedmap_t *sm, const char *key, const char *type, const void *data,
                  size_t len, int64_t now)
{
    size_t klen = key ? strlen(key) : 0, tlen = type ? strlen(type) : 0;
    if (klen == 0 || klen > SHAREDMAP_MAX_KEY || tlen > SHAREDMAP_MAX_TYPE || len < 8)
        return marie_fail(EINVAL);
    if (len > SHAREDMAP_MAX_VALUE)
        return marie_fail(EFBIG);
    const marie_type_t *t = marie_type_find(type);
    if (t && ca_payload_check(t, data, len, NULL) < 0)
        return marie_fail(EBADMSG);
    int rc = grow(sm, sharedmap_log_record_size(klen, tlen, len));
    if (rc < 0)
        return rc;
    int64_t version = sm->version + 1;
    sharedmap_log_rec_t r = { SHAREDMAP_LOG_SET, sm->seq + 1, version, now, key, type, data, len };
    size_t n = sharedmap_log_encode(sm->buf, &r);
    if ((rc = log_append(sm, sm->buf, n)) < 0)
        return rc;
    if ((rc = mem_set(sm, key, type, data, len, version, now)) < 0)
        return rc;
    sm->version = version;
    sm->snap_due = 1;
    sm->stats.sets++;
    maybe_compact(sm);
    return 0;
}

int sharedmap_delete(sharedmap_t *sm, const char *key)
{
    int found;
    if (!key || !*key || strlen(key) > SHAREDMAP_MAX_KEY)
        return marie_fail(EINVAL);
    find(sm, key, &found);
    if (!found)
        return marie_fail(ENOENT);
    int rc = grow(sm, sharedmap_log_record_size(strlen(key), 0, 0));
    if (rc < 0)
        return rc;
    int64_t version = sm->version + 1;
    sharedmap_log_rec_t r = { SHAREDMAP_LOG_DEL, sm->seq + 1, version, 0, key, NULL, NULL, 0 };
    size_t n = sharedmap_log_encode(sm->buf, &r);
    if ((rc = log_append(sm, sm->buf, n)) < 0)
        return rc;
    mem_delete(sm, key);
    sm->version = version;
    sm->snap_due = 1;
    sm->stats.deletes++;
    maybe_compact(sm);
    return 0;
}

static void fill(const entry_t *e, sharedmap_value_t *out)
{
    *out = (sharedmap_value_t){ e->key, e->type, e->data, e->len, e->version, e->set_utime };
}

int sharedmap_get(const sharedmap_t *sm, const char *key, sharedmap_value_t *out)
{
    int found;
    size_t i = (size_t)find(sm, key, &found);
    if (!found)
        return marie_fail(ENOENT);
    if (out)
        fill(&sm->entries[i], out);
    return 0;
}

size_t sharedmap_size(const sharedmap_t *sm) { return sm->n; }
int64_t sharedmap_version(const sharedmap_t *sm) { return sm->version; }
const sharedmap_stats_t *sharedmap_stats(const sharedmap_t *sm) { return &sm->stats; }

int sharedmap_entry(const sharedmap_t *sm, size_t i, sharedmap_value_t *out)
{
    if (i >= sm->n)
        return marie_fail(ENOENT);
    fill(&sm->entries[i], out);
    return 0;
}

int sharedmap_compact(sharedmap_t *sm)
{
    if (sm->fd < 0)
        return 0;
    size_t total = SHAREDMAP_LOG_MAGIC_LEN + sharedmap_log_record_size(0, 0, 0);
    for (size_t i = 0; i < sm->n; i++)
        total += sharedmap_log_record_size(strlen(sm->entries[i].key), strlen(sm->entries[i].type), sm->entries[i].len);
    uint8_t *img = malloc(total);
    if (!img)
        return marie_fail(ENOMEM);
    memcpy(img, sharedmap_log_magic, SHAREDMAP_LOG_MAGIC_LEN);
    size_t off = SHAREDMAP_LOG_MAGIC_LEN;
    int64_t seq = 0;
    /* The version first: the last change may have been a delete, which leaves no entry to
     * carry it, and a version must never go back. */
    sharedmap_log_rec_t vr = { SHAREDMAP_LOG_VERSION, ++seq, sm->version, 0, "", NULL, NULL, 0 };
    off += sharedmap_log_encode(img + off, &vr);
    for (size_t i = 0; i < sm->n; i++) {
        const entry_t *e = &sm->entries[i];
        sharedmap_log_rec_t r = { SHAREDMAP_LOG_SET, ++seq, e->version, e->set_utime,
                                  e->key, e->type, e->data, e->len };
        off += sharedmap_log_encode(img + off, &r);
    }
    /* The old log stays complete until the rename replaces it, so a crash at any point
     * leaves one whole log or the other. */
    int rc = ca_write_file_atomic(sm->path, img, off);
    MARIE_KEEP_ERRNO(free(img));
    if (rc < 0) {
        sm->stats.io_errors++;
        MARIE_KEEP_ERRNO(ca_note(&sm->sink, CA_NOTE_EVENT, "sharedmap_io_error", 2, "%s: compaction failed: %s",
                                 sm->path, strerror(errno)));
        return -1;
    }
    int fd = open(sm->path, O_WRONLY | O_APPEND | O_CLOEXEC);
    if (fd < 0)
        return -1;
    close(sm->fd);
    sm->fd = fd;
    sm->log_size = (off_t)off;
    sm->nrecords = seq;
    sm->seq = seq;
    sm->stats.compactions++;
    note_write(sm);
    return 0;
}

/* ---- request protocol ---- */

static int send_reply(sharedmap_t *sm, const char *channel, marie_sharedmap_reply_t *r)
{
    int need = marie_sharedmap_reply_t_encoded_size(r);
    if (need < 0 || grow(sm, (size_t)need) < 0)
        return marie_fail(ENOMEM);
    int n = marie_sharedmap_reply_t_encode(sm->buf, 0, need, r);
    if (n < 0)
        return marie_fail(EINVAL);
    if (ca_publish(&sm->sink, channel, sm->buf, (size_t)n) < 0) {
        ca_note(&sm->sink, CA_NOTE_DROP, "reply_failed", 1, "reply to %s failed", channel);
        return marie_fail(EIO);
    }
    return 0;
}

static int8_t status_of(int err)
{
    switch (err) {
    case 0: return MARIE_SHAREDMAP_REPLY_T_STATUS_OK;
    case ENOENT: return MARIE_SHAREDMAP_REPLY_T_STATUS_NOT_FOUND;
    case EBADMSG: return MARIE_SHAREDMAP_REPLY_T_STATUS_BAD_TYPE;
    case EFBIG: return MARIE_SHAREDMAP_REPLY_T_STATUS_TOO_LARGE;
    case EINVAL: return MARIE_SHAREDMAP_REPLY_T_STATUS_BAD_REQUEST;
    default: return MARIE_SHAREDMAP_REPLY_T_STATUS_IO_ERROR;
    }
}

int sharedmap_handle_request(sharedmap_t *sm, const marie_sharedmap_request_t *req, int64_t now)
{
    sm->stats.requests++;
    if (!req->reply_channel || !*req->reply_channel) {
        sm->stats.bad_requests++;
        ca_note(&sm->sink, CA_NOTE_BAD_INPUT, "bad_request", 1,
                "request %lld from '%s' has no reply channel", (long long)req->request_id,
                req->client ? req->client : "");
        return marie_fail(EINVAL);
    }
    marie_sharedmap_reply_t r = {
        .utime = now, .request_id = req->request_id, .client = req->client ? req->client : "",
        .op = req->op, .key = req->key ? req->key : "", .type = "",
        .data = (uint8_t *)"",      /* lcm-gen's encoder memcpy()s even 0 bytes */
    };
    char **keys = NULL;
    int err;                    /* 0, or the errno of the refusal */
    sharedmap_value_t v;
    switch (req->op) {
    case MARIE_SHAREDMAP_REQUEST_T_OP_SET:
        err = req->size < 0 ? EINVAL
              : sharedmap_set(sm, req->key, req->type, req->data, (size_t)req->size, now) < 0 ? errno : 0;
        if (err == 0)
            r.version = sm->version;
        break;
    case MARIE_SHAREDMAP_REQUEST_T_OP_GET:
        sm->stats.gets++;
        err = sharedmap_get(sm, r.key, &v) < 0 ? errno : 0;
        if (err == 0) {
            r.version = v.version;
            r.type = (char *)v.type;
            r.age_us = now - v.set_utime;
            r.size = (int32_t)v.len;
            r.data = (uint8_t *)v.data;
        }
        break;
    case MARIE_SHAREDMAP_REQUEST_T_OP_DELETE:
        err = sharedmap_delete(sm, r.key) < 0 ? errno : 0;
        if (err == 0)
            r.version = sm->version;
        break;
    case MARIE_SHAREDMAP_REQUEST_T_OP_LIST: {
        sm->stats.lists++;
        size_t plen = strlen(r.key);
        keys = malloc((sm->n ? sm->n : 1) * sizeof *keys);
        if (!keys) {
            err = ENOMEM;
            break;
        }
        for (size_t i = 0; i < sm->n; i++)
            if (strncmp(sm->entries[i].key, r.key, plen) == 0)
                keys[r.nkeys++] = sm->entries[i].key;
        r.keys = keys;
        r.version = sm->version;
        err = 0;
        break;
    }
    default:
        err = EINVAL;
        break;
    }
    r.status = status_of(err);
    if (err == EINVAL || err == EBADMSG || err == EFBIG) {
        sm->stats.bad_requests++;
        ca_note(&sm->sink, CA_NOTE_BAD_INPUT, "bad_request", 1,
                "request %lld from '%s' (op %d, key '%.64s') refused: %s", (long long)req->request_id,
                r.client, req->op, r.key, strerror(err));
    }
    send_reply(sm, req->reply_channel, &r);
    free(keys);
    if (sm->snap_due)
        sharedmap_tick(sm, now);
    return err ? marie_fail(err) : 0;
}

int sharedmap_handle_request_raw(sharedmap_t *sm, const void *buf, size_t len, int64_t now)
{
    marie_sharedmap_request_t req;
    if (marie_decode_checked(&marie_type_sharedmap_request_t, buf, len, &req) < 0) {
        sm->stats.bad_requests++;
        return ca_bad_request(&sm->sink, NULL, "SharedMap request", buf, len);
    }
    int rc = sharedmap_handle_request(sm, &req, now);
    MARIE_KEEP_ERRNO(marie_sharedmap_request_t_decode_cleanup(&req));
    return rc;
}

void sharedmap_set_snapshot(sharedmap_t *sm, const char *channel, const char *source,
                            int64_t min_interval_us)
{
    free(sm->snap_channel);
    free(sm->snap_source);
    sm->snap_channel = channel && *channel ? strdup(channel) : NULL;
    sm->snap_source = strdup(source ? source : "");
    sm->snap_min_interval = min_interval_us;
}

int sharedmap_publish_snapshot(sharedmap_t *sm, int64_t now)
{
    if (!sm->snap_channel)
        return 0;
    marie_sharedmap_entry_t *es = calloc(sm->n ? sm->n : 1, sizeof *es);
    if (!es)
        return marie_fail(ENOMEM);
    for (size_t i = 0; i < sm->n; i++) {
        const entry_t *e = &sm->entries[i];
        es[i] = (marie_sharedmap_entry_t){ e->key, e->type, e->version, e->set_utime,
                                           (int32_t)e->len, e->data };
    }
    marie_sharedmap_snapshot_t s = { .utime = now, .source = sm->snap_source,
                                     .version = sm->version, .nentries = (int32_t)sm->n,
                                     .entries = es };
    int rc;
    int need = marie_sharedmap_snapshot_t_encoded_size(&s);
    if (need < 0 || grow(sm, (size_t)need) != 0) {
        rc = marie_fail(ENOMEM);
    } else {
        int n = marie_sharedmap_snapshot_t_encode(sm->buf, 0, need, &s);
        rc = n < 0 ? marie_fail(EINVAL) : ca_publish(&sm->sink, sm->snap_channel, sm->buf, (size_t)n);
    }
    MARIE_KEEP_ERRNO(free(es));
    sm->snap_due = 0;
    sm->snap_last = now;
    sm->stats.snapshots++;
    return rc;
}

void sharedmap_tick(sharedmap_t *sm, int64_t now)
{
    if (sm->snap_due && now - sm->snap_last >= sm->snap_min_interval)
        sharedmap_publish_snapshot(sm, now);
}

static void on_request(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    sharedmap_handle_request_raw(user, rbuf->data, rbuf->data_size, marie_wall_us());
}

int sharedmap_attach(sharedmap_t *sm, lcm_t *lcm, const char *request_channel)
{
    if (sm->lcm)
        return marie_fail(EALREADY);
    char *pat = ca_channel_pattern(request_channel);
    if (!pat)
        return marie_fail(ENOMEM);
    sm->sub = marie_bus_subscribe(lcm, pat, on_request, sm);
    free(pat);
    if (!sm->sub)
        return marie_fail(EIO);
    sm->lcm = lcm;
    sm->sink.lcm = lcm;
    return 0;
}

void sharedmap_detach(sharedmap_t *sm)
{
    if (!sm->lcm)
        return;
    marie_bus_unsubscribe(sm->lcm, sm->sub);
    sm->sub = NULL;
    sm->lcm = NULL;
}
