/* mailbox: keeps the last N payloads of one channel and answers pull requests for them. */
#ifndef MARIE_CA_MAILBOX_H
#define MARIE_CA_MAILBOX_H

#include <stddef.h>
#include <stdint.h>

#include "ca/ca.h"
#include "lcmtypes/marie_pull_request_t.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct mailbox mailbox_t;

typedef struct {
    int64_t received;       /* payloads accepted */
    int64_t overflow;       /* oldest payloads dropped because the buffer was full */
    int64_t bad_input;      /* payloads with the wrong fingerprint */
    int64_t requests;       /* pull requests decoded */
    int64_t bad_requests;   /* undecodable or invalid requests */
    int64_t replies;        /* replies sent (any status) */
    int64_t waited;         /* requests held until data arrived or their deadline */
} mailbox_stats_t;

/* A Mailbox of `channel` holding the newest `depth` (>= 1) payloads of `type` (NULL:
 * any payload; only its 8-byte fingerprint is checked). Replies go through sink->publish,
 * counters and bad input through sink->note. NULL with errno on failure. */
mailbox_t *mailbox_create(const char *channel, const marie_type_t *type, int depth,
                          const ca_sink_t *sink);
void mailbox_destroy(mailbox_t *mb);          /* NULL is a no-op */

const char *mailbox_channel(const mailbox_t *mb);
/* The channel its pull requests arrive on: channel MARIE_PULL_SUFFIX (".PULL"). */
const char *mailbox_pull_channel(const mailbox_t *mb);
/* At most this many requests wait for data at once; beyond, the oldest is answered EMPTY. */
#define MAILBOX_MAX_WAITING 256

/* Store a payload received at recv_utime (wall clock, us). The oldest is dropped (and
 * counted) when full. Requests waiting for data are answered. 0, or -1 with errno EBADMSG when the
 * fingerprint does not match (counted, not stored). */
int mailbox_push(mailbox_t *mb, const void *raw, size_t len, int64_t recv_utime);

/* Answer a pull request at wall time `now`: OK with the newest payload and its age; if
 * empty, the request waits for data until shortly before its timeout (so its EMPTY
 * answer still reaches the requester), or is answered EMPTY at once when timeout_ms <= 0.
 * A request for another channel is answered UNKNOWN_CHANNEL. Returns 0 when answered,
 * 1 when held, -1 with errno EINVAL for an invalid request (answered BAD_REQUEST when it names a
 * reply channel). */
int mailbox_handle_request(mailbox_t *mb, const marie_pull_request_t *req, int64_t now);
/* The same from an encoded pull_request_t; undecodable bytes are counted and dropped
 * (-1 with errno EBADMSG). */
int mailbox_handle_request_raw(mailbox_t *mb, const void *buf, size_t len, int64_t now);

/* Answer the waiting requests whose deadline is <= now with EMPTY. Returns how many. */
int mailbox_tick(mailbox_t *mb, int64_t now);
/* Earliest deadline of a waiting request, or INT64_MAX. */
int64_t mailbox_next_deadline(const mailbox_t *mb);

/* In-process access: number held, and the i-th newest (0 = newest). The pointer stays
 * valid until the next push. 0, or -1 with errno ENODATA. */
size_t mailbox_count(const mailbox_t *mb);
int mailbox_peek(const mailbox_t *mb, size_t i, const void **raw, size_t *len, int64_t *recv_utime);
/* In-process pull of the newest value, decoded with the mailbox's type into msg (free
 * with type->decode_cleanup). 0, or -1 with errno ENODATA (empty), EBADMSG (decode failed), EINVAL (no type). */
int mailbox_latest(const mailbox_t *mb, void *msg, int64_t now, int64_t *age_us);

const mailbox_stats_t *mailbox_stats(const mailbox_t *mb);

/* Serve over LCM: subscribe to the channel and its pull channel on `lcm` (replies go
 * out on it unless the sink has a publish function). A channel the bus's transports put on
 * shared memory is read from its ring (ca_input_open). The host must still call mailbox_tick()
 * (every 10 ms is plenty) to answer requests that time out. 0, or -1 with errno. */
int mailbox_attach(mailbox_t *mb, lcm_t *lcm);
/* Its input's counts since attached (ca_input_stats: zero on LCM). */
marie_bus_sub_stats_t mailbox_input_stats(const mailbox_t *mb);
void mailbox_detach(mailbox_t *mb);           /* unsubscribe; no-op when not attached */

#ifdef __cplusplus
}
#endif
#endif
