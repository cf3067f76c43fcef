/* ca: what the Communication Adapters share: type lookup, fingerprint checks, counters, channel names. */
#ifndef MARIE_CA_H
#define MARIE_CA_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <lcm/lcm.h>

#include "core/bus/bus.h"
#include "core/bus/bus.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_types.h"
#include "lcmtypes/marie_pull_reply_t.h"
#include "lcmtypes/marie_pull_request_t.h"
#include "lcmtypes/marie_sharedmap_reply_t.h"
#include "lcmtypes/marie_sharedmap_request_t.h"
#include "lcmtypes/marie_switch_select_t.h"

#ifdef __cplusplus
extern "C" {
#endif

/* What a CA reports to whoever hosts it (the marie-ca process forwards these to the
 * component's heartbeat counters and events; a test may just count them). */
typedef enum {
    CA_NOTE_BAD_INPUT = 0,  /* malformed or mistyped input, dropped */
    CA_NOTE_DROP,           /* a good message lost (overflow, send failure) */
    CA_NOTE_COUNT,          /* an ordinary counter */
    CA_NOTE_EVENT,          /* a notable occurrence (refusal, restore) */
} ca_note_kind_t;

/* `counter` names the counter or event kind; `n` the increment (events: a severity,
 * marie_event_t SEV_*); `text` a human description (may be NULL for plain counts). */
typedef void (*ca_note_fn)(void *user, ca_note_kind_t kind, const char *counter, int64_t n,
                           const char *text);
/* Publishes `len` bytes on `channel`; returns 0 or a negative value. */
typedef int (*ca_publish_fn)(void *user, const char *channel, const void *buf, size_t len);

/* Where a CA's output goes: `publish` if set, else straight onto `lcm` (set by the
 * *_attach() calls). */
typedef struct {
    ca_note_fn note;
    ca_publish_fn publish;
    void *user;
    lcm_t *lcm;
} ca_sink_t;

void ca_note(const ca_sink_t *s, ca_note_kind_t kind, const char *counter, int64_t n,
             const char *fmt, ...) __attribute__((format(printf, 5, 6)));
int ca_publish(const ca_sink_t *s, const char *channel, const void *buf, size_t len);
/* Counts (counter bad_request) and reports an undecodable request: "[where: ]undecodable
 * WHAT (N bytes, fingerprint F)". Returns -1 with errno EBADMSG for the caller to pass on. */
int ca_bad_request(const ca_sink_t *s, const char *where, const char *what, const void *buf, size_t len);

/* The big-endian fingerprint that starts every LCM payload; -1 with errno EBADMSG when len < 8. */
int ca_fingerprint(const void *raw, size_t len, int64_t *fp);
/* 0 when `raw` carries `type` (NULL type: any payload of at least 8 bytes), else -1 with errno EBADMSG. */
int ca_check_type(const marie_type_t *type, const void *raw, size_t len);

/* Whether a CA may store or forward `raw`: it carries `type` (NULL: any), and when its
 * fingerprint is a marie type, it is well formed (marie_typeinfo_check) with every float and
 * double finite, as a component's input port would demand; a CA never hands on what every
 * receiver would drop. 0, or -1 with errno EBADMSG and *why (if why is not NULL) the counter to bump:
 * "bad_fingerprint", "bad_payload" or "bad_nonfinite". */
int ca_payload_check(const marie_type_t *type, const void *raw, size_t len, const char **why);
/* ca_payload_check() that also counts and reports a refusal through the sink (kind
 * CA_NOTE_BAD_INPUT, the counter named by why), naming `channel`. 0, or -1 with errno EBADMSG. */
int ca_input_check(const ca_sink_t *s, const marie_type_t *type, const char *channel, const void *raw, size_t len);

/* `channel` as an LCM subscription pattern that matches only itself (lcm_subscribe takes a
 * regular expression). Caller frees. */
char *ca_channel_pattern(const char *channel);

/* A CA's input channel, read through the bus: from LCM, or from the ring on this host when the
 * system file puts the channel on shared memory (`transports:`; the messages over LCM when the
 * writer is on another host). `fn(user, bytes, len, recv_utime)` gets each message, whichever
 * way it came. */
typedef void (*ca_input_fn)(void *user, const void *buf, size_t len, int64_t recv_utime);
typedef struct {
    lcm_t *lcm;
    marie_bus_sub_t *sub;
    ca_input_fn fn;
    void *user;
} ca_input_t;
/* 0, or -1 with errno ENOMEM or EIO (nothing left open). */
int ca_input_open(ca_input_t *in, lcm_t *lcm, const char *channel, ca_input_fn fn, void *user);
void ca_input_close(ca_input_t *in);    /* no-op when not open */
/* The input's counts since it opened (zero on LCM): `lost` overwritten in shared memory before
 * they were read, `bad` malformed notices. */
marie_bus_sub_stats_t ca_input_stats(const ca_input_t *in);

/* CRC-32 (IEEE 802.3), for the SharedMap's log records. */
uint32_t ca_crc32(uint32_t crc, const void *buf, size_t len);

/* fsync the directory holding `path`, so a create or rename in it is durable. 0, or -1 with errno. */
int ca_fsync_dir(const char *path);

/* Writes `len` bytes to `path` durably and atomically: a temporary file in the same
 * directory, fsync, rename over `path`, fsync of the directory. 0, or -1 with errno. */
int ca_write_file_atomic(const char *path, const void *buf, size_t len);

#ifdef __cplusplus
}
#endif
#endif
