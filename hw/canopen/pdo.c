/* pdo: bit-packing of PDO payloads per a mapping table. */
#include "hw/canopen/pdo.h"

#include <errno.h>
#include <string.h>

#include "core/err.h"

static int map_bits(const co_pdo_map_t *m)
{
    if (m->n > CO_PDO_MAX_ENTRIES)
        return marie_fail(EINVAL);
    int bits = 0;
    for (int i = 0; i < m->n; i++) {
        if (m->e[i].bits == 0 || m->e[i].bits > 64)
            return marie_fail(EINVAL);
        bits += m->e[i].bits;
    }
    return bits > 64 ? marie_fail(EINVAL) : bits;
}

int co_pdo_map_bytes(const co_pdo_map_t *m)
{
    int bits = map_bits(m);
    return bits < 0 ? bits : (bits + 7) / 8;
}

int co_pdo_encode(const co_pdo_map_t *m, const uint64_t *vals, struct can_frame *f)
{
    int bits = map_bits(m);
    if (bits < 0)
        return bits;
    memset(f, 0, sizeof *f);
    f->can_id = m->cob_id;
    f->len = (uint8_t)((bits + 7) / 8);
    /* The payload is one little-endian bit string; entries follow each other from bit 0. */
    uint64_t acc = 0;
    int at = 0;
    for (int i = 0; i < m->n; i++) {
        uint8_t b = m->e[i].bits;
        uint64_t v = b == 64 ? vals[i] : vals[i] & ((UINT64_C(1) << b) - 1);
        acc |= v << at;
        at += b;
    }
    for (int k = 0; k < f->len; k++)
        f->data[k] = (uint8_t)(acc >> (8 * k));
    return f->len;
}

int co_pdo_decode(const co_pdo_map_t *m, const struct can_frame *f, uint64_t *vals)
{
    int bits = map_bits(m);
    if (bits < 0)
        return bits;
    if (f->len < (bits + 7) / 8 || f->len > 8)
        return marie_fail(EBADMSG);
    uint64_t acc = 0;
    for (int k = 0; k < f->len; k++)
        acc |= (uint64_t)f->data[k] << (8 * k);
    int at = 0;
    for (int i = 0; i < m->n; i++) {
        uint8_t b = m->e[i].bits;
        uint64_t v = at >= 64 ? 0 : acc >> at;
        vals[i] = b == 64 ? v : v & ((UINT64_C(1) << b) - 1);
        at += b;
    }
    return 0;
}

int64_t co_pdo_signed(uint64_t v, uint8_t bits)
{
    if (bits == 0 || bits >= 64)
        return (int64_t)v;
    uint64_t sign = UINT64_C(1) << (bits - 1);
    v &= (UINT64_C(1) << bits) - 1;
    return (int64_t)((v ^ sign) - sign);
}

int co_pdo_map_steps(co_sdo_step_t *out, uint16_t comm, canid_t cob, const co_pdo_map_t *m, uint8_t trans,
                     const co_sdo_step_t *extra)
{
    uint16_t map = (uint16_t)(comm + 0x200);
    int n = 0;
    out[n++] = (co_sdo_step_t){ CO_STEP_DN, comm, 1, 4, CO_STEP_INVALID_NODE, cob };
    out[n++] = (co_sdo_step_t){ CO_STEP_DN, map, 0, 1, CO_STEP_CONST, 0 };
    for (int i = 0; i < m->n && i < CO_PDO_MAX_ENTRIES; i++)
        out[n++] = (co_sdo_step_t){ CO_STEP_DN, map, (uint8_t)(i + 1), 4, CO_STEP_CONST, co_pdo_entry_u32(m->e[i]) };
    out[n++] = (co_sdo_step_t){ CO_STEP_DN, map, 0, 1, CO_STEP_CONST, m->n };
    out[n++] = (co_sdo_step_t){ CO_STEP_DN, comm, 2, 1, CO_STEP_CONST, trans };
    if (extra)
        out[n++] = *extra;
    out[n++] = (co_sdo_step_t){ CO_STEP_DN, comm, 1, 4, CO_STEP_NODE, cob };
    return n;
}
