/* test_cia402: every state of the statusword and every transition of the drive state machine,
 * from both ends: the device's transitions and the master's controlword choice. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <cmocka.h>

#include "hw/drives/cia402.h"

static void statusword_decodes_every_state(void **state)
{
    for (int s = CIA402_NOT_READY; s <= CIA402_FAULT; s++) {
        uint16_t sw = cia402_sw_from_state((cia402_state_t)s);
        assert_int_equal(cia402_state_from_sw(sw), s);
        /* bits outside the state masks (warning, remote, target reached, speed 0) do not matter */
        assert_int_equal(cia402_state_from_sw(sw | 0x1680), s);
    }
    assert_int_equal(cia402_state_from_sw(0x0250), CIA402_SWITCH_ON_DISABLED);  /* typical drive */
    assert_int_equal(cia402_state_from_sw(0x0237), CIA402_OPERATION_ENABLED);
    assert_int_equal(cia402_state_from_sw(0x0218), CIA402_FAULT);
    assert_int_equal(cia402_state_from_sw(0x0001), CIA402_UNKNOWN);
    assert_string_equal(cia402_state_name(CIA402_QUICK_STOP_ACTIVE), "quick stop active");
}

static cia402_state_t apply(cia402_state_t s, uint16_t cw, uint16_t prev)
{
    return cia402_transition(s, cia402_decode_controlword(s, cw, prev));
}

static void device_transitions(void **state)
{
    /* numbers are CiA 402's transition numbers */
    assert_int_equal(apply(CIA402_SWITCH_ON_DISABLED, 0x06, 0), CIA402_READY_TO_SWITCH_ON);     /* 2 */
    assert_int_equal(apply(CIA402_READY_TO_SWITCH_ON, 0x07, 6), CIA402_SWITCHED_ON);            /* 3 */
    assert_int_equal(apply(CIA402_SWITCHED_ON, 0x0F, 7), CIA402_OPERATION_ENABLED);             /* 4 */
    assert_int_equal(apply(CIA402_OPERATION_ENABLED, 0x07, 0xF), CIA402_SWITCHED_ON);           /* 5 */
    assert_int_equal(apply(CIA402_SWITCHED_ON, 0x06, 7), CIA402_READY_TO_SWITCH_ON);            /* 6 */
    assert_int_equal(apply(CIA402_READY_TO_SWITCH_ON, 0x00, 6), CIA402_SWITCH_ON_DISABLED);     /* 7 */
    assert_int_equal(apply(CIA402_READY_TO_SWITCH_ON, 0x02, 6), CIA402_SWITCH_ON_DISABLED);     /* 7 (quick stop) */
    assert_int_equal(apply(CIA402_OPERATION_ENABLED, 0x06, 0xF), CIA402_READY_TO_SWITCH_ON);    /* 8 */
    assert_int_equal(apply(CIA402_OPERATION_ENABLED, 0x00, 0xF), CIA402_SWITCH_ON_DISABLED);    /* 9 */
    assert_int_equal(apply(CIA402_SWITCHED_ON, 0x00, 7), CIA402_SWITCH_ON_DISABLED);            /* 10 */
    assert_int_equal(apply(CIA402_SWITCHED_ON, 0x02, 7), CIA402_SWITCH_ON_DISABLED);            /* 10 (quick stop) */
    assert_int_equal(apply(CIA402_OPERATION_ENABLED, 0x02, 0xF), CIA402_QUICK_STOP_ACTIVE);     /* 11 */
    assert_int_equal(apply(CIA402_QUICK_STOP_ACTIVE, 0x00, 2), CIA402_SWITCH_ON_DISABLED);      /* 12 */
    assert_int_equal(apply(CIA402_FAULT, 0x80, 0x00), CIA402_SWITCH_ON_DISABLED);               /* 15 */
    assert_int_equal(apply(CIA402_QUICK_STOP_ACTIVE, 0x0F, 2), CIA402_OPERATION_ENABLED);       /* 16 */
    assert_int_equal(apply(CIA402_READY_TO_SWITCH_ON, 0x0F, 6), CIA402_OPERATION_ENABLED);      /* 3+4 */
    /* fault reset needs a rising edge: held high does nothing */
    assert_int_equal(apply(CIA402_FAULT, 0x80, 0x80), CIA402_FAULT);
    /* commands that do not apply leave the state */
    assert_int_equal(apply(CIA402_FAULT, 0x0F, 0), CIA402_FAULT);
    assert_int_equal(apply(CIA402_SWITCH_ON_DISABLED, 0x0F, 0), CIA402_SWITCH_ON_DISABLED);
    assert_int_equal(apply(CIA402_SWITCH_ON_DISABLED, 0x07, 0), CIA402_SWITCH_ON_DISABLED);
    assert_int_equal(apply(CIA402_NOT_READY, 0x06, 0), CIA402_NOT_READY);
    assert_int_equal(apply(CIA402_FAULT_REACTION_ACTIVE, 0x80, 0), CIA402_FAULT_REACTION_ACTIVE);
    assert_true(cia402_state_powered(CIA402_OPERATION_ENABLED));
    assert_false(cia402_state_powered(CIA402_SWITCHED_ON));
}

