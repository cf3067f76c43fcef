/* switch: selection by name, persisted with an atomic rename; forwarding of the selected input. */
#include "ca/switch.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core/err.h"
#include "core/loop.h"
#include "core/time.h"
#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_switch_state_t.h"

typedef struct {
    char *name, *channel;
    marie_bus_sub_t *sub;
    struct ca_switch *sw;
} input_t;

struct ca_switch {
    char *output;
    const marie_type_t *type;
    char *state_file;
    char *state_channel, *source;
    ca_sink_t sink;
    input_t *inputs;
    size_t n;
    long selected;              /* index, -1 none */
    lcm_t *lcm;
    marie_bus_sub_t *sub_select;
    ca_switch_stats_t stats;
};

ca_switch_t *ca_switch_create(const char *output, const marie_type_t *type, const char *state_file,
                              const ca_sink_t *sink)
{
    if (!output || !*output)
        return marie_fail_null(EINVAL);
    ca_switch_t *sw = calloc(1, sizeof *sw);
    if (!sw)
        return NULL;
    sw->output = strdup(output);
    sw->state_file = state_file && *state_file ? strdup(state_file) : NULL;
    sw->source = strdup("");
    sw->type = type;
    sw->selected = -1;
    if (sink)
        sw->sink = *sink;
    if (!sw->output || !sw->source || (state_file && *state_file && !sw->state_file)) {
        ca_switch_destroy(sw);
        return marie_fail_null(ENOMEM);
    }
    return sw;
}

void ca_switch_destroy(ca_switch_t *sw)
{
    if (!sw)
        return;
    ca_switch_detach(sw);
    for (size_t i = 0; i < sw->n; i++) {
        free(sw->inputs[i].name);
        free(sw->inputs[i].channel);
    }
    free(sw->inputs);
    free(sw->output);
    free(sw->state_file);
    free(sw->state_channel);
    free(sw->source);
    free(sw);
}

static long find(const ca_switch_t *sw, const char *name)
{
    for (size_t i = 0; i < sw->n; i++)
        if (strcmp(sw->inputs[i].name, name) == 0)
            return (long)i;
    return -1;
}

int ca_switch_add_input(ca_switch_t *sw, const char *name, const char *channel)
{
    if (!name || !*name || !channel || !*channel)
        return marie_fail(EINVAL);
    if (find(sw, name) >= 0)
        return marie_fail(EEXIST);
    input_t *ni = realloc(sw->inputs, (sw->n + 1) * sizeof *ni);
    if (!ni)
        return marie_fail(ENOMEM);
    sw->inputs = ni;
    input_t *in = &sw->inputs[sw->n];
    *in = (input_t){ strdup(name), strdup(channel), NULL, sw };
    if (!in->name || !in->channel) {
        free(in->name);
        free(in->channel);
        return marie_fail(ENOMEM);
    }
    sw->n++;
    return 0;
}

size_t ca_switch_ninputs(const ca_switch_t *sw) { return sw->n; }
const char *ca_switch_input_name(const ca_switch_t *sw, size_t i) { return i < sw->n ? sw->inputs[i].name : NULL; }
const char *ca_switch_input_channel(const ca_switch_t *sw, size_t i) { return i < sw->n ? sw->inputs[i].channel : NULL; }
const char *ca_switch_selected(const ca_switch_t *sw) { return sw->selected >= 0 ? sw->inputs[sw->selected].name : ""; }
const ca_switch_stats_t *ca_switch_stats(const ca_switch_t *sw) { return &sw->stats; }

/* State file: one line "selected=NAME\n"; written atomically. */
static int persist(ca_switch_t *sw, const char *name)
{
    if (!sw->state_file)
        return 0;
    char buf[512];
    int n = snprintf(buf, sizeof buf, "selected=%s\n", name);
    if (n < 0 || n >= (int)sizeof buf)
        return marie_fail(ENAMETOOLONG);
    int rc = ca_write_file_atomic(sw->state_file, buf, (size_t)n);
    if (rc < 0)
        MARIE_KEEP_ERRNO(ca_note(&sw->sink, CA_NOTE_EVENT, "switch_io_error", MARIE_EVENT_T_SEV_ERROR,
                                 "%s: cannot save the selection: %s", sw->state_file, strerror(errno)));
    return rc;
}

