/* marie-ca: runs one Communication Adapter (mailbox, splitter, sharedmap, switch) as a component. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ca/ca.h"
#include "ca/mailbox.h"
#include "ca/sharedmap.h"
#include "ca/splitter.h"
#include "ca/switch.h"
#include "core/clear.h"
#include "core/file.h"
#include "core/component.h"
#include "ca/ca_params.h"
#include "core/version.h"

#define MAX_MAILBOXES 64

static const ca_params_t *params_of(const marie_component_t *c) { return marie_component_params(c); }

typedef struct {
    marie_component_t *c;
    const marie_type_t *type;
    mailbox_t *mb[MAX_MAILBOXES];
    size_t nmb;
    splitter_t *sp;
    sharedmap_t *sm;
    char *sm_channel;
    ca_switch_t *sw;
    char *sw_select;
    marie_timer_t *tick;
    int attached;
    /* last values pushed into the heartbeat counters */
    int64_t shown[8];
} ca_proc_t;

/* ---- reporting: CA notes become heartbeat counters and events ---- */

static void note(void *user, ca_note_kind_t kind, const char *counter, int64_t n, const char *text)
{
    ca_proc_t *p = user;
    switch (kind) {
    case CA_NOTE_BAD_INPUT:
        marie_component_bad_input(p->c, counter, "%s", text ? text : counter);
        break;
    case CA_NOTE_DROP:
        marie_component_drop(p->c, n);
        marie_component_count(p->c, counter, n);
        break;
    case CA_NOTE_COUNT:
        marie_component_count(p->c, counter, n);
        break;
    case CA_NOTE_EVENT:
        marie_component_event(p->c, (int)n, counter, "%s", text ? text : counter);
        break;
    }
}

static ca_sink_t sink_of(ca_proc_t *p)
{
    return (ca_sink_t){ .note = note, .user = p };
}

/* Counter `name` shown in the heartbeat follows `value`. */
static void show(ca_proc_t *p, int slot, const char *name, int64_t value)
{
    if (value != p->shown[slot])
        marie_component_count(p->c, name, value - p->shown[slot]);
    p->shown[slot] = value;
}

/* ---- parameters ---- */

static int param_type(ca_proc_t *p, const char *name, const marie_type_t **out)
{
    *out = NULL;
    if (!*name)
        return 0;
    if (!(*out = marie_type_find(name))) {
        marie_component_fail_reason(p->c, "type: unknown LCM type '%s'", name);
        return -1;
    }
    return 0;
}

static int fail_errs(ca_proc_t *p, marie_errors_t *errs)
{
    marie_component_fail_reason(p->c, "%s", errs->n ? errs->msgs[0] : "bad parameter");
    marie_errors_print(errs, stderr);
    marie_errors_clear(errs);
    return -1;
}

/* Where a CA keeps its state unless told: marie_state_dir()/NAME.SUFFIX, never the working
 * directory. NULL with the reason given as the component's failure. */
static char *state_path(ca_proc_t *p, const char *given, const char *suffix)
{
    if (given && *given)
        return strdup(given);
    char *dir = marie_state_dir(), *path = NULL;
    if (!dir) {
        marie_component_fail_reason(p->c, "state directory: %s (set MARIE_STATE_DIR or state_file)",
                                    errno == ENOENT ? "none known" : strerror(errno));
        return NULL;
    }
    if (asprintf(&path, "%s/%s.%s", dir, marie_component_name(p->c), suffix) < 0)
        path = NULL;
    free(dir);
    return path;
}

static void proc_free(ca_proc_t *p)
{
    for (size_t i = 0; i < p->nmb; i++)
        mailbox_destroy(p->mb[i]);
    p->nmb = 0;
    MARIE_CLEAR(p->sp, splitter_destroy);
    MARIE_CLEAR(p->sm, sharedmap_close);
    MARIE_CLEAR(p->sw, ca_switch_destroy);
    free(p->sm_channel);
    free(p->sw_select);
    p->sm_channel = p->sw_select = NULL;
    p->attached = 0;
}

static void on_tick(marie_component_t *c, int64_t overruns);

