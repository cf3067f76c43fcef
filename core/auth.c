/* auth: HMAC-SHA256 (libsodium) over encoded orders, key file checks, replay table. */
#include "core/auth.h"

#include <errno.h>
#include <stdbool.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <sodium.h>

#include "core/err.h"
#include "core/log.h"
#include "core/time.h"

struct marie_auth {
    uint8_t key[MARIE_AUTH_KEY_LEN];
};

static int hexval(int c)
{
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

marie_auth_t *marie_auth_load(const char *path, char *err, size_t errlen)
{
    char dummy[8];
    if (!err) { err = dummy; errlen = sizeof dummy; }
    err[0] = 0;
    if (sodium_init() < 0) {
        snprintf(err, errlen, "libsodium failed to initialise");
        return marie_fail_null(EIO);
    }
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
    if (fd < 0) {
        int e = errno;
        snprintf(err, errlen, "key file %s: %s", path, strerror(e));
        errno = e;
        return NULL;
    }
    struct stat st;
    uint8_t buf[256];
    ssize_t n = -1;
    marie_auth_t *a = NULL;
    if (fstat(fd, &st) < 0) {
        snprintf(err, errlen, "key file %s: %s", path, strerror(errno));
        goto err_close;
    }
    if (!S_ISREG(st.st_mode)) {
        snprintf(err, errlen, "key file %s is not a regular file", path);
        errno = EINVAL;
        goto err_close;
    }
    if (st.st_mode & 077) {
        snprintf(err, errlen, "key file %s has mode %04o: group or others may read it (chmod 600)",
                 path, (unsigned)(st.st_mode & 07777));
        errno = EACCES;
        goto err_close;
    }
    n = read(fd, buf, sizeof buf);
    if (n < 0) {
        snprintf(err, errlen, "key file %s: %s", path, strerror(errno));
        goto err_close;
    }
    a = calloc(1, sizeof *a);
    if (!a)
        goto err_close;
    if (n == MARIE_AUTH_KEY_LEN && (hexval(buf[0]) < 0 || hexval(buf[1]) < 0 || memchr(buf, 0, (size_t)n))) {
        memcpy(a->key, buf, MARIE_AUTH_KEY_LEN);        /* raw bytes */
    } else {
        size_t nd = 0;
        for (ssize_t i = 0; i < n; i++) {
            if (buf[i] == ' ' || buf[i] == '\n' || buf[i] == '\r' || buf[i] == '\t')
                continue;
            int v = hexval(buf[i]);
            if (v < 0 || nd >= 2 * MARIE_AUTH_KEY_LEN) { nd = 0; break; }
            a->key[nd / 2] = (uint8_t)(nd % 2 ? a->key[nd / 2] | v : v << 4);
            nd++;
        }
        if (nd != 2 * MARIE_AUTH_KEY_LEN) {
            snprintf(err, errlen, "key file %s: expected 64 hex digits or 32 raw bytes", path);
            errno = EINVAL;
            goto err_free;
        }
    }
    sodium_memzero(buf, sizeof buf);
    close(fd);
    return a;
err_free:
    sodium_memzero(a, sizeof *a);
    free(a);
err_close:
    sodium_memzero(buf, sizeof buf);
    MARIE_KEEP_ERRNO(close(fd));
    return NULL;
}

marie_auth_t *marie_auth_from_key(const uint8_t key[MARIE_AUTH_KEY_LEN])
{
    if (sodium_init() < 0)
        return NULL;
    marie_auth_t *a = calloc(1, sizeof *a);
    if (a)
        memcpy(a->key, key, MARIE_AUTH_KEY_LEN);
    return a;
}

void marie_auth_destroy(marie_auth_t *a)
{
    if (!a)
        return;
    sodium_memzero(a, sizeof *a);
    free(a);
}

int marie_auth_keygen(const char *path)
{
    if (sodium_init() < 0)
        return marie_fail(EIO);
    int fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0)
        return -1;
    uint8_t key[MARIE_AUTH_KEY_LEN];
    char hex[2 * MARIE_AUTH_KEY_LEN + 2];
    randombytes_buf(key, sizeof key);
    sodium_bin2hex(hex, sizeof hex, key, sizeof key);
    strcat(hex, "\n");
    ssize_t w = write(fd, hex, strlen(hex));
    int rc = (w == (ssize_t)strlen(hex)) ? 0 : marie_fail(EIO);
    sodium_memzero(key, sizeof key);
    sodium_memzero(hex, sizeof hex);
    if (rc < 0)
        MARIE_KEEP_ERRNO(close(fd));
    else if (close(fd) < 0)
        rc = -1;
    return rc;
}

