/* fuzz_ros2_cdr: what marie-ros2 does with a DDS sample from ROS 2, from the bytes on: Cyclone's
 * own check of the CDR (dds_stream_normalize_data, what its receive path runs), its decoder, then
 * the bridge's conversion. Whatever the bytes, nothing crashes, and a message the conversion
 * accepts passes marie's checked decode (finite, consistent) once encoded: bad input never reaches
 * the bus. The first byte picks one of the kinds the bridge reads from ROS 2 (its top bit: the
 * payload is big-endian); the rest is the CDR payload after its encapsulation header. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <dds/ddsi/ddsi_cdrstream.h>

#include "adapters/ros2/ros2_conv.h"
#include "core/typeinfo.h"

static void check_on_bus(const marie_type_t *t, const void *msg)
{
    int n = t->encoded_size(msg);
    uint8_t *buf = malloc(n > 0 ? (size_t)n : 1);
    void *back = calloc(1, t->size);
    const char *why;
    if (n < 0 || t->encode(buf, 0, n, msg) != n || marie_decode_input(t, buf, (size_t)n, back, &why) != 0)
        abort();    /* the bridge would have put bad input on the bus */
    t->decode_cleanup(back);
    free(back);
    free(buf);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    size_t nk, nfrom = 0;
    const ros2_kind_t *all = ros2_kinds(&nk), *from[32];
    for (size_t i = 0; i < nk; i++)
        if (!all[i].to_ros)
            from[nfrom++] = &all[i];
    if (size < 1 || size > (1u << 24))
        return 0;
    const ros2_kind_t *k = from[(data[0] & 0x7f) % nfrom];
    uint32_t len = (uint32_t)(size - 1), off = 0;
    char *buf = malloc(len ? len : 1);      /* normalizing swaps bytes in place */
    memcpy(buf, data + 1, len);
    if (dds_stream_normalize_data(buf, &off, len, (data[0] & 0x80) != 0, CDR_ENC_VERSION_1, k->desc->m_ops)) {
        dds_istream_t is;
        dds_istream_init(&is, len, buf, CDR_ENC_VERSION_1);
        void *sample = calloc(1, k->desc->m_size);
        dds_stream_read(&is, sample, k->desc->m_ops);
        ros2_ctx_t x = {.frame = "map", .source = "/fuzz", .now_us = 1000000};
        void *msg = ros2_arena_alloc(&x.arena, k->marie->size);
        const char *why;
        if (k->from(&x, sample, msg, &why) == 0)
            check_on_bus(k->marie, msg);
        ros2_arena_free(&x.arena);
        dds_stream_free_sample(sample, k->desc->m_ops);
        free(sample);
    }
    free(buf);
    return 0;
}
