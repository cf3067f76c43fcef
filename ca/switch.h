/* switch: forwards only the selected one of N inputs to one output; the selection is a
 * message and is persisted so it survives a restart. */
#ifndef MARIE_CA_SWITCH_H
#define MARIE_CA_SWITCH_H

#include <stddef.h>
#include <stdint.h>

#include "ca/ca.h"
#include "lcmtypes/marie_switch_select_t.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct ca_switch ca_switch_t;

typedef struct {
    int64_t forwarded, ignored;   /* payloads of the selected / of other inputs */
    int64_t bad_input;            /* wrong fingerprint */
    int64_t selections, refused, bad_requests;
} ca_switch_stats_t;
const ca_switch_stats_t *ca_switch_stats(const ca_switch_t *sw);

/* A Switch publishing on `output`, carrying `type` (NULL: any payload), persisting its
 * selection in `state_file` (NULL: not persisted). NULL with errno. */
ca_switch_t *ca_switch_create(const char *output, const marie_type_t *type, const char *state_file,
                              const ca_sink_t *sink);
void ca_switch_destroy(ca_switch_t *sw);        /* NULL is a no-op */

/* Inputs, in order; names are unique. 0, or -1 with errno EEXIST, EINVAL, ENOMEM. */
int ca_switch_add_input(ca_switch_t *sw, const char *name, const char *channel);
size_t ca_switch_ninputs(const ca_switch_t *sw);
const char *ca_switch_input_name(const ca_switch_t *sw, size_t i);
const char *ca_switch_input_channel(const ca_switch_t *sw, size_t i);

/* After the inputs are added: take the persisted selection if there is one and it names an
 * input, else `initial` (NULL or "": nothing selected). 1 when restored from the file. */
int ca_switch_restore(ca_switch_t *sw, const char *initial);

/* Select an input by name ("" selects none). Persisted before it takes effect.
 * 0, or -1 with errno ENOENT (unknown: refused, selection unchanged), EIO. */
int ca_switch_select(ca_switch_t *sw, const char *name);
const char *ca_switch_selected(const ca_switch_t *sw);     /* "" when none */

/* A payload arrived on input i: forwarded when i is selected. 1 forwarded, 0 not
 * selected, -1 with errno EBADMSG wrong fingerprint (counted), EINVAL bad index. */
int ca_switch_push(ca_switch_t *sw, size_t i, const void *raw, size_t len);

/* A switch_select_t request: applied, or refused with an event; either way the state
 * (switch_state_t) is published on the state channel. Undecodable: counted, -1 with errno EBADMSG. */
int ca_switch_handle_select(ca_switch_t *sw, const marie_switch_select_t *req, int64_t now);
int ca_switch_handle_select_raw(ca_switch_t *sw, const void *buf, size_t len, int64_t now);
/* Channels of selection requests and of the state (NULL: no state published). */
void ca_switch_set_state_channel(ca_switch_t *sw, const char *channel, const char *source);
int ca_switch_publish_state(ca_switch_t *sw, int64_t request_id, const char *requester,
                            int8_t status, int64_t now);

/* Subscribe to every input and to select_channel on `lcm`. 0, or -1 with errno. */
int ca_switch_attach(ca_switch_t *sw, lcm_t *lcm, const char *select_channel);
void ca_switch_detach(ca_switch_t *sw);

#ifdef __cplusplus
}
#endif
#endif
