/* cia402: the drive state machine of CiA 402 (IEC 61800-7-201), both ends. */
#include "hw/drives/cia402.h"

#include <stddef.h>

#include "hw/canopen/sdo.h"

const char *cia402_object_name(uint16_t index)
{
    static const struct { uint16_t index; const char *name; } names[] = {
        { CIA402_OBJ_ABORT_CONN, "abort connection option code" }, { CIA402_OBJ_ERROR_CODE, "error code" },
        { CIA402_OBJ_CONTROLWORD, "controlword" }, { CIA402_OBJ_STATUSWORD, "statusword" },
        { CIA402_OBJ_MODE, "modes of operation" }, { CIA402_OBJ_MODE_DISPLAY, "modes of operation display" },
        { CIA402_OBJ_POSITION, "position actual value" }, { CIA402_OBJ_VELOCITY, "velocity actual value" },
        { CIA402_OBJ_PROFILE_ACC, "profile acceleration" }, { CIA402_OBJ_QUICKSTOP_DEC, "quick stop deceleration" },
        { CIA402_OBJ_TARGET_VEL, "target velocity" },
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (names[i].index == index)
            return names[i].name;
    return co_object_name(index);
}

const char *cia402_state_name(cia402_state_t s)
{
    switch (s) {
    case CIA402_NOT_READY: return "not ready to switch on";
    case CIA402_SWITCH_ON_DISABLED: return "switch on disabled";
    case CIA402_READY_TO_SWITCH_ON: return "ready to switch on";
    case CIA402_SWITCHED_ON: return "switched on";
    case CIA402_OPERATION_ENABLED: return "operation enabled";
    case CIA402_QUICK_STOP_ACTIVE: return "quick stop active";
    case CIA402_FAULT_REACTION_ACTIVE: return "fault reaction active";
    case CIA402_FAULT: return "fault";
    case CIA402_UNKNOWN: break;
    }
    return "unknown";
}

cia402_state_t cia402_state_from_sw(uint16_t sw)
{
    /* CiA 402 table 30: the masks exclude bits whose value does not matter. */
    if ((sw & 0x4F) == 0x00) return CIA402_NOT_READY;
    if ((sw & 0x4F) == 0x40) return CIA402_SWITCH_ON_DISABLED;
    if ((sw & 0x6F) == 0x21) return CIA402_READY_TO_SWITCH_ON;
    if ((sw & 0x6F) == 0x23) return CIA402_SWITCHED_ON;
    if ((sw & 0x6F) == 0x27) return CIA402_OPERATION_ENABLED;
    if ((sw & 0x6F) == 0x07) return CIA402_QUICK_STOP_ACTIVE;
    if ((sw & 0x4F) == 0x0F) return CIA402_FAULT_REACTION_ACTIVE;
    if ((sw & 0x4F) == 0x08) return CIA402_FAULT;
    return CIA402_UNKNOWN;
}

uint16_t cia402_sw_from_state(cia402_state_t s)
{
    switch (s) {
    case CIA402_NOT_READY: return 0x0000;
    case CIA402_SWITCH_ON_DISABLED: return 0x0040 | CIA402_SW_QUICK_STOP;
    case CIA402_READY_TO_SWITCH_ON: return 0x0021 | CIA402_SW_VOLTAGE_ENABLED;
    case CIA402_SWITCHED_ON: return 0x0023 | CIA402_SW_VOLTAGE_ENABLED;
    case CIA402_OPERATION_ENABLED: return 0x0027 | CIA402_SW_VOLTAGE_ENABLED;
    case CIA402_QUICK_STOP_ACTIVE: return 0x0007 | CIA402_SW_VOLTAGE_ENABLED;
    case CIA402_FAULT_REACTION_ACTIVE: return 0x000F | CIA402_SW_VOLTAGE_ENABLED;
    case CIA402_FAULT: return 0x0008;
    case CIA402_UNKNOWN: break;
    }
    return 0;
}

uint16_t cia402_next_controlword(cia402_state_t cur, cia402_want_t want, uint16_t prev, bool allow_reset)
{
    switch (cur) {
    case CIA402_FAULT:
        if (!allow_reset || (prev & CIA402_CW_FAULT_RESET))
            return CIA402_CW_DISABLE_VOLTAGE;       /* bit 7 low first: the reset is an edge */
        return CIA402_CW_FAULT_RESET;
    case CIA402_NOT_READY:
    case CIA402_FAULT_REACTION_ACTIVE:
    case CIA402_UNKNOWN:
        return CIA402_CW_DISABLE_VOLTAGE;           /* the drive moves on by itself */
    case CIA402_SWITCH_ON_DISABLED:
        return want == CIA402_WANT_ENABLED ? CIA402_CW_SHUTDOWN : CIA402_CW_DISABLE_VOLTAGE;
    case CIA402_READY_TO_SWITCH_ON:
        if (want == CIA402_WANT_ENABLED)
            return CIA402_CW_SWITCH_ON;
        return want == CIA402_WANT_QUICK_STOP ? CIA402_CW_QUICK_STOP : CIA402_CW_DISABLE_VOLTAGE;
    case CIA402_SWITCHED_ON:
        if (want == CIA402_WANT_ENABLED)
            return CIA402_CW_ENABLE_OPERATION;
        return want == CIA402_WANT_QUICK_STOP ? CIA402_CW_QUICK_STOP : CIA402_CW_DISABLE_VOLTAGE;
    case CIA402_OPERATION_ENABLED:
        if (want == CIA402_WANT_ENABLED)
            return CIA402_CW_ENABLE_OPERATION;
        return want == CIA402_WANT_QUICK_STOP ? CIA402_CW_QUICK_STOP : CIA402_CW_DISABLE_VOLTAGE;
    case CIA402_QUICK_STOP_ACTIVE:
        if (want == CIA402_WANT_ENABLED)
            return CIA402_CW_ENABLE_OPERATION;       /* transition 16 */
        return want == CIA402_WANT_QUICK_STOP ? CIA402_CW_QUICK_STOP : CIA402_CW_DISABLE_VOLTAGE;
    }
    return CIA402_CW_DISABLE_VOLTAGE;
}

cia402_cmd_t cia402_decode_controlword(cia402_state_t cur, uint16_t cw, uint16_t prev)
{
    if ((cw & CIA402_CW_FAULT_RESET) && !(prev & CIA402_CW_FAULT_RESET))
        return CIA402_CMD_FAULT_RESET;
    if (cw & CIA402_CW_FAULT_RESET)
        return CIA402_CMD_NONE;                     /* held high: no new command */
    /* Table 28: bits 3 2 1 0 (enable operation, quick stop, enable voltage, switch on). */
    if (!(cw & 0x0002))
        return CIA402_CMD_DISABLE_VOLTAGE;          /* x x 0 x */
    if (!(cw & 0x0004))
        return CIA402_CMD_QUICK_STOP;               /* x 0 1 x */
    switch (cw & 0x000F) {
    case 0x6: case 0xE:
        return CIA402_CMD_SHUTDOWN;                 /* x 1 1 0 */
    case 0x7:
        return cur == CIA402_OPERATION_ENABLED ? CIA402_CMD_DISABLE_OPERATION : CIA402_CMD_SWITCH_ON;
    case 0xF:
        if (cur == CIA402_READY_TO_SWITCH_ON)
            return CIA402_CMD_SWITCH_ON_ENABLE;     /* transitions 3 + 4 */
        return CIA402_CMD_ENABLE_OPERATION;
    }
    return CIA402_CMD_NONE;
}

cia402_state_t cia402_transition(cia402_state_t cur, cia402_cmd_t cmd)
{
    switch (cur) {
    case CIA402_SWITCH_ON_DISABLED:
        if (cmd == CIA402_CMD_SHUTDOWN) return CIA402_READY_TO_SWITCH_ON;           /* 2 */
        break;
    case CIA402_READY_TO_SWITCH_ON:
        if (cmd == CIA402_CMD_SWITCH_ON) return CIA402_SWITCHED_ON;                 /* 3 */
        if (cmd == CIA402_CMD_SWITCH_ON_ENABLE) return CIA402_OPERATION_ENABLED;    /* 3+4 */
        if (cmd == CIA402_CMD_DISABLE_VOLTAGE || cmd == CIA402_CMD_QUICK_STOP)
            return CIA402_SWITCH_ON_DISABLED;                                       /* 7 */
        break;
    case CIA402_SWITCHED_ON:
        if (cmd == CIA402_CMD_ENABLE_OPERATION) return CIA402_OPERATION_ENABLED;    /* 4 */
        if (cmd == CIA402_CMD_SHUTDOWN) return CIA402_READY_TO_SWITCH_ON;           /* 6 */
        if (cmd == CIA402_CMD_DISABLE_VOLTAGE || cmd == CIA402_CMD_QUICK_STOP)
            return CIA402_SWITCH_ON_DISABLED;                                       /* 10 */
        break;
    case CIA402_OPERATION_ENABLED:
        if (cmd == CIA402_CMD_DISABLE_OPERATION) return CIA402_SWITCHED_ON;         /* 5 */
        if (cmd == CIA402_CMD_SHUTDOWN) return CIA402_READY_TO_SWITCH_ON;           /* 8 */
        if (cmd == CIA402_CMD_DISABLE_VOLTAGE) return CIA402_SWITCH_ON_DISABLED;    /* 9 */
        if (cmd == CIA402_CMD_QUICK_STOP) return CIA402_QUICK_STOP_ACTIVE;          /* 11 */
        break;
    case CIA402_QUICK_STOP_ACTIVE:
        if (cmd == CIA402_CMD_DISABLE_VOLTAGE) return CIA402_SWITCH_ON_DISABLED;    /* 12 */
        if (cmd == CIA402_CMD_ENABLE_OPERATION) return CIA402_OPERATION_ENABLED;    /* 16 */
        break;
    case CIA402_FAULT:
        if (cmd == CIA402_CMD_FAULT_RESET) return CIA402_SWITCH_ON_DISABLED;        /* 15 */
        break;
    case CIA402_NOT_READY:              /* 1: automatic, after self test */
    case CIA402_FAULT_REACTION_ACTIVE:  /* 14: automatic, once stopped */
    case CIA402_UNKNOWN:
        break;
    }
    return cur;
}

bool cia402_state_powered(cia402_state_t s)
{
    return s == CIA402_OPERATION_ENABLED || s == CIA402_QUICK_STOP_ACTIVE ||
           s == CIA402_FAULT_REACTION_ACTIVE;
}
