/* fuzz_ca_requests: the CA request decoders (pull requests, SharedMap requests, Switch
 * selections) and payload checks on arbitrary bytes. The first byte picks the decoder. */
#include <stddef.h>
#include <stdint.h>

#include "ca/mailbox.h"
#include "ca/sharedmap.h"
#include "ca/splitter.h"
#include "ca/switch.h"
#include "lcmtypes/marie_pose2d_t.h"

static int discard(void *user, const char *channel, const void *buf, size_t len) { return 0; }

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static mailbox_t *mb;
    static sharedmap_t *sm;
    static ca_switch_t *sw;
    static splitter_t *sp;
    static int64_t now;
    if (!mb) {
        ca_sink_t sink = { .publish = discard };
        mb = mailbox_create("POSE", &marie_type_pose2d_t, 4, &sink);
        sm = sharedmap_open(NULL, &sink);
        sharedmap_set_snapshot(sm, "SNAP", "fuzz", 0);
        sw = ca_switch_create("OUT", NULL, NULL, &sink);
        ca_switch_add_input(sw, "a", "A");
        ca_switch_add_input(sw, "b", "B");
        ca_switch_set_state_channel(sw, "OUT.STATE", "fuzz");
        sp = splitter_create("IN", &marie_type_pose2d_t, &sink);
        splitter_add_output(sp, "O1", 0);
        splitter_add_output(sp, "O2", 5);
    }
    if (size < 1)
        return 0;
    now += 1000;
    const uint8_t *p = data + 1;
    size_t n = size - 1;
    switch (data[0] % 5) {
    case 0: mailbox_handle_request_raw(mb, p, n, now); mailbox_tick(mb, now); break;
    case 1: mailbox_push(mb, p, n, now); break;
    case 2: sharedmap_handle_request_raw(sm, p, n, now); break;
    case 3: ca_switch_handle_select_raw(sw, p, n, now); ca_switch_push(sw, 0, p, n); break;
    case 4: splitter_push(sp, p, n, now); break;
    }
    /* keep the map small so a long run stays fast */
    if (sharedmap_size(sm) > 1000) {
        sharedmap_close(sm);
        ca_sink_t sink = { .publish = discard };
        sm = sharedmap_open(NULL, &sink);
    }
    return 0;
}
