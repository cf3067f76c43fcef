/* cia402: the CiA 402 drive state machine: statusword decoding and controlword commands for
 * the master, and the device side (state transitions per controlword) for the emulator. */
#ifndef MARIE_HW_CIA402_H
#define MARIE_HW_CIA402_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Objects (CiA 402 part 2) used in profile velocity mode. */
#define CIA402_OBJ_ABORT_CONN   0x6007  /* i16: abort connection option code */
#define CIA402_OBJ_ERROR_CODE   0x603F  /* u16 */
#define CIA402_OBJ_CONTROLWORD  0x6040  /* u16 */
#define CIA402_OBJ_STATUSWORD   0x6041  /* u16 */
#define CIA402_OBJ_QUICKSTOP_OPT 0x605A /* i16 */
#define CIA402_OBJ_MODE         0x6060  /* i8: modes of operation */
#define CIA402_OBJ_MODE_DISPLAY 0x6061  /* i8 */
#define CIA402_OBJ_POSITION     0x6064  /* i32: position actual value, increments */
#define CIA402_OBJ_VELOCITY     0x606C  /* i32: velocity actual value, increments/s */
#define CIA402_OBJ_PROFILE_ACC  0x6083  /* u32: increments/s^2 */
#define CIA402_OBJ_PROFILE_DEC  0x6084  /* u32 */
#define CIA402_OBJ_QUICKSTOP_DEC 0x6085 /* u32 */
#define CIA402_OBJ_TARGET_VEL   0x60FF  /* i32: target velocity, increments/s */
#define CIA402_DEVICE_TYPE      0x00020192u  /* 0x1000: profile 402, servo drive */
#define CIA402_MODE_PROFILE_VELOCITY 3

typedef enum {
    CIA402_NOT_READY = 0,           /* not ready to switch on */
    CIA402_SWITCH_ON_DISABLED,
    CIA402_READY_TO_SWITCH_ON,
    CIA402_SWITCHED_ON,
    CIA402_OPERATION_ENABLED,
    CIA402_QUICK_STOP_ACTIVE,
    CIA402_FAULT_REACTION_ACTIVE,
    CIA402_FAULT,
    CIA402_UNKNOWN,                 /* a statusword matching no state */
} cia402_state_t;

/* Statusword bits. */
#define CIA402_SW_READY_TO_SWITCH_ON 0x0001
#define CIA402_SW_SWITCHED_ON        0x0002
#define CIA402_SW_OPERATION_ENABLED  0x0004
#define CIA402_SW_FAULT              0x0008
#define CIA402_SW_VOLTAGE_ENABLED    0x0010
#define CIA402_SW_QUICK_STOP         0x0020  /* 0 = quick stop active */
#define CIA402_SW_SWITCH_ON_DISABLED 0x0040
#define CIA402_SW_WARNING            0x0080
#define CIA402_SW_REMOTE             0x0200
#define CIA402_SW_TARGET_REACHED     0x0400
#define CIA402_SW_SPEED_ZERO         0x1000  /* profile velocity mode: speed is 0 */

/* Controlword commands (bits 0-3 and 7). */
#define CIA402_CW_SHUTDOWN          0x0006
#define CIA402_CW_SWITCH_ON         0x0007
#define CIA402_CW_DISABLE_VOLTAGE   0x0000
#define CIA402_CW_QUICK_STOP        0x0002
#define CIA402_CW_DISABLE_OPERATION 0x0007
#define CIA402_CW_ENABLE_OPERATION  0x000F
#define CIA402_CW_FAULT_RESET       0x0080
#define CIA402_CW_HALT              0x0100

const char *cia402_state_name(cia402_state_t s);
/* The name of an object a CiA 402 drive has ("modes of operation"; the CiA 301 names of
 * communication objects, co_object_name), NULL when marie does not know it. */
const char *cia402_object_name(uint16_t index);
cia402_state_t cia402_state_from_sw(uint16_t sw);
/* The statusword of a state (bits 0-6), as a device reports it. */
uint16_t cia402_sw_from_state(cia402_state_t s);

/* What the master wants from a drive. */
typedef enum {
    CIA402_WANT_DISABLED = 0,   /* voltage off: switch on disabled */
    CIA402_WANT_ENABLED,        /* operation enabled */
    CIA402_WANT_QUICK_STOP,     /* e-stop: quick stop active (or not enabled at all) */
} cia402_want_t;

/* Master side: the next controlword to move a drive in `cur` toward `want`. `prev` is the
 * last controlword sent: a fault reset needs a rising edge of bit 7, so from fault this
 * returns 0x0000 first when the previous one had bit 7 set. `allow_reset` false holds a
 * faulted drive in fault. */
uint16_t cia402_next_controlword(cia402_state_t cur, cia402_want_t want, uint16_t prev, bool allow_reset);

/* Device-side controlword commands. */
typedef enum {
    CIA402_CMD_NONE = 0, CIA402_CMD_SHUTDOWN, CIA402_CMD_SWITCH_ON, CIA402_CMD_SWITCH_ON_ENABLE,
    CIA402_CMD_DISABLE_VOLTAGE, CIA402_CMD_QUICK_STOP, CIA402_CMD_DISABLE_OPERATION,
    CIA402_CMD_ENABLE_OPERATION, CIA402_CMD_FAULT_RESET,
} cia402_cmd_t;

/* Decode a controlword into the command it means in state `cur` (CiA 402 table 28);
 * fault reset needs the rising edge of bit 7 against `prev`. */
cia402_cmd_t cia402_decode_controlword(cia402_state_t cur, uint16_t cw, uint16_t prev);
/* Device side: the state after `cmd` in `cur` (unchanged when the command does not apply). */
cia402_state_t cia402_transition(cia402_state_t cur, cia402_cmd_t cmd);
/* True when the power stage drives the motor (operation enabled or stopping). */
bool cia402_state_powered(cia402_state_t s);

#ifdef __cplusplus
}
#endif
#endif
