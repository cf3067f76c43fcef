/* splitter: forwards one input to several outputs, each optionally renamed and rate-limited. */
#ifndef MARIE_CA_SPLITTER_H
#define MARIE_CA_SPLITTER_H

#include <stddef.h>
#include <stdint.h>

#include "ca/ca.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct splitter splitter_t;

typedef struct {
    int64_t received, bad_input;
} splitter_stats_t;

/* A Splitter of `input` carrying `type` (NULL: any payload). NULL with errno. */
splitter_t *splitter_create(const char *input, const marie_type_t *type, const ca_sink_t *sink);
void splitter_destroy(splitter_t *sp);          /* NULL is a no-op */

/* An output on `channel` (the input's own name is allowed only with another LCM instance,
 * so it is refused: -1 with errno EINVAL), at most max_hz messages per second (0: every message).
 * A limited output forwards the first message due on a fixed grid of 1/max_hz, so its rate
 * never exceeds max_hz and stays close to it under jitter. Returns the output's index. */
int splitter_add_output(splitter_t *sp, const char *channel, double max_hz);
size_t splitter_noutputs(const splitter_t *sp);
const char *splitter_output_channel(const splitter_t *sp, size_t i);
int64_t splitter_output_forwarded(const splitter_t *sp, size_t i);
int64_t splitter_output_limited(const splitter_t *sp, size_t i);   /* held back by the rate limit */

/* One input payload received at now_us (monotonic or wall, consistently). Returns the
 * number of outputs it went to, or -1 with errno EBADMSG for a wrong fingerprint (counted). */
int splitter_push(splitter_t *sp, const void *raw, size_t len, int64_t now_us);

const splitter_stats_t *splitter_stats(const splitter_t *sp);
const char *splitter_input(const splitter_t *sp);

/* Subscribe to the input on `lcm` (outputs go out on it unless the sink has a publish
 * function), through the bus's transports (ca_input_open). 0, or -1 with errno. */
int splitter_attach(splitter_t *sp, lcm_t *lcm);
void splitter_detach(splitter_t *sp);
/* Its input's counts since attached (ca_input_stats: zero on LCM). */
marie_bus_sub_stats_t splitter_input_stats(const splitter_t *sp);

#ifdef __cplusplus
}
#endif
#endif
