/* fuzz_viewer_cmd: the page's commands arrive over a socket: any bytes must parse or be
 * refused, never crash; string values stay NUL-terminated. The same bytes, as the payload of
 * a marie type picked by the first byte, must be written as JSON or refused untouched. */
#include <assert.h>
#include <stdint.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "tools/webcommon/vjson.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    vj_cmd_t cmd;
    if (vj_cmd_parse(&cmd, (const char *)data, size) == 0) {
        assert(cmd.n >= 0 && cmd.n <= VJ_CMD_MAX);
        for (int i = 0; i < cmd.n; i++)
            assert(strlen(cmd.key[i]) < sizeof cmd.key[i] && strlen(cmd.str[i]) < sizeof cmd.str[i]);
        double x;
        (void)vj_cmd_str(&cmd, "op");
        (void)vj_cmd_num(&cmd, "t", &x);
    }
    /* and the string escaper on the same bytes */
    char s[256];
    size_t n = size < sizeof s - 1 ? size : sizeof s - 1;
    memcpy(s, data, n);
    s[n] = 0;
    marie_buf_t b;
    marie_buf_init(&b, 0);
    vj_str(&b, s);
    assert(b.failed || (b.len >= 2 && b.data[0] == '"' && b.data[b.len - 1] == '"'));
    marie_buf_free(&b);

    if (size < 1)
        return 0;
    const marie_typeinfo_t *t = marie_typeinfos[data[0] % marie_typeinfos_count];
    uint8_t *payload = malloc(size + 7);
    assert(payload);
    for (int i = 0; i < 8; i++)
        payload[i] = (uint8_t)((uint64_t)t->fingerprint >> (56 - 8 * i));
    memcpy(payload + 8, data + 1, size - 1);
    marie_buf_init(&b, 0);
    marie_buf_puts(&b, "{");
    int rc = vj_message(&b, payload, size + 7, VJ_ROLE_POSE);
    int err = errno;
    marie_buf_puts(&b, "}");
    if (rc == 0)
        assert(b.failed || (strncmp(b.data, "{,\"k\":", 6) == 0 && strstr(b.data, ",\"msg\":{")));
    else
        assert(rc == -1 && err == EBADMSG && strcmp(b.data, "{}") == 0);
    marie_buf_free(&b);
    free(payload);
    return 0;
}