static int common_init(marie_component_t *c, ca_proc_t **out, bool typed)
{
    ca_proc_t *p = marie_component_user(c);
    proc_free(p);
    p->c = c;
    if (typed && param_type(p, params_of(c)->type, &p->type) < 0)
        return -1;
    if (!p->tick && !(p->tick = marie_component_every(c, 100, on_tick))) {
        marie_component_fail_reason(c, "cannot create the timer: %s", strerror(errno));
        return -1;
    }
    *out = p;
    return 0;
}

/* ---- mailbox ---- */

static int add_mailbox(ca_proc_t *p, const char *channel, const marie_type_t *type, int64_t depth)
{
    if (p->nmb == MAX_MAILBOXES) {
        marie_component_fail_reason(p->c, "at most %d channels per process", MAX_MAILBOXES);
        return -1;
    }
    if (depth < 1 || depth > 100000) {
        marie_component_fail_reason(p->c, "%s: depth %lld out of range 1..100000", channel, (long long)depth);
        return -1;
    }
    for (size_t i = 0; i < p->nmb; i++)
        if (strcmp(mailbox_channel(p->mb[i]), channel) == 0) {
            marie_component_fail_reason(p->c, "channel %s listed twice", channel);
            return -1;
        }
    ca_sink_t s = sink_of(p);
    if (!(p->mb[p->nmb] = mailbox_create(channel, type, (int)depth, &s))) {
        marie_component_fail_reason(p->c, "%s: %s", channel, strerror(errno));
        return -1;
    }
    p->nmb++;
    return 0;
}

static int mailbox_init(marie_component_t *c)
{
    ca_proc_t *p;
    if (common_init(c, &p, true) < 0)
        return -1;
    int64_t depth = params_of(c)->depth;
    const char *channel = params_of(c)->channel;
    if (*channel && add_mailbox(p, channel, p->type, depth) < 0)
        return -1;
    const marie_node_t *list = params_of(c)->channels;
    marie_errors_t errs = {0};
    for (size_t i = 0; list && list->kind == MARIE_NODE_SEQ && i < list->n; i++) {
        const marie_node_t *it = list->items[i];
        const char *ch = NULL, *tn = NULL;
        const marie_type_t *t = p->type;
        int64_t d = depth;
        if (it->kind == MARIE_NODE_SCALAR) {
            if (marie_node_str(it, &ch, &errs) < 0)
                return fail_errs(p, &errs);
        } else if (it->kind == MARIE_NODE_MAP) {
            static const char *const keys[] = { "channel", "type", "depth", NULL };
            if (marie_node_check_keys(it, keys, "mailbox channel", &errs) < 0 ||
                marie_node_str(marie_node_get(it, "channel"), &ch, &errs) < 0 ||
                (marie_node_get(it, "type") && marie_node_str(marie_node_get(it, "type"), &tn, &errs) < 0) ||
                (marie_node_get(it, "depth") && marie_node_int(marie_node_get(it, "depth"), &d, &errs) < 0))
                return fail_errs(p, &errs);
            if (tn && param_type(p, tn, &t) < 0)
                return -1;
        } else {
            marie_errors_add(&errs, it->file, it->line, it->col, "channels: expected a channel name or a map");
            return fail_errs(p, &errs);
        }
        if (!ch || !*ch) {
            marie_errors_add(&errs, it->file, it->line, it->col, "channels: missing channel");
            return fail_errs(p, &errs);
        }
        if (add_mailbox(p, ch, t, d) < 0)
            return -1;
    }
    if (list && list->kind != MARIE_NODE_SEQ) {
        marie_errors_add(&errs, list->file, list->line, list->col, "channels: expected a list");
        return fail_errs(p, &errs);
    }
    if (p->nmb == 0) {
        marie_component_fail_reason(c, "mailbox: set 'channel' or 'channels'");
        return -1;
    }
    return 0;
}

/* ---- splitter ---- */