/* Drive a simulated device with the master's controlwords until it settles. */
static cia402_state_t walk(cia402_state_t s, cia402_want_t want, int *steps)
{
    uint16_t prev = 0, devprev = 0;
    for (*steps = 0; *steps < 10; (*steps)++) {
        uint16_t cw = cia402_next_controlword(s, want, prev, true);
        cia402_state_t ns = cia402_transition(s, cia402_decode_controlword(s, cw, devprev));
        devprev = cw;
        prev = cw;
        if (ns == s && cw == prev && !(cw & 0x80) && *steps > 0) {
            cia402_state_t again = cia402_transition(s, cia402_decode_controlword(s, cw, devprev));
            if (again == s)
                break;
        }
        s = ns;
    }
    return s;
}

static void master_reaches_every_goal_from_every_state(void **state)
{
    cia402_state_t from[] = { CIA402_SWITCH_ON_DISABLED, CIA402_READY_TO_SWITCH_ON, CIA402_SWITCHED_ON,
                              CIA402_OPERATION_ENABLED, CIA402_QUICK_STOP_ACTIVE, CIA402_FAULT };
    for (size_t i = 0; i < sizeof from / sizeof from[0]; i++) {
        int steps;
        assert_int_equal(walk(from[i], CIA402_WANT_ENABLED, &steps), CIA402_OPERATION_ENABLED);
        assert_int_equal(walk(from[i], CIA402_WANT_DISABLED, &steps), CIA402_SWITCH_ON_DISABLED);
        cia402_state_t q = walk(from[i], CIA402_WANT_QUICK_STOP, &steps);
        /* quick stop: a powered drive stops in quick stop active, others go to disabled */
        if (from[i] == CIA402_OPERATION_ENABLED || from[i] == CIA402_QUICK_STOP_ACTIVE)
            assert_int_equal(q, CIA402_QUICK_STOP_ACTIVE);
        else
            assert_int_equal(q, CIA402_SWITCH_ON_DISABLED);
    }
    /* from fault: reset edge (0x80 after a low), then shutdown, switch on, enable */
    assert_int_equal(cia402_next_controlword(CIA402_FAULT, CIA402_WANT_ENABLED, 0x0F, true), 0x80);
    assert_int_equal(cia402_next_controlword(CIA402_FAULT, CIA402_WANT_ENABLED, 0x80, true), 0x00);
    assert_int_equal(cia402_next_controlword(CIA402_FAULT, CIA402_WANT_ENABLED, 0x00, false), 0x00);
    assert_int_equal(cia402_next_controlword(CIA402_SWITCH_ON_DISABLED, CIA402_WANT_ENABLED, 0x80, true), 0x06);
    assert_int_equal(cia402_next_controlword(CIA402_FAULT_REACTION_ACTIVE, CIA402_WANT_ENABLED, 0, true), 0x00);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(statusword_decodes_every_state),
        cmocka_unit_test(device_transitions),
        cmocka_unit_test(master_reaches_every_goal_from_every_state),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
