/* splitter: fan-out with a per-output rate limit on a fixed time grid. */
#include "ca/splitter.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "core/bus/bus.h"
#include "core/err.h"
#include "core/loop.h"
#include "core/time.h"

typedef struct {
    char *channel;
    int64_t period_us;          /* 0: unlimited */
    int64_t next_due;           /* earliest time the next message may go */
    int started;
    int64_t forwarded, limited;
} output_t;

struct splitter {
    char *input;
    const marie_type_t *type;
    ca_sink_t sink;
    output_t *outputs;
    size_t n;
    lcm_t *lcm;
    ca_input_t in;
    splitter_stats_t stats;
};

splitter_t *splitter_create(const char *input, const marie_type_t *type, const ca_sink_t *sink)
{
    if (!input || !*input)
        return marie_fail_null(EINVAL);
    splitter_t *sp = calloc(1, sizeof *sp);
    if (!sp)
        return NULL;
    sp->input = strdup(input);
    if (!sp->input) {
        free(sp);
        return marie_fail_null(ENOMEM);
    }
    sp->type = type;
    if (sink)
        sp->sink = *sink;
    return sp;
}

void splitter_destroy(splitter_t *sp)
{
    if (!sp)
        return;
    splitter_detach(sp);
    for (size_t i = 0; i < sp->n; i++)
        free(sp->outputs[i].channel);
    free(sp->outputs);
    free(sp->input);
    free(sp);
}

int splitter_add_output(splitter_t *sp, const char *channel, double max_hz)
{
    if (!channel || !*channel || strcmp(channel, sp->input) == 0 || !(max_hz >= 0) || max_hz > 1e6)
        return marie_fail(EINVAL);
    output_t *no = realloc(sp->outputs, (sp->n + 1) * sizeof *no);
    if (!no)
        return marie_fail(ENOMEM);
    sp->outputs = no;
    output_t *o = &sp->outputs[sp->n];
    memset(o, 0, sizeof *o);
    o->channel = strdup(channel);
    if (!o->channel)
        return marie_fail(ENOMEM);
    o->period_us = max_hz > 0 ? (int64_t)(1e6 / max_hz + 0.5) : 0;
    return (int)sp->n++;
}

size_t splitter_noutputs(const splitter_t *sp) { return sp->n; }
int64_t splitter_output_forwarded(const splitter_t *sp, size_t i) { return i < sp->n ? sp->outputs[i].forwarded : 0; }
int64_t splitter_output_limited(const splitter_t *sp, size_t i) { return i < sp->n ? sp->outputs[i].limited : 0; }
const splitter_stats_t *splitter_stats(const splitter_t *sp) { return &sp->stats; }

/* Whether output o may send at now; advances its grid when it does. */
static int rate_pass(output_t *o, int64_t now)
{
    if (o->period_us == 0)
        return 1;
    if (o->started && now < o->next_due)
        return 0;
    /* On schedule (less than a period late): keep the grid so the mean rate is exact;
     * after a gap, restart the grid at now rather than bursting to catch up. */
    if (o->started && now - o->next_due < o->period_us)
        o->next_due += o->period_us;
    else
        o->next_due = now + o->period_us;
    o->started = 1;
    return 1;
}

int splitter_push(splitter_t *sp, const void *raw, size_t len, int64_t now_us)
{
    if (ca_input_check(&sp->sink, sp->type, sp->input, raw, len) < 0) {
        sp->stats.bad_input++;
        return marie_fail(EBADMSG);
    }
    sp->stats.received++;
    int sent = 0;
    for (size_t i = 0; i < sp->n; i++) {
        output_t *o = &sp->outputs[i];
        if (!rate_pass(o, now_us)) {
            o->limited++;
            continue;
        }
        if (ca_publish(&sp->sink, o->channel, raw, len) < 0) {
            ca_note(&sp->sink, CA_NOTE_DROP, "send_failed", 1, NULL);
            continue;
        }
        o->forwarded++;
        sent++;
    }
    return sent;
}

static void on_input(void *user, const void *buf, size_t len, int64_t recv_utime)
{
    splitter_push(user, buf, len, marie_mono_us());
}

int splitter_attach(splitter_t *sp, lcm_t *lcm)
{
    if (sp->lcm)
        return marie_fail(EALREADY);
    /* An output on a ring has it from the start, so a reader off the ring (another host, a
     * Python port) that asked before the first message gets that message too. */
    for (size_t i = 0; i < sp->n; i++)
        if (marie_bus_prepare(lcm, sp->outputs[i].channel) < 0)
            return -1;
    int rc = ca_input_open(&sp->in, lcm, sp->input, on_input, sp);
    if (rc < 0)
        return rc;
    sp->lcm = lcm;
    sp->sink.lcm = lcm;
    return 0;
}

marie_bus_sub_stats_t splitter_input_stats(const splitter_t *sp)
{
    return ca_input_stats(&sp->in);
}

void splitter_detach(splitter_t *sp)
{
    if (!sp->lcm)
        return;
    ca_input_close(&sp->in);
    sp->lcm = NULL;
}