void marie_auth_mac(const marie_auth_t *a, const void *data, size_t len, uint8_t mac[MARIE_AUTH_MAC_LEN])
{
    crypto_auth_hmacsha256(mac, data, len, a->key);
}

int marie_auth_verify(const marie_auth_t *a, const void *data, size_t len, const uint8_t *mac, size_t maclen)
{
    if (!mac || maclen != MARIE_AUTH_MAC_LEN)
        return marie_fail(EBADMSG);
    return crypto_auth_hmacsha256_verify(mac, data, len, a->key) == 0 ? 0 : marie_fail(EBADMSG);
}

/* Encode a copy of the message with an empty MAC: what the MAC covers. (liblcm copies
 * even an empty byte array with memcpy, so the pointer must not be NULL.) */
static uint8_t no_mac[1];
#define ENCODE_UNSIGNED(type, msg, out_buf, out_len) do {                         \
        type tmp_ = *(msg);                                                       \
        tmp_.mac_len = 0;                                                         \
        tmp_.mac = no_mac;                                                        \
        int n_ = type##_encoded_size(&tmp_);                                      \
        (out_buf) = n_ > 0 ? malloc((size_t)n_) : NULL;                           \
        (out_len) = marie_fail(ENOMEM);                                           \
        if (out_buf) {                                                            \
            (out_len) = type##_encode((out_buf), 0, n_, &tmp_);                   \
            if ((out_len) < 0) (out_len) = marie_fail(EINVAL);                    \
        }                                                                         \
    } while (0)



const char *marie_auth_result_name(marie_auth_result_t r)
{
    switch (r) {
    case MARIE_AUTH_OK: return "ok";
    case MARIE_AUTH_UNSIGNED: return "unsigned";
    case MARIE_AUTH_FORGED: return "forged";
    case MARIE_AUTH_REPLAYED: return "replayed";
    case MARIE_AUTH_NOKEY: return "no key";
    case MARIE_AUTH_STALE: return "stale";
    case MARIE_AUTH_FUTURE: return "future";
    }
    return "?";
}

/* ---- replay table ---- */
typedef struct {
    char *sender;
    int64_t seq;
} replay_entry_t;

struct marie_replay {
    char *path;
    replay_entry_t *e;
    size_t n;
    int64_t epoch;              /* receiver's wall clock at creation: older orders were never ours */
    int64_t lifetime_us, max_skew_us;
};

static replay_entry_t *replay_find(const marie_replay_t *r, const char *sender)
{
    for (size_t i = 0; i < r->n; i++)
        if (strcmp(r->e[i].sender, sender) == 0)
            return &r->e[i];
    return NULL;
}

static int replay_set(marie_replay_t *r, const char *sender, int64_t seq)
{
    replay_entry_t *e = replay_find(r, sender);
    if (e) {
        e->seq = seq;
        return 0;
    }
    replay_entry_t *ne = realloc(r->e, (r->n + 1) * sizeof *ne);
    if (!ne)
        return marie_fail(ENOMEM);
    r->e = ne;
    r->e[r->n].sender = strdup(sender);
    if (!r->e[r->n].sender)
        return marie_fail(ENOMEM);
    r->e[r->n].seq = seq;
    r->n++;
    return 0;
}

