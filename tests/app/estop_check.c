/* estop_check: reads a demo log and measures the software e-stop chain after the button went
 * down (the first pressed ESTOP on the bus: the simulator's, or marie-gpio's on the robot): the
 * behaviours' zero MOTOR_COMMAND from the e-stop behaviour and the drives' WHEEL_ENCODERS
 * reporting them stopped (ESTOP or DISABLED).
 *   estop_check LOG MAX_S     exit 0 when both happen after the press, each within MAX_S
 * Every event is timed on one clock: the simulated time as the log saw it (the last
 * MARIE_CLOCK recorded before it), so the order of the log is the order of the times. The
 * components' own stamps are their views of that clock, a clock period or two apart, and would
 * put a reaction before its cause. The demo's request on SIM_ESTOP is not the press: at ~10x
 * real time its delivery alone can take tenths of simulated seconds. */
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
    int64_t now = 0, requested = 0, pressed = 0, cmd_at = 0, drives_at = 0;
    long moving_after = 0;
    lcm_eventlog_event_t *ev;
    while ((ev = lcm_eventlog_read_next_event(log)) != NULL && !(cmd_at && drives_at)) {
        marie_estop_t e;
        marie_motor_command_t m;
        marie_wheel_encoders_t w;
        marie_sim_clock_t clk;
        if (decode(ev, "MARIE_CLOCK", &marie_type_sim_clock_t, &clk) == 0) {
            now = clk.utime > now ? clk.utime : now;
            marie_type_sim_clock_t.decode_cleanup(&clk);
        }
        if (!requested && decode(ev, "SIM_ESTOP", &marie_type_estop_t, &e) == 0) {
            if (e.pressed)
                requested = now;
            marie_type_estop_t.decode_cleanup(&e);
        } else if (!pressed && decode(ev, "ESTOP", &marie_type_estop_t, &e) == 0) {
            if (e.pressed)
                pressed = now;
            marie_type_estop_t.decode_cleanup(&e);
        } else if (pressed && !cmd_at && decode(ev, "MOTOR_COMMAND", &marie_type_motor_command_t, &m) == 0) {
            if (m.v == 0 && m.omega == 0 && m.source && strcmp(m.source, "estop") == 0)
                cmd_at = now;
            else
                moving_after++;
            marie_type_motor_command_t.decode_cleanup(&m);
        } else if (pressed && !drives_at && decode(ev, "WHEEL_ENCODERS", &marie_type_wheel_encoders_t, &w) == 0) {
            if (w.status == MARIE_WHEEL_ENCODERS_T_STATUS_ESTOP || w.status == MARIE_WHEEL_ENCODERS_T_STATUS_DISABLED)
                drives_at = now;
            marie_type_wheel_encoders_t.decode_cleanup(&w);
        }
        lcm_eventlog_free_event(ev);
    }
    if (ev)
        lcm_eventlog_free_event(ev);
    lcm_eventlog_destroy(log);
    if (!pressed) {
        printf("estop_check: no pressed ESTOP on the bus in %s\n", argv[1]);
        return 1;
    }
    if (requested)
        printf("estop_check: requested on SIM_ESTOP at %.3f s, the button down (ESTOP) at %.3f s\n", requested / 1e6,
               pressed / 1e6);
    double cmd_s = (cmd_at - pressed) / 1e6, drives_s = (drives_at - pressed) / 1e6;
    printf("estop_check: e-stop behaviour's zero command %s%.3f s after the press (%ld other commands before it); "
           "drives stopped %s%.3f s after\n",
           cmd_at ? "" : "never, ", cmd_at ? cmd_s : -1, moving_after, drives_at ? "" : "never, ",
           drives_at ? drives_s : -1);
    int ok = cmd_at && drives_at && cmd_s <= max_s && drives_s <= max_s;
    return ok ? 0 : 1;
}
