/* emcy: emergency message codec and code names. */
#include "hw/canopen/emcy.h"

#include <errno.h>

#include "core/err.h"
#include "hw/canopen/co.h"

int co_emcy_encode(struct can_frame *f, const co_emcy_t *e)
{
    uint8_t d[8];
    co_put_u16(d, e->code);
    d[2] = e->reg;
    for (int i = 0; i < 5; i++)
        d[3 + i] = e->vendor[i];
    co_frame_set(f, CO_COB_EMCY + e->node, d, 8);
    return 8;
}

int co_emcy_decode(const struct can_frame *f, co_emcy_t *e)
{
    uint8_t node;
    if (co_classify(f->can_id, &node, NULL) != CO_FC_EMCY || f->len != 8)
        return marie_fail(EBADMSG);
    e->node = node;
    e->code = co_get_u16(f->data);
    e->reg = f->data[2];
    for (int i = 0; i < 5; i++)
        e->vendor[i] = f->data[3 + i];
    return 0;
}

const char *co_emcy_str(uint16_t code)
{
    switch (code) {
    case CO_EMCY_NO_ERROR: return "error reset";
    case CO_EMCY_OVERCURRENT: return "continuous over-current";
    case CO_EMCY_OVERVOLTAGE: return "DC link over-voltage";
    case CO_EMCY_UNDERVOLTAGE: return "DC link under-voltage";
    case CO_EMCY_OVERTEMP_DRIVE: return "drive over-temperature";
    case CO_EMCY_CAN_OVERRUN: return "CAN overrun";
    case CO_EMCY_CAN_PASSIVE: return "CAN error passive";
    case CO_EMCY_HB_ERROR: return "heartbeat error";
    case CO_EMCY_BUS_OFF_REC: return "recovered from bus off";
    case CO_EMCY_PDO_LENGTH: return "PDO length error";
    case CO_EMCY_RPDO_TIMEOUT: return "RPDO timeout";
    case CO_EMCY_FOLLOWING_ERR: return "following error";
    case CO_EMCY_SENSOR: return "sensor fault";
    }
    switch (code >> 12) {
    case 0x1: return "generic error";
    case 0x2: return "current";
    case 0x3: return "voltage";
    case 0x4: return "temperature";
    case 0x5: return "device hardware";
    case 0x6: return "device software";
    case 0x7: return "additional modules";
    case 0x8: return "monitoring";
    case 0x9: return "external error";
    case 0xF: return code >= 0xFF00 ? "device specific" : "additional functions";
    }
    return "unknown";
}