/* Drop marks that can no longer matter (every order at or below them is stale now), and
 * marks no order in the window could have set; returns how many of the latter went. */
static size_t replay_prune(marie_replay_t *r, int64_t now)
{
    size_t bogus = 0, k = 0;
    for (size_t i = 0; i < r->n; i++) {
        replay_entry_t *e = &r->e[i];
        bool future = e->seq > now + r->max_skew_us;
        if (future || e->seq < now - r->lifetime_us - r->max_skew_us) {
            bogus += future;
            free(e->sender);
            continue;
        }
        r->e[k++] = *e;
    }
    r->n = k;
    return bogus;
}

/* One "seq sender" per line; a sender name has no newline (checked on the way in). */
static void replay_save(const marie_replay_t *r)
{
    if (!r->path)
        return;
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.tmp", r->path);
    FILE *f = fopen(tmp, "w");
    if (!f)
        return;
    for (size_t i = 0; i < r->n; i++)
        fprintf(f, "%lld %s\n", (long long)r->e[i].seq, r->e[i].sender);
    if (fclose(f) == 0)
        rename(tmp, r->path);
}

static void replay_load(marie_replay_t *r)
{
    FILE *f = fopen(r->path, "r");
    if (!f)
        return;
    char line[512];
    unsigned lineno = 0, bad = 0;
    while (fgets(line, sizeof line, f)) {
        long long seq;
        char sender[400];
        lineno++;
        if (sscanf(line, "%lld %399[^\n]", &seq, sender) == 2)
            replay_set(r, sender, seq);
        else if (bad++ == 0)
            marie_warn("%s:%u: not a 'seq sender' line: ignored", r->path, lineno);
    }
    fclose(f);
    size_t bogus = replay_prune(r, r->epoch);
    if (bogus)
        marie_warn("%s: %zu sender mark(s) beyond now + %.1f s dropped (an older marie kept any seq)", r->path,
                   bogus, r->max_skew_us / 1e6);
}

marie_replay_t *marie_replay_create_window(const char *path, int64_t lifetime_us, int64_t max_skew_us)
{
    if (lifetime_us < 0 || max_skew_us < 0 || lifetime_us > INT64_MAX / 8 || max_skew_us > INT64_MAX / 8)
        return marie_fail_null(EINVAL);
    marie_replay_t *r = calloc(1, sizeof *r);
    if (!r)
        return NULL;
    r->epoch = marie_wall_us();
    r->lifetime_us = lifetime_us;
    r->max_skew_us = max_skew_us;
    if (path) {
        if (!(r->path = strdup(path))) {
            free(r);
            return NULL;
        }
        replay_load(r);
    }
    return r;
}

marie_replay_t *marie_replay_create(const char *path)
{
    return marie_replay_create_window(path, MARIE_AUTH_LIFETIME_US, MARIE_AUTH_MAX_SKEW_US);
}

void marie_replay_destroy(marie_replay_t *r)
{
    if (!r)
        return;
    for (size_t i = 0; i < r->n; i++)
        free(r->e[i].sender);
    free(r->e);
    free(r->path);
    free(r);
}

int64_t marie_replay_last(const marie_replay_t *r, const char *sender)
{
    replay_entry_t *e = replay_find(r, sender);
    return e ? e->seq : 0;
}

int64_t marie_replay_epoch(const marie_replay_t *r)
{
    return r->epoch;
}

/* The window bounds both times the order carries: utime is what a reader sees, seq is what
 * the marks remember; a sender's seq runs ahead of its clock only by orders per microsecond. */
