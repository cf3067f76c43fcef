/* lms200: pure SICK LMS200 telegram codec (CRC-16, streaming parser, encoders, reply decoders). */
#ifndef MARIE_HW_LMS200_H
#define MARIE_HW_LMS200_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Telegram: STX | address | length (LE16) | command | data... | [status] | CRC (LE16).
 * length counts command + data (+ status); the CRC covers every byte from STX to the last
 * byte before it. Replies from the device carry address | 0x80 and always a status byte. */
#define LMS200_STX          0x02
#define LMS200_ACK          0x06
#define LMS200_NAK          0x15
#define LMS200_REPLY_BIT    0x80
#define LMS200_HEADER_LEN   4
#define LMS200_CRC_LEN      2
#define LMS200_MAX_LEN      812     /* longest length field the LMS2xx family sends */
#define LMS200_MAX_TELEGRAM (LMS200_HEADER_LEN + LMS200_MAX_LEN + LMS200_CRC_LEN)
#define LMS200_MAX_VALUES   401

/* Commands (host -> device) and replies (device -> host). */
enum {
    LMS200_CMD_MODE = 0x20,         /* change operating mode */
    LMS200_CMD_REQUEST = 0x30,      /* request measured values */
    LMS200_CMD_VARIANT = 0x3B,      /* switch variant (angle, resolution) */
    LMS200_REPLY_MODE = 0xA0,
    LMS200_REPLY_SCAN = 0xB0,
    LMS200_REPLY_VARIANT = 0xBB,
};

/* Operating modes for LMS200_CMD_MODE. */
enum {
    LMS200_MODE_INSTALL = 0x00,     /* needs the password */
    LMS200_MODE_CONTINUOUS = 0x24,  /* continuous output of all measured values */
    LMS200_MODE_STOP = 0x25,        /* measured values only on request */
    LMS200_MODE_BAUD_38400 = 0x40,
    LMS200_MODE_BAUD_19200 = 0x41,
    LMS200_MODE_BAUD_9600 = 0x42,
    LMS200_MODE_BAUD_500000 = 0x48,
};
#define LMS200_PASSWORD "SICK_LMS"

/* Result byte of the 0xA0 mode reply. */
enum {
    LMS200_MODE_OK = 0x00,
    LMS200_MODE_NOT_POSSIBLE = 0x01,
    LMS200_MODE_BAD_PASSWORD = 0x02,
    LMS200_MODE_FAULT = 0x03,
};

/* Measured-value units, from bits 14-15 of the 0xB0 count word. */
typedef enum { LMS200_UNIT_CM = 0, LMS200_UNIT_MM = 1 } lms200_unit_t;
/* Raw distances at or above this are error codes (no echo, dazzle, ...), not ranges. */
#define LMS200_VALUE_MASK      0x1FFF
#define LMS200_VALUE_ERROR_MIN 0x1FF7

/* The SICK CRC-16 (generator 0x8005, initial value 0) over len bytes. */
uint16_t lms200_crc(const uint8_t *buf, size_t len);

/* ---- streaming parser ---- */
typedef struct {
    uint8_t addr;
    uint8_t cmd;
    const uint8_t *data;        /* after the command byte, before the status byte */
    size_t data_len;
    bool has_status;            /* replies (address bit 7 set) */
    uint8_t status;
    const uint8_t *raw;         /* the whole telegram including the CRC */
    size_t raw_len;
} lms200_telegram_t;

typedef struct {
    uint64_t telegrams;         /* good telegrams delivered */
    uint64_t crc_errors;        /* complete telegrams whose CRC did not match */
    uint64_t truncated;         /* a telegram cut short by the next one, or by a reset */
    uint64_t oversized;         /* length field 0 or above LMS200_MAX_LEN */
    uint64_t garbage_bytes;     /* bytes skipped while looking for a telegram */
    uint64_t acks, naks;
} lms200_parser_stats_t;

typedef struct lms200_parser lms200_parser_t;
/* Pointers in the telegram are valid only during the callback. */
typedef void (*lms200_telegram_cb_t)(void *user, const lms200_telegram_t *t);
/* ACK (0x06) or NAK (0x15) seen between telegrams. */
typedef void (*lms200_ack_cb_t)(void *user, uint8_t byte);

