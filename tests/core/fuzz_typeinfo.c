/* fuzz_typeinfo: whatever bytes pass marie_typeinfo_check must decode with lcm-gen's decoder
 * and encode back to the very same bytes (a round trip: the check accepts nothing the codec
 * would misread), for every marie type, and marie_decode_input takes exactly the finite ones
 * among them; marie_decode_view takes the same ones and gives the same message, its tail (when
 * the type has one) pointing into the bytes. The first byte picks the type. */
#include <errno.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "core/typeinfo.h"
#include "lcmtypes/marie_types.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    const marie_type_t *t = marie_types[data[0] % marie_types_count];
    const marie_typeinfo_t *ti = marie_typeinfo_by_fingerprint(t->hash());
    if (!ti)
        abort();  /* every registered type has a descriptor */
    /* Put the right fingerprint in front so the walk goes past it. */
    size_t len = size - 1 + 8;
    uint8_t *buf = malloc(len);
    uint64_t fp = (uint64_t)t->hash();
    for (int i = 0; i < 8; i++)
        buf[i] = (uint8_t)(fp >> (56 - 8 * i));
    memcpy(buf + 8, data + 1, size - 1);
    int ok = marie_typeinfo_check(ti, buf, len) == 0;
    if (ok) {
        void *msg = calloc(1, t->size);
        if (t->decode(buf, 0, (int)len, msg) < 0)
            abort();    /* checked, yet the decoder refuses it */
        int n = t->encoded_size(msg);
        uint8_t *again = malloc(len);
        if (n != (int)len || t->encode(again, 0, (int)len, msg) != n || memcmp(again, buf, len) != 0)
            abort();    /* checked bytes that do not survive decode + encode */
        free(again);
        t->decode_cleanup(msg);
        free(msg);
    }
    /* A component's decode takes a subset of what the walk takes: the finite ones. */
    void *in = calloc(1, t->size), *view = calloc(1, t->size);
    const char *why = NULL;
    int rc = marie_decode_input(t, buf, len, in, &why);
    bool nonfinite = rc < 0 && errno == EDOM;
    int viewed = marie_decode_view(t, buf, len, view, NULL);
    if ((viewed >= 0) != (rc == 0))
        abort();        /* the view takes exactly what the copy takes */
    if (viewed >= 0) {
        uint8_t *a = malloc(len), *b = malloc(len);
        if (t->encode(a, 0, (int)len, in) != (int)len || t->encode(b, 0, (int)len, view) != (int)len ||
            memcmp(a, b, len) != 0)
            abort();    /* the same message, whether its tail was copied or not */
        marie_tail_t tl;
        if (viewed == 1 && (marie_typeinfo_tail(ti, &tl) < 0 ||
                            *(uint8_t **)((uint8_t *)view + tl.ptr_off) != buf + tl.wire_off))
            abort();
        free(a);
        free(b);
        marie_decode_cleanup_view(t, view, viewed);
    }
    if (rc == 0)
        t->decode_cleanup(in);
    if ((rc == 0 && !ok) || (ok && rc != 0 && !nonfinite) || nonfinite != (why && !strcmp(why, "bad_nonfinite")))
        abort();
    free(view);
    free(in);
    free(buf);
    return 0;
}
