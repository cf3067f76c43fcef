/* fuzz_webproto: the web pages' requests and frames arrive from a socket: any bytes must parse
 * or be refused with an HTTP status, never crash or read past them; what parses is consistent. */
#include <assert.h>
#include <stdint.h>
#include <string.h>

#include "tools/webcommon/webproto.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    webreq_t r;
    int status = 0;
    const char *why = NULL;
    int n = webreq_parse(&r, (const char *)data, size, &status, &why);
    if (n < 0)
        assert(status >= 400 && status < 600 && why);
    else if (n > 0)
        assert((size_t)n <= size && n <= WEBREQ_HEAD_MAX && r.path[0] == '/' && strlen(r.path) < sizeof r.path);
    char accept[29];
    if (r.key[0] && webws_accept(r.key, accept) == 0)
        assert(strlen(accept) == 28);

    /* the same bytes as a page's frames, one after another */
    for (size_t at = 0; at < size;) {
        webws_frame_t f;
        int hl = webws_parse(&f, data + at, size - at, &why);
        if (hl <= 0)
            break;
        assert(hl >= 2 && hl <= 14 && (size_t)hl <= size - at);
        assert(!(f.op & 8) || (f.fin && f.len <= 125));
        if (f.len > size - at - (size_t)hl)
            break;
        at += (size_t)hl + (size_t)f.len;
    }
    return 0;
}