static int splitter_init(marie_component_t *c)
{
    ca_proc_t *p;
    if (common_init(c, &p, true) < 0)
        return -1;
    ca_sink_t s = sink_of(p);
    const char *input = params_of(c)->input;
    if (!(p->sp = splitter_create(input, p->type, &s))) {
        marie_component_fail_reason(c, "input: %s", *input ? strerror(errno) : "missing");
        return -1;
    }
    const marie_node_t *list = params_of(c)->outputs;
    marie_errors_t errs = {0};
    if (!list || list->kind != MARIE_NODE_SEQ || list->n == 0) {
        marie_component_fail_reason(c, "outputs: expected a list of channels");
        return -1;
    }
    for (size_t i = 0; i < list->n; i++) {
        const marie_node_t *it = list->items[i];
        const char *ch = NULL;
        double hz = 0;
        if (it->kind == MARIE_NODE_SCALAR) {
            if (marie_node_str(it, &ch, &errs) < 0)
                return fail_errs(p, &errs);
        } else if (it->kind == MARIE_NODE_MAP) {
            static const char *const keys[] = { "channel", "max_hz", NULL };
            if (marie_node_check_keys(it, keys, "splitter output", &errs) < 0 ||
                marie_node_str(marie_node_get(it, "channel"), &ch, &errs) < 0 ||
                (marie_node_get(it, "max_hz") && marie_node_double(marie_node_get(it, "max_hz"), &hz, &errs) < 0))
                return fail_errs(p, &errs);
        }
        if (!ch || splitter_add_output(p->sp, ch, hz) < 0) {
            marie_errors_add(&errs, it->file, it->line, it->col,
                             "outputs: need a channel other than the input and max_hz >= 0");
            return fail_errs(p, &errs);
        }
    }
    return 0;
}

/* ---- sharedmap ---- */

static int sharedmap_init(marie_component_t *c)
{
    ca_proc_t *p;
    if (common_init(c, &p, false) < 0)
        return -1;
    if (!*params_of(c)->channel) {
        marie_component_fail_reason(c, "channel: must not be empty");
        return -1;
    }
    char *path = state_path(p, params_of(c)->state_file, "sharedmap");
    if (!path)
        return -1;
    ca_sink_t s = sink_of(p);
    p->sm = sharedmap_open_flags(path, params_of(c)->strict_log ? SHAREDMAP_STRICT : 0, &s);
    if (!p->sm) {
        marie_component_fail_reason(c, "state_file %s: %s", path,
                                    errno == EINVAL ? "not a SharedMap log"
                                    : errno == EBUSY ? "in use by another SharedMap"
                                    : errno == EBADMSG ? "damaged, left as it is (strict_log)" : strerror(errno));
        free(path);
        return -1;
    }
    const sharedmap_stats_t *st = sharedmap_stats(p->sm);
    marie_component_event(c, 1, "sharedmap_loaded", "%s: %zu keys, version %lld, %lld records%s%s",
                          path, sharedmap_size(p->sm), (long long)sharedmap_version(p->sm),
                          (long long)st->records_loaded,
                          st->tail_bytes_dropped ? " (torn unacknowledged tail cut off)" : "",
                          st->records_skipped || sharedmap_kept_aside(p->sm) ? " (damaged log recovered)" : "");
    free(path);
    sharedmap_set_compaction(p->sm, params_of(c)->compact_min_records);
    p->sm_channel = strdup(params_of(c)->channel);
    const char *snap = params_of(c)->snapshot_channel;
    char def[512];
    snprintf(def, sizeof def, "%s.SNAPSHOT", p->sm_channel ? p->sm_channel : "");
    sharedmap_set_snapshot(p->sm, strcmp(snap, "none") == 0 ? NULL : *snap ? snap : def,
                           marie_component_name(c), params_of(c)->snapshot_min_interval_ms * 1000);
    return p->sm_channel ? 0 : -1;
}

/* ---- switch ---- */

