/* fuzz_am_order: arbitrary bytes as a manager order (decode, MAC check, replay table) and as
 * captured component output (line splitter); nothing may crash or leak. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/auth.h"
#include "core/typeinfo.h"
#include "managers/logcap.h"

static void count_line(const char *line, size_t len, void *user)
{
    size_t *n = user;
    *n += len + 1;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static marie_auth_t *auth;
    static marie_replay_t *replay;
    if (!auth) {
        uint8_t key[MARIE_AUTH_KEY_LEN];
        memset(key, 0x42, sizeof key);
        auth = marie_auth_from_key(key);
        replay = marie_replay_create(NULL);
    }
    marie_am_order_t o;
    /* liblcm's decoder trusts lengths from the wire: it only ever sees checked bytes. */
    if (marie_decode_checked(&marie_type_am_order_t, data, size, &o) == 0) {
        marie_auth_check_order(auth, replay, &o);
        marie_auth_check_order(NULL, replay, &o);
        marie_am_order_t_decode_cleanup(&o);
    }
    marie_linebuf_t lb = {0};
    size_t n = 0;
    marie_linebuf_feed(&lb, (const char *)data, size, count_line, &n);
    marie_linebuf_flush(&lb, count_line, &n);
    return 0;
}
