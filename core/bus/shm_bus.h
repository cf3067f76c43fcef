/* shm_bus: a channel's messages through same-host shared memory, with notices and fallback on LCM. */
#ifndef MARIE_SHM_BUS_H
#define MARIE_SHM_BUS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include <lcm/lcm.h>

#include "core/shm.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The host whose memory a segment is in: gethostname(), or MARIE_SHM_HOST where machines share a
 * name (containers) or a test plays another host. */
void marie_shm_host(char *out, size_t cap);

/* A publisher writes each encoded message (the LCM payload, fingerprint first) into its ring
 * (core/shm.h) and publishes a marie.shm_notice_t on CHANNEL.SHM. The message itself goes on
 * CHANNEL over LCM only while someone that cannot map the ring has asked for it on
 * CHANNEL.SHMWANT within the last 2 s (another host's subscriber, a recorder, lcm-spy's user):
 * so lcm-spy and lcm-logger always see the notices, and the messages on request. The
 * publisher's lcm_t must be handled by its owner's loop for the requests to be heard. */
typedef struct marie_shm_pub marie_shm_pub_t;

typedef struct {
    int64_t published;          /* messages written and noticed */
    int64_t lcm_copies;         /* of those, also sent whole on LCM for a remote subscriber */
    int64_t wants;              /* requests heard */
    int64_t too_big;            /* refused: larger than a slot */
} marie_shm_pub_stats_t;

marie_shm_pub_t *marie_shm_pub_create(lcm_t *lcm, const char *channel, size_t max_size, int nslots);
void marie_shm_pub_destroy(marie_shm_pub_t *p);         /* NULL is a no-op */
/* 0, or -1 with errno EMSGSIZE (larger than max_size), EINVAL (shorter than a fingerprint), EIO (LCM). */
int marie_shm_pub_publish(marie_shm_pub_t *p, const void *data, size_t len);
/* Without the copy: fill writes the len encoded bytes straight into the ring (marie_shm_write_with).
 * The same returns, and EINVAL when fill gave up. */
int marie_shm_pub_publish_with(marie_shm_pub_t *p, size_t len, marie_shm_fill_t fill, void *user);
/* Without any copy, for a producer that makes the message where it will be read: the loan is
 * the next slot's bytes (max_size of them), and commit publishes its first len as above. The
 * loan stays valid until the next commit or publish, which takes up a loan not committed. */
void *marie_shm_pub_loan(marie_shm_pub_t *p);
int marie_shm_pub_commit(marie_shm_pub_t *p, size_t len);
const marie_shm_pub_stats_t *marie_shm_pub_stats(const marie_shm_pub_t *p);
const char *marie_shm_pub_segment(const marie_shm_pub_t *p);
/* For the same-host fast path, whose readers follow the ring without notices: a notice (a
 * beacon, for lcm-spy and other hosts) at most every notice_every_us, and after_ring(user) run
 * once each message is in the ring, before anything goes on LCM. */
void marie_shm_pub_pace(marie_shm_pub_t *p, int64_t notice_every_us, void (*after_ring)(void *), void *user);

/* A subscriber gets each message's bytes, read from the ring on this host; when the writer is
 * elsewhere (its notice names another host, or the segment is not here) it asks for the
 * messages on LCM and delivers those instead. The bytes are only valid during the call. */
typedef void (*marie_shm_msg_cb_t)(const void *data, size_t len, void *user);
typedef struct marie_shm_sub marie_shm_sub_t;

typedef struct {
    int64_t received;           /* delivered from shared memory */
    int64_t remote;             /* delivered from LCM (the writer on another host) */
    int64_t lost;               /* noticed, but overwritten before it was read (a slow reader) */
    int64_t bad;                /* malformed notices, or a size or type that does not match */
} marie_shm_sub_stats_t;

marie_shm_sub_t *marie_shm_sub_create(lcm_t *lcm, const char *channel, size_t max_size, marie_shm_msg_cb_t cb,
                                      void *user);
void marie_shm_sub_destroy(marie_shm_sub_t *s);         /* NULL is a no-op */
const marie_shm_sub_stats_t *marie_shm_sub_stats(const marie_shm_sub_t *s);
/* Without the copy: the callback gets the bytes inside the shared memory, where the writer may
 * overwrite them at any moment (a reader that slow). It should only decode them; right after
 * it `verdict(ok, user)` says whether they were intact throughout, and when not, whatever was
 * made of them must be dropped (counted as lost). Saves one copy of each message. */
typedef void (*marie_shm_verdict_cb_t)(bool ok, void *user);
void marie_shm_sub_in_place(marie_shm_sub_t *s, marie_shm_verdict_cb_t verdict);
/* And held: a message of MARIE_SHM_HOLD_MIN bytes or more goes to `held(data, len, user)`
 * instead of the callback when the reader could hold its slot (marie_shm_hold()): its bytes
 * stay as they are until the verdict returns, so what is made of them may point into them. */
void marie_shm_sub_held(marie_shm_sub_t *s, marie_shm_msg_cb_t held);
/* Only writers on other hosts: notices from this host are left alone (the fast path reads
 * those rings itself). */
void marie_shm_sub_remote_only(marie_shm_sub_t *s);

#ifdef __cplusplus
}
#endif
#endif