static int switch_init(marie_component_t *c)
{
    ca_proc_t *p;
    if (common_init(c, &p, true) < 0)
        return -1;
    const char *output = params_of(c)->output;
    char *path = state_path(p, params_of(c)->state_file, "switch");
    if (!path)
        return -1;
    ca_sink_t s = sink_of(p);
    p->sw = ca_switch_create(output, p->type, path, &s);
    free(path);
    if (!p->sw) {
        marie_component_fail_reason(c, "output: %s", *output ? strerror(errno) : "missing");
        return -1;
    }
    const marie_node_t *in = params_of(c)->inputs;
    marie_errors_t errs = {0};
    if (!in || in->kind != MARIE_NODE_MAP || in->n == 0) {
        marie_component_fail_reason(c, "inputs: expected a map of input names to channels");
        return -1;
    }
    for (size_t i = 0; i < in->n; i++) {
        const char *ch;
        if (marie_node_str(in->items[i], &ch, &errs) < 0)
            return fail_errs(p, &errs);
        if (ca_switch_add_input(p->sw, in->items[i]->key, ch) < 0 || strcmp(ch, output) == 0) {
            marie_errors_add(&errs, in->items[i]->file, in->items[i]->line, in->items[i]->col,
                             "inputs: '%s' must be a unique name with a channel other than the output",
                             in->items[i]->key);
            return fail_errs(p, &errs);
        }
    }
    const char *initial = params_of(c)->initial;
    if (*initial && strcmp(initial, "none") != 0) {
        int known = 0;
        for (size_t i = 0; i < ca_switch_ninputs(p->sw); i++)
            known |= strcmp(ca_switch_input_name(p->sw, i), initial) == 0;
        if (!known) {
            marie_component_fail_reason(c, "initial: '%s' is not one of the inputs", initial);
            return -1;
        }
    }
    ca_switch_restore(p->sw, *initial ? initial : ca_switch_input_name(p->sw, 0));
    char buf[512];
    const char *sel = params_of(c)->select_channel;
    snprintf(buf, sizeof buf, "%s.SELECT", output);
    p->sw_select = strdup(*sel ? sel : buf);
    const char *st = params_of(c)->state_channel;
    snprintf(buf, sizeof buf, "%s.STATE", output);
    ca_switch_set_state_channel(p->sw, *st ? st : buf, marie_component_name(c));
    return p->sw_select ? 0 : -1;
}

/* ---- lifecycle shared by all kinds ---- */

static int attach(marie_component_t *c)
{
    ca_proc_t *p = marie_component_user(c);
    lcm_t *lcm = marie_component_lcm(c);
    int rc = 0;
    if (p->attached)
        return 0;
    for (size_t i = 0; i < p->nmb && rc == 0; i++)
        rc = mailbox_attach(p->mb[i], lcm);
    if (p->sp && rc == 0)
        rc = splitter_attach(p->sp, lcm);
    if (p->sm && rc == 0) {
        rc = sharedmap_attach(p->sm, lcm, p->sm_channel);
        if (rc == 0)
            sharedmap_publish_snapshot(p->sm, marie_wall_us());
    }
    if (p->sw && rc == 0) {
        rc = ca_switch_attach(p->sw, lcm, p->sw_select);
        if (rc == 0)
            ca_switch_publish_state(p->sw, 0, "", 0, marie_wall_us());
    }
    if (rc < 0) {
        marie_component_fail_reason(c, "cannot subscribe: %s", strerror(errno));
        return -1;
    }
    p->attached = 1;
    return 0;
}

static void detach_all(marie_component_t *c)
{
    ca_proc_t *p = marie_component_user(c);
    for (size_t i = 0; i < p->nmb; i++)
        mailbox_detach(p->mb[i]);
    if (p->sp)
        splitter_detach(p->sp);
    if (p->sm)
        sharedmap_detach(p->sm);
    if (p->sw)
        ca_switch_detach(p->sw);
    p->attached = 0;
}

static int detach(marie_component_t *c)
{
    detach_all(c);
    return 0;
}

static void on_abort(marie_component_t *c) { detach_all(c); }

static void on_quit(marie_component_t *c)
{
    proc_free(marie_component_user(c));
}

/* Shared-memory inputs, named as ports name them: messages overwritten before they were read
 * (drops) and malformed notices (bad input). */