/* NULL with errno on failure. on_ack may be NULL. */
lms200_parser_t *lms200_parser_create(lms200_telegram_cb_t on_telegram, lms200_ack_cb_t on_ack, void *user);
void lms200_parser_destroy(lms200_parser_t *p);         /* NULL is a no-op */
/* Consume len bytes; callbacks run from inside. Returns the number of telegrams delivered.
 * After a bad CRC the bytes after the false start are scanned again, so one corrupt or
 * truncated telegram never hides the good one behind it. */
int lms200_parser_feed(lms200_parser_t *p, const uint8_t *buf, size_t len);
/* Bytes held waiting for the rest of a telegram. */
size_t lms200_parser_pending(const lms200_parser_t *p);
/* Drop held bytes (line silent, baud changed, device reopened); a partial telegram counts
 * as truncated. */
void lms200_parser_reset(lms200_parser_t *p);
const lms200_parser_stats_t *lms200_parser_stats(const lms200_parser_t *p);

/* ---- encoders: write one telegram into out (cap bytes); return its length, 0 if it does not fit ---- */
size_t lms200_encode(uint8_t *out, size_t cap, uint8_t addr, uint8_t cmd,
                     const uint8_t *data, size_t data_len, int status /* <0: none */);
/* Mode change; password NULL uses LMS200_PASSWORD for LMS200_MODE_INSTALL. */
size_t lms200_encode_mode(uint8_t *out, size_t cap, uint8_t addr, uint8_t mode, const char *password);
size_t lms200_encode_variant(uint8_t *out, size_t cap, uint8_t addr, uint16_t angle_deg, uint16_t res_cdeg);
size_t lms200_encode_request(uint8_t *out, size_t cap, uint8_t addr);
/* Device side (emulator, tests). addr is the device's own address; the reply bit is added. */
size_t lms200_encode_mode_reply(uint8_t *out, size_t cap, uint8_t addr, uint8_t result, uint8_t status);
size_t lms200_encode_variant_reply(uint8_t *out, size_t cap, uint8_t addr, bool ok,
                                   uint16_t angle_deg, uint16_t res_cdeg, uint8_t status);
size_t lms200_encode_scan(uint8_t *out, size_t cap, uint8_t addr, lms200_unit_t unit,
                          const uint16_t *values, size_t n, uint8_t status);

/* Bytes of a scan telegram of n values (732 for 361), and the time n bytes take on the line
 * at baud (8N1: 10 bits a byte; 0.76 s for that telegram at 9600). */
size_t lms200_scan_telegram_len(size_t n);
int64_t lms200_wire_us(size_t bytes, int baud);

/* Baud rate <-> mode byte. -1 / 0 when not an LMS200 rate. */
int lms200_baud_mode(int baud);
int lms200_mode_baud(uint8_t mode);

/* ---- reply decoders: 0, or -1 with errno EBADMSG when the telegram is not a well-formed reply ---- */
int lms200_decode_mode_reply(const lms200_telegram_t *t, uint8_t *result);
typedef struct {
    bool ok;
    uint16_t angle_deg;
    uint16_t res_cdeg;
} lms200_variant_t;
int lms200_decode_variant_reply(const lms200_telegram_t *t, lms200_variant_t *v);

typedef struct {
    uint16_t n;                 /* number of values */
    lms200_unit_t unit;
    bool partial;               /* part of an interlaced scan */
    uint8_t partial_index;      /* which part (0..3) */
    uint16_t values[LMS200_MAX_VALUES];   /* masked with LMS200_VALUE_MASK */
    uint8_t flags[LMS200_MAX_VALUES];     /* the 3 bits above the value (field/dazzle flags) */
    uint8_t status;
} lms200_scan_t;
int lms200_decode_scan(const lms200_telegram_t *t, lms200_scan_t *s);
/* A value in metres; error codes give +INFINITY (the caller maps them to range_max). */
double lms200_value_m(uint16_t value, lms200_unit_t unit);

#ifdef __cplusplus
}
#endif
#endif
