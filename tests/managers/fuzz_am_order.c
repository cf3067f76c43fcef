/* fuzz_am_order: arbitrary bytes as a manager order (decode, MAC check, replay table) and as
 * captured component output (line splitter); nothing may crash or leak, an order is never
 * accepted twice nor without a key, and the splitter hands on every byte it was given. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/auth.h"
#include "core/typeinfo.h"
#include "managers/logcap.h"

static void count_line(const char *line, size_t len, void *user)
{
    size_t *n = user;
    if (len > MARIE_LINE_MAX || memchr(line, '\n', len))
        abort();    /* a line longer than promised, or not split at a newline */
    *n += len;
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
        if (marie_auth_check_order(auth, replay, &o) == MARIE_AUTH_OK &&
            marie_auth_check_order(auth, replay, &o) == MARIE_AUTH_OK)
            abort();    /* a replayed order accepted */
        if (marie_auth_check_order(NULL, replay, &o) == MARIE_AUTH_OK)
            abort();    /* accepted with no key */
        marie_am_order_t_decode_cleanup(&o);
    }
    marie_linebuf_t lb = {0};
    size_t n = 0;
    marie_linebuf_feed(&lb, (const char *)data, size, count_line, &n);
    marie_linebuf_flush(&lb, count_line, &n);
    /* nothing is lost but the newlines and the carriage returns before them */
    size_t nl = 0, cr = 0;
    for (size_t i = 0; i < size; i++) {
        nl += data[i] == '\n';
        cr += data[i] == '\r';
    }
    if (n > size - nl || n + cr < size - nl)
        abort();
    return 0;
}