static void count_shm_losses(ca_proc_t *p)
{
    marie_bus_sub_stats_t st[MAX_MAILBOXES + 1] = { 0 };
    for (size_t i = 0; i < p->nmb; i++)
        st[i] = mailbox_input_stats(p->mb[i]);
    if (p->sp)
        st[p->nmb] = splitter_input_stats(p->sp);
    int64_t lost = 0, bad = 0;
    for (size_t i = 0; i <= p->nmb; i++) {
        lost += st[i].lost;
        bad += st[i].bad;
    }
    if (lost > p->shown[4])
        marie_component_drop(p->c, lost - p->shown[4]);
    show(p, 4, "shm_overwritten", lost);
    if (bad > p->shown[5])
        marie_component_bad_input(p->c, "bad_shm_notice", "%lld malformed or mismatched notices on shared-memory inputs",
                                  (long long)(bad - p->shown[5]));
    p->shown[5] = bad;
}

static void on_tick(marie_component_t *c, int64_t overruns)
{
    ca_proc_t *p = marie_component_user(c);
    int64_t now = marie_wall_us();
    int64_t in = 0, replies = 0, fwd = 0;
    for (size_t i = 0; i < p->nmb; i++) {
        mailbox_tick(p->mb[i], now);
        in += mailbox_stats(p->mb[i])->received;
        replies += mailbox_stats(p->mb[i])->replies;
    }
    if (p->sm) {
        sharedmap_tick(p->sm, now);
        replies += sharedmap_stats(p->sm)->requests;
        show(p, 3, "compactions", sharedmap_stats(p->sm)->compactions);
    }
    if (p->sp) {
        in += splitter_stats(p->sp)->received;
        for (size_t i = 0; i < splitter_noutputs(p->sp); i++)
            fwd += splitter_output_forwarded(p->sp, i);
    }
    if (p->sw)
        fwd += ca_switch_stats(p->sw)->forwarded;
    count_shm_losses(p);
    show(p, 0, "received", in);
    show(p, 1, p->sm ? "requests" : "replies", replies);
    show(p, 2, "forwarded", fwd);
}

/* ---- definitions ---- */

static const marie_port_spec_t no_ports[] = { { 0 } };

static const marie_param_spec_t mailbox_params[] = CA_MAILBOX_PARAMS;
static const marie_param_spec_t splitter_params[] = CA_SPLITTER_PARAMS;
static const marie_param_spec_t sharedmap_params[] = CA_SHAREDMAP_PARAMS;
static const marie_param_spec_t switch_params[] = CA_SWITCH_PARAMS;

#define CA_DEF(KIND, PARAMS, INIT) { \
    .kind = KIND, .ports = no_ports, .params = PARAMS, .params_size = sizeof(ca_params_t), .on_init = INIT, \
    .on_start = attach, .on_stop = detach, .on_pause = detach, .on_resume = attach, .on_abort = on_abort, .on_quit = on_quit }

static const marie_component_def_t defs[] = {
    CA_DEF("mailbox", mailbox_params, mailbox_init),
    CA_DEF("splitter", splitter_params, splitter_init),
    CA_DEF("sharedmap", sharedmap_params, sharedmap_init),
    CA_DEF("switch", switch_params, switch_init),
};

int main(int argc, char **argv)
{
    marie_version_exit("marie-ca", argc, argv);
    const marie_component_def_t *def = NULL;
    for (size_t i = 0; argc > 1 && i < sizeof defs / sizeof defs[0]; i++)
        if (strcmp(argv[1], defs[i].kind) == 0)
            def = &defs[i];
    bool help = argc == 2 && strcmp(argv[1], "--help") == 0;
    if (!def) {
        FILE *out = help ? stdout : stderr;
        fprintf(out, "usage: marie-ca mailbox|splitter|sharedmap|switch [component options]\n"
                     "       (marie-ca KIND --help lists one kind's options)\n");
        for (size_t i = 0; help && i < sizeof defs / sizeof defs[0]; i++) {
            char prog[64];
            snprintf(prog, sizeof prog, "marie-ca %s", defs[i].kind);
            fprintf(out, "\n");
            marie_component_usage(&defs[i], prog, out);
        }
        return help ? 0 : 2;
    }
    static ca_proc_t proc;
    argv[1] = argv[0];
    int rc = marie_main(def, argc - 1, argv + 1, &proc);
    proc_free(&proc);
    return rc;
}