int ca_switch_restore(ca_switch_t *sw, const char *initial)
{
    if (sw->state_file) {
        FILE *f = fopen(sw->state_file, "r");
        char line[512];
        if (f) {
            int got = fgets(line, sizeof line, f) != NULL;
            fclose(f);
            line[strcspn(line, "\n")] = 0;
            if (got && strncmp(line, "selected=", 9) == 0) {
                const char *name = line + 9;
                long i = find(sw, name);
                if (i >= 0 || !*name) {
                    sw->selected = i;
                    ca_note(&sw->sink, CA_NOTE_EVENT, "switch_restored", MARIE_EVENT_T_SEV_INFO,
                            "selection '%s' restored from %s", name, sw->state_file);
                    return 1;
                }
                ca_note(&sw->sink, CA_NOTE_EVENT, "switch_stale_selection", MARIE_EVENT_T_SEV_WARN,
                        "%s names input '%s', which is not configured; using '%s'",
                        sw->state_file, name, initial ? initial : "");
            }
        }
    }
    sw->selected = initial && *initial ? find(sw, initial) : -1;
    return 0;
}

int ca_switch_select(ca_switch_t *sw, const char *name)
{
    long i = name && *name ? find(sw, name) : -1;
    if (name && *name && i < 0)
        return marie_fail(ENOENT);
    if (i == sw->selected)
        return 0;
    int rc = persist(sw, name ? name : "");
    if (rc < 0)
        return marie_fail(EIO);
    sw->selected = i;
    return 0;
}

int ca_switch_push(ca_switch_t *sw, size_t i, const void *raw, size_t len)
{
    if (i >= sw->n)
        return marie_fail(EINVAL);
    if (ca_input_check(&sw->sink, sw->type, sw->inputs[i].channel, raw, len) < 0) {
        sw->stats.bad_input++;
        return marie_fail(EBADMSG);
    }
    if ((long)i != sw->selected) {
        sw->stats.ignored++;
        return 0;
    }
    if (ca_publish(&sw->sink, sw->output, raw, len) < 0) {
        ca_note(&sw->sink, CA_NOTE_DROP, "send_failed", 1, NULL);
        return marie_fail(EIO);
    }
    sw->stats.forwarded++;
    return 1;
}

void ca_switch_set_state_channel(ca_switch_t *sw, const char *channel, const char *source)
{
    free(sw->state_channel);
    sw->state_channel = channel && *channel ? strdup(channel) : NULL;
    char *s = strdup(source ? source : "");
    if (s) {
        free(sw->source);
        sw->source = s;
    }
}

int ca_switch_publish_state(ca_switch_t *sw, int64_t request_id, const char *requester,
                            int8_t status, int64_t now)
{
    if (!sw->state_channel)
        return 0;
    char **names = calloc(sw->n ? sw->n : 1, sizeof *names);
    if (!names)
        return marie_fail(ENOMEM);
    for (size_t i = 0; i < sw->n; i++)
        names[i] = sw->inputs[i].name;
    marie_switch_state_t st = {
        .utime = now, .source = sw->source, .request_id = request_id,
        .requester = (char *)(requester ? requester : ""), .status = status,
        .selected = (char *)ca_switch_selected(sw), .ninputs = (int32_t)sw->n, .inputs = names,
    };
    int need = marie_switch_state_t_encoded_size(&st);
    uint8_t *buf = need > 0 ? malloc((size_t)need) : NULL;
    int rc = marie_fail(ENOMEM);
    if (buf) {
        int n = marie_switch_state_t_encode(buf, 0, need, &st);
        rc = n < 0 ? marie_fail(EINVAL) : ca_publish(&sw->sink, sw->state_channel, buf, (size_t)n);
    }
    MARIE_KEEP_ERRNO(free(buf); free(names));
    return rc;
}

