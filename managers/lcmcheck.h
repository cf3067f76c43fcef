/* lcmcheck: validates an encoded LCM message against a field layout before decoding it.
 * liblcm 1.3's generated decoders trust string lengths and array counts from the wire (a
 * negative length crashes them), so everything the managers receive is checked first. */
#ifndef MARIE_LCMCHECK_H
#define MARIE_LCMCHECK_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Layout after the 8-byte fingerprint: b int8/boolean, h int16, i int32, l int64, f float,
 * d double, s string; "[...]" after an i repeats the bracketed layout that many times.
 * Returns 0 when every length and count fits and the layout ends exactly at len, else
 * -EBADMSG. */
int marie_lcm_check(const void *buf, size_t len, const char *layout);

/* Layouts of the messages the managers receive. */
#define MARIE_LAYOUT_AM_ORDER  "lslsbi[s]sssi[b]"
#define MARIE_LAYOUT_AM_REPLY  "lsslbsii[s]"
#define MARIE_LAYOUT_AM_STATUS "lsillsssfffiflli[s]i[sssbiliifllsl]"
#define MARIE_LAYOUT_HEARTBEAT "lssilbslllllli[sl]"
#define MARIE_LAYOUT_LOG_LINE  "lssibllls"
#define MARIE_LAYOUT_EVENT     "lslbss"

#ifdef __cplusplus
}
#endif
#endif
