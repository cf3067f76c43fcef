/* emcy: CANopen emergency messages (0x080 + node): error code, error register, vendor bytes. */
#ifndef MARIE_HW_CO_EMCY_H
#define MARIE_HW_CO_EMCY_H

#include <stdint.h>
#include <linux/can.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Error codes used by marie's drives and gyro (CiA 301 table 21, CiA 402 annex). */
#define CO_EMCY_NO_ERROR        0x0000  /* error reset or no error */
#define CO_EMCY_GENERIC         0x1000
#define CO_EMCY_CURRENT         0x2000
#define CO_EMCY_OVERCURRENT     0x2310  /* continuous over-current */
#define CO_EMCY_VOLTAGE         0x3000
#define CO_EMCY_OVERVOLTAGE     0x3210  /* DC link over-voltage */
#define CO_EMCY_UNDERVOLTAGE    0x3220  /* DC link under-voltage */
#define CO_EMCY_TEMPERATURE     0x4000
#define CO_EMCY_OVERTEMP_DRIVE  0x4310
#define CO_EMCY_HARDWARE        0x5000
#define CO_EMCY_SOFTWARE        0x6000
#define CO_EMCY_MONITORING      0x8000
#define CO_EMCY_CAN_OVERRUN     0x8110  /* CAN overrun (objects lost) */
#define CO_EMCY_CAN_PASSIVE     0x8120
#define CO_EMCY_HB_ERROR        0x8130  /* life guard or heartbeat error */
#define CO_EMCY_BUS_OFF_REC     0x8140  /* recovered from bus off */
#define CO_EMCY_PDO_LENGTH      0x8210  /* PDO not processed due to length error */
#define CO_EMCY_RPDO_TIMEOUT    0x8250  /* RPDO timeout (event-timer deadline missed) */
#define CO_EMCY_FOLLOWING_ERR   0x8611  /* following error (CiA 402) */
#define CO_EMCY_SENSOR          0x7300  /* sensor (encoder / gyro element) */
#define CO_EMCY_DEVICE_SPECIFIC 0xFF00

typedef struct {
    uint8_t node;
    uint16_t code;
    uint8_t reg;            /* error register (object 0x1001) */
    uint8_t vendor[5];
} co_emcy_t;

int co_emcy_encode(struct can_frame *f, const co_emcy_t *e);
/* 0, or -1 with errno EBADMSG (not 0x081..0x0FF, or DLC other than 8). */
int co_emcy_decode(const struct can_frame *f, co_emcy_t *e);
/* Text for a code: exact where known, else its class ("voltage", "temperature"...). */
const char *co_emcy_str(uint16_t code);

#ifdef __cplusplus
}
#endif
#endif
