/* drives_text: what the wheel-drive master's events say to a person (drives_ctl_event_text). */
#include "hw/drives/drives_ctl.h"

#include <stdio.h>

#include "hw/canopen/emcy.h"

static const char *side(int axis) { return axis == 0 ? "left" : axis == 1 ? "right" : "bus"; }

static const char *object_name(uint16_t index)
{
    const char *n = cia402_object_name(index);
    return n ? n : "object";
}

static void fail_text(const drives_ctl_t *d, int axis, char *buf, size_t cap)
{
    const drives_cfg_fail_t *f = &drives_ctl_axis(d, axis)->fail;
    int n;
    if (f->abort)
        n = snprintf(buf, cap, "%s drive: configuration failed at 0x%04X:%02X (%s, %s): %s (0x%08X)", side(axis),
                     f->index, f->sub, object_name(f->index), f->write ? "write" : "read", co_sdo_abort_str(f->abort),
                     f->abort);
    else
        n = snprintf(buf, cap, "%s drive: configuration failed at 0x%04X:%02X (%s): 0x%08X is not a CiA 402 drive",
                     side(axis), f->index, f->sub, object_name(f->index), f->value);
    if (n > 0 && (size_t)n < cap)
        snprintf(buf + n, cap - (size_t)n, "; stopped, again in %.0f s%s", DRIVES_BOOT_RETRY_US / 1e6,
                 f->repeats ? " (failed alike before)" : "");
}

static void watch_text(const drives_ctl_t *d, int axis, uint32_t code, char *buf, size_t cap)
{
    const drives_axis_t *a = drives_ctl_axis(d, axis);
    const char *hb = a->lacks_consumer ? "it has no 0x1016" : "master_heartbeat_ms is 0";
    if (code == DRIVES_WATCH_RPDO_ONLY)
        snprintf(buf, cap, "%s drive cannot watch our heartbeat (%s): it notices a dead marie-drives by its RPDO "
                 "deadline alone (0x1400:05, %u ms)", side(axis), hb, drives_ctl_rpdo_timeout_ms(d));
    else
        snprintf(buf, cap, "%s drive can watch neither our heartbeat (%s) nor our RPDOs (%s): it would keep turning "
                 "if marie-drives died; %s", side(axis), hb,
                 drives_ctl_rpdo_timeout_ms(d) ? "it has no 0x1400:05" : "rpdo_timeout is 0",
                 code == DRIVES_WATCH_NONE_REFUSED ? "kept disabled (allow_unwatched: true drives it anyway)"
                                                   : "driven all the same (allow_unwatched)");
}

static void configured_text(const drives_ctl_t *d, int axis, char *buf, size_t cap)
{
    const drives_axis_t *a = drives_ctl_axis(d, axis);
    int n = snprintf(buf, cap, "%s drive '%s' configured, started", side(axis), a->name);
    if (n > 0 && (size_t)n < cap && (a->identity[0] || a->identity[1] || a->identity[3]))
        snprintf(buf + n, cap - (size_t)n, " (vendor 0x%08X, product 0x%X, revision 0x%X, serial %u)", a->identity[0],
                 a->identity[1], a->identity[2], a->identity[3]);
}

void drives_ctl_event_text(const drives_ctl_t *d, int axis, drives_ev_t e, uint32_t code, char *buf, size_t cap)
{
    const drives_axis_t *a = axis >= 0 && axis < DRIVES_N ? drives_ctl_axis(d, axis) : NULL;
    if (!a && e != DRIVES_EV_UNEXPECTED) {
        snprintf(buf, cap, "bus: %s 0x%X", drives_ev_name(e), code);
        return;
    }
    switch (e) {
    case DRIVES_EV_CONFIGURED: configured_text(d, axis, buf, cap); break;
    case DRIVES_EV_CONFIG_FAILED: fail_text(d, axis, buf, cap); break;
    case DRIVES_EV_WATCH: watch_text(d, axis, code, buf, cap); break;
    case DRIVES_EV_FAULT:
        if (a->have_fault_emcy)
            snprintf(buf, cap, "%s drive in fault (last EMCY 0x%04X %s)", side(axis), code, co_emcy_str((uint16_t)code));
        else
            snprintf(buf, cap, "%s drive in fault (no EMCY told why; statusword 0x%04X)", side(axis), a->statusword);
        break;
    case DRIVES_EV_FAULT_RESET: snprintf(buf, cap, "%s drive: fault reset", side(axis)); break;
    case DRIVES_EV_RECOVERED: snprintf(buf, cap, "%s drive operational again", side(axis)); break;
    case DRIVES_EV_EMCY:
    case DRIVES_EV_EMCY_QUIET:
        snprintf(buf, cap, "%s drive EMCY 0x%04X %s", side(axis), code, co_emcy_str((uint16_t)code));
        break;
    case DRIVES_EV_EMCY_STORM:
        snprintf(buf, cap, "%s drive: EMCY storm (0x%04X), further ones only counted", side(axis), code);
        break;
    case DRIVES_EV_HB_TIMEOUT: snprintf(buf, cap, "%s drive: heartbeat lost", side(axis)); break;
    case DRIVES_EV_BOOTUP: snprintf(buf, cap, "%s drive booted", side(axis)); break;
    case DRIVES_EV_BAD_FRAME: snprintf(buf, cap, "%s drive: malformed frame id 0x%03X", side(axis), code); break;
    case DRIVES_EV_UNEXPECTED: snprintf(buf, cap, "unexpected frame id 0x%03X", code); break;
    case DRIVES_EV_OPTIONAL_MISSING:
        snprintf(buf, cap, "%s drive has no object 0x%04X:%02X (%s; optional, skipped)", side(axis), code >> 8,
                 code & 0xFF, object_name((uint16_t)(code >> 8)));
        break;
    case DRIVES_EV_HOLD:
        snprintf(buf, cap, "%s drive enabled again: the motor command from before is not resumed, it waits for a new "
                 "one (restart interlock)", side(axis));
        break;
    case DRIVES_EV_NOT_FOUND:
        snprintf(buf, cap, "%s drive (node %u): no boot-up %.0f s after reset communication; asking again",
                 side(axis), drives_ctl_node(d, axis), DRIVES_BOOT_RETRY_US / 1e6);
        break;
    }
}