int ca_switch_handle_select(ca_switch_t *sw, const marie_switch_select_t *req, int64_t now)
{
    const char *name = req->input ? req->input : "";
    const char *who = req->requester ? req->requester : "";
    int rc = ca_switch_select(sw, name);
    int err = rc < 0 ? errno : 0;
    int8_t status = MARIE_SWITCH_STATE_T_STATUS_OK;
    if (err == ENOENT) {
        status = MARIE_SWITCH_STATE_T_STATUS_UNKNOWN_INPUT;
        sw->stats.refused++;
        ca_note(&sw->sink, CA_NOTE_EVENT, "switch_unknown_input", MARIE_EVENT_T_SEV_WARN,
                "selection of unknown input '%.128s' by '%.64s' refused; '%s' stays selected",
                name, who, ca_switch_selected(sw));
    } else if (rc < 0) {
        status = MARIE_SWITCH_STATE_T_STATUS_IO_ERROR;
        sw->stats.refused++;
    } else {
        sw->stats.selections++;
        ca_note(&sw->sink, CA_NOTE_EVENT, "switch_selected", MARIE_EVENT_T_SEV_INFO,
                "'%s' selected by '%.64s'", ca_switch_selected(sw), who);
    }
    ca_switch_publish_state(sw, req->request_id, who, status, now);
    return err ? marie_fail(err) : 0;
}

int ca_switch_handle_select_raw(ca_switch_t *sw, const void *buf, size_t len, int64_t now)
{
    marie_switch_select_t req;
    if (marie_decode_checked(&marie_type_switch_select_t, buf, len, &req) < 0) {
        sw->stats.bad_requests++;
        return ca_bad_request(&sw->sink, NULL, "selection request", buf, len);
    }
    int rc = ca_switch_handle_select(sw, &req, now);
    MARIE_KEEP_ERRNO(marie_switch_select_t_decode_cleanup(&req));
    return rc;
}

static void on_input(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    input_t *in = user;
    ca_switch_push(in->sw, (size_t)(in - in->sw->inputs), rbuf->data, rbuf->data_size);
}

static void on_select(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    ca_switch_handle_select_raw(user, rbuf->data, rbuf->data_size, marie_wall_us());
}

static marie_bus_sub_t *subscribe(lcm_t *lcm, const char *channel, lcm_msg_handler_t h, void *user)
{
    char *pat = ca_channel_pattern(channel);
    marie_bus_sub_t *s = pat ? marie_bus_subscribe(lcm, pat, h, user) : NULL;
    free(pat);
    return s;
}

int ca_switch_attach(ca_switch_t *sw, lcm_t *lcm, const char *select_channel)
{
    if (sw->lcm)
        return marie_fail(EALREADY);
    sw->lcm = lcm;
    sw->sink.lcm = lcm;
    for (size_t i = 0; i < sw->n; i++)
        if (!(sw->inputs[i].sub = subscribe(lcm, sw->inputs[i].channel, on_input, &sw->inputs[i])))
            goto err;
    if (select_channel && !(sw->sub_select = subscribe(lcm, select_channel, on_select, sw)))
        goto err;
    return 0;
err:
    ca_switch_detach(sw);
    return marie_fail(EIO);
}

void ca_switch_detach(ca_switch_t *sw)
{
    if (!sw->lcm)
        return;
    for (size_t i = 0; i < sw->n; i++) {
        if (sw->inputs[i].sub)
            marie_bus_unsubscribe(sw->lcm, sw->inputs[i].sub);
        sw->inputs[i].sub = NULL;
    }
    if (sw->sub_select)
        marie_bus_unsubscribe(sw->lcm, sw->sub_select);
    sw->sub_select = NULL;
    sw->lcm = NULL;
}
