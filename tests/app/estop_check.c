/* estop_check: reads a demo log and measures the software e-stop chain after the first press on
 * SIM_ESTOP: the behaviours' zero MOTOR_COMMAND from the e-stop behaviour and the drives'
 * WHEEL_ENCODERS reporting them stopped (ESTOP or DISABLED), in the components' (sim) clock.
 *   estop_check LOG MAX_S     exit 0 when both happen, each 0 < latency <= MAX_S */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <lcm/lcm.h>

#include "core/typeinfo.h"
#include "lcmtypes/marie_types.h"

/* One decoded record of a channel we follow, or -1 when it is not one or does not decode:
 * the log came from the bus, so it goes through the checked decode like any bus input. */
static int decode(const lcm_eventlog_event_t *ev, const char *ch, const marie_type_t *t, void *out)
{
    if (strcmp(ev->channel, ch) != 0)
        return -1;
    return marie_decode_checked(t, ev->data, (size_t)ev->datalen, out) == 0 ? 0 : -1;
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: estop_check LOG MAX_S\n");
        return 2;
    }
    double max_s = atof(argv[2]);
    lcm_eventlog_t *log = lcm_eventlog_create(argv[1], "r");
    if (!log) {
        perror(argv[1]);
        return 2;
    }
    int64_t pressed = 0, cmd_at = 0, drives_at = 0, estop_at = 0;
    long moving_after = 0;
    lcm_eventlog_event_t *ev;
    while ((ev = lcm_eventlog_read_next_event(log)) != NULL && !(cmd_at && drives_at)) {
        marie_estop_t e;
        marie_motor_command_t m;
        marie_wheel_encoders_t w;
        if (!pressed && decode(ev, "SIM_ESTOP", &marie_type_estop_t, &e) == 0) {
            if (e.pressed)
                pressed = e.utime;
            marie_type_estop_t.decode_cleanup(&e);
        } else if (pressed && !estop_at && decode(ev, "ESTOP", &marie_type_estop_t, &e) == 0) {
            if (e.pressed)
                estop_at = e.utime;
            marie_type_estop_t.decode_cleanup(&e);
        } else if (pressed && !cmd_at && decode(ev, "MOTOR_COMMAND", &marie_type_motor_command_t, &m) == 0) {
            if (m.v == 0 && m.omega == 0 && m.source && strcmp(m.source, "estop") == 0)
                cmd_at = m.utime;
            else
                moving_after++;
            marie_type_motor_command_t.decode_cleanup(&m);
        } else if (pressed && !drives_at && decode(ev, "WHEEL_ENCODERS", &marie_type_wheel_encoders_t, &w) == 0) {
            if (w.status == MARIE_WHEEL_ENCODERS_T_STATUS_ESTOP || w.status == MARIE_WHEEL_ENCODERS_T_STATUS_DISABLED)
                drives_at = w.utime;
            marie_type_wheel_encoders_t.decode_cleanup(&w);
        }
        lcm_eventlog_free_event(ev);
    }
    if (ev)
        lcm_eventlog_free_event(ev);
    lcm_eventlog_destroy(log);
    if (!pressed) {
        printf("estop_check: no e-stop press on SIM_ESTOP in %s\n", argv[1]);
        return 1;
    }
    double cmd_s = cmd_at ? (cmd_at - pressed) / 1e6 : -1, drives_s = drives_at ? (drives_at - pressed) / 1e6 : -1;
    printf("estop_check: ESTOP on the bus %s; e-stop behaviour's zero command %s%.3f s after the press "
           "(%ld other commands before it); drives stopped %s%.3f s after\n",
           estop_at ? "seen" : "never seen", cmd_at ? "" : "never, ", cmd_s, moving_after,
           drives_at ? "" : "never, ", drives_s);
    int ok = cmd_s > 0 && cmd_s <= max_s && drives_s > 0 && drives_s <= max_s;
    return ok ? 0 : 1;
}