static marie_auth_result_t check_fresh(marie_replay_t *r, const char *sender, int64_t utime, int64_t seq)
{
    if (!sender || strchr(sender, '\n') || strlen(sender) > 256)
        return MARIE_AUTH_FORGED;
    if (!r)
        return MARIE_AUTH_OK;
    int64_t now = marie_wall_us();
    int64_t oldest = now - r->lifetime_us - r->max_skew_us, newest = now + r->max_skew_us;
    if (utime < oldest || seq < oldest)
        return MARIE_AUTH_STALE;
    if (utime > newest || seq > newest)
        return MARIE_AUTH_FUTURE;
    if (seq <= r->epoch || seq <= marie_replay_last(r, sender))
        return MARIE_AUTH_REPLAYED;
    if (replay_set(r, sender, seq) == 0) {
        replay_prune(r, now);
        replay_save(r);
    }
    return MARIE_AUTH_OK;
}



int64_t marie_auth_next_seq(const char *path)
{
    int64_t now = marie_wall_us();
    if (!path)
        return now;
    int fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0600);
    if (fd < 0)
        return now;
    int64_t seq = now;
    if (flock(fd, LOCK_EX) == 0) {
        char buf[32] = {0};
        ssize_t n = pread(fd, buf, sizeof buf - 1, 0);
        long long last = n > 0 ? atoll(buf) : 0;
        if (last >= seq && last <= now + MARIE_AUTH_MAX_SKEW_US)
            seq = last + 1;
        int len = snprintf(buf, sizeof buf, "%lld\n", (long long)seq);
        if (pwrite(fd, buf, (size_t)len, 0) == len)
            (void)ftruncate(fd, len);
        flock(fd, LOCK_UN);
    }
    close(fd);
    return seq;
}

/* Signing and checking of one signed message type: every one carries utime, sender, seq and a
 * mac (mac_len bytes), and its MAC covers its encoding with an empty mac. */
#define MARIE_AUTH_SIGNED(type, sign_fn, check_fn)                                                   \
    int sign_fn(const marie_auth_t *a, type *m, uint8_t store[MARIE_AUTH_MAC_LEN])                   \
    {                                                                                                \
        uint8_t *buf;                                                                                \
        int n;                                                                                       \
        ENCODE_UNSIGNED(type, m, buf, n);                                                            \
        if (n >= 0)                                                                                  \
            marie_auth_mac(a, buf, (size_t)n, store);                                                \
        MARIE_KEEP_ERRNO(free(buf));                                                                 \
        if (n < 0)                                                                                   \
            return -1;                                                                               \
        m->mac = store;                                                                              \
        m->mac_len = MARIE_AUTH_MAC_LEN;                                                             \
        return 0;                                                                                    \
    }                                                                                                \
    marie_auth_result_t check_fn(const marie_auth_t *a, marie_replay_t *r, const type *m)            \
    {                                                                                                \
        if (m->mac_len <= 0)                                                                         \
            return MARIE_AUTH_UNSIGNED;                                                              \
        if (!a)                                                                                      \
            return MARIE_AUTH_NOKEY;                                                                 \
        uint8_t *buf;                                                                                \
        int n;                                                                                       \
        ENCODE_UNSIGNED(type, m, buf, n);                                                            \
        int ok = n >= 0 && marie_auth_verify(a, buf, (size_t)n, m->mac, (size_t)m->mac_len) == 0;    \
        free(buf);                                                                                   \
        return ok ? check_fresh(r, m->sender, m->utime, m->seq) : MARIE_AUTH_FORGED;                 \
    }

MARIE_AUTH_SIGNED(marie_am_order_t, marie_auth_sign_order, marie_auth_check_order)
MARIE_AUTH_SIGNED(marie_lifecycle_command_t, marie_auth_sign_command, marie_auth_check_command)
MARIE_AUTH_SIGNED(marie_goal_request_t, marie_auth_sign_goal_request, marie_auth_check_goal_request)
MARIE_AUTH_SIGNED(marie_param_request_t, marie_auth_sign_param, marie_auth_check_param)
