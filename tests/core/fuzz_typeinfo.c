/* fuzz_typeinfo: whatever bytes pass marie_typeinfo_check must decode with lcm-gen's decoder
 * and encode back to the very same bytes (a round trip: the check accepts nothing the codec
 * would misread), for every marie type, and marie_decode_input takes exactly the finite ones
 * among them. The first byte picks the type. */
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
    void *in = calloc(1, t->size);
    const char *why = NULL;
    int rc = marie_decode_input(t, buf, len, in, &why);
    bool nonfinite = rc < 0 && errno == EDOM;
    if (rc == 0)
        t->decode_cleanup(in);
    if ((rc == 0 && !ok) || (ok && rc != 0 && !nonfinite) || nonfinite != (why && !strcmp(why, "bad_nonfinite")))
        abort();
    free(in);
    free(buf);
    return 0;
}
