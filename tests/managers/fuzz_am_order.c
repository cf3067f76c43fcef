/* fuzz_am_order: arbitrary bytes as a manager order (decode, MAC check, replay table) and as
 * captured component output (line splitter); nothing may crash or leak. */
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/auth.h"
#include "managers/lcmcheck.h"
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
    /* liblcm's decoder trusts lengths from the wire: the managers check the layout first.
     * An empty MAC (the last field, so the last four bytes are zero) makes liblcm's inline
     * decoder memcpy() zero bytes to NULL, which UBSan reports inside liblcm; unsigned
     * orders are exercised end to end by test_am.sh instead. */
    bool empty_mac = size >= 4 && memcmp(data + size - 4, "\0\0\0\0", 4) == 0;
    if (marie_lcm_check(data, size, MARIE_LAYOUT_AM_ORDER) == 0 && !empty_mac &&
        marie_am_order_t_decode(data, 0, (int)size, &o) >= 0) {
        marie_auth_check_order(auth, replay, &o);
        marie_auth_check_order(NULL, replay, &o);
        marie_am_order_t_decode_cleanup(&o);
    }
    static const char *const layouts[] = {MARIE_LAYOUT_AM_REPLY, MARIE_LAYOUT_AM_STATUS, MARIE_LAYOUT_HEARTBEAT,
                                          MARIE_LAYOUT_LOG_LINE, MARIE_LAYOUT_EVENT};
    for (size_t i = 0; i < sizeof layouts / sizeof layouts[0]; i++)
        marie_lcm_check(data, size, layouts[i]);
    marie_linebuf_t lb = {0};
    size_t n = 0;
    marie_linebuf_feed(&lb, (const char *)data, size, count_line, &n);
    marie_linebuf_flush(&lb, count_line, &n);
    return 0;
}
