/* test_am_wire: the payload check (core/typeinfo) accepts every message the managers exchange,
 * as encoded by liblcm, and refuses truncated ones and lying lengths (which crash liblcm's decoder). */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <stdlib.h>
#include <string.h>

#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_heartbeat_t.h"
#include "proto/am_proto.h"
#include "core/typeinfo.h"

#define ENCODE(type, msg, buf, n) do {                              \
        n = type##_encoded_size(msg);                               \
        buf = malloc((size_t)n);                                    \
        assert_int_equal(type##_encode(buf, 0, n, msg), n);         \
    } while (0)

static void expect_all_truncations_refused(const uint8_t *buf, int n, const char *type)
{
    const marie_typeinfo_t *layout = marie_typeinfo_find(type);
    assert_non_null(layout);
    assert_int_equal(marie_typeinfo_check(layout, buf, (size_t)n), 0);
    /* a trailing byte is refused too */
    uint8_t *longer = malloc((size_t)n + 1);
    memcpy(longer, buf, (size_t)n);
    longer[n] = 0;
    assert_int_not_equal(marie_typeinfo_check(layout, longer, (size_t)n + 1), 0);
    free(longer);
    for (int cut = 0; cut < n; cut++)
        assert_int_not_equal(marie_typeinfo_check(layout, buf, (size_t)cut), 0);
}

static void test_order(void **state)
{
    char *targets[] = {"a", "group-b", ""};
    uint8_t mac[32] = {1, 2, 3};
    marie_am_order_t o = {.utime = 5, .sender = "ops@laptop", .seq = 9, .host = "*", .op = 3, .ntargets = 3,
                          .targets = targets, .arg = "x", .system_path = "/p", .system_text = "system: t\n",
                          .mac_len = 32, .mac = mac};
    uint8_t *buf;
    int n;
    ENCODE(marie_am_order_t, &o, buf, n);
    expect_all_truncations_refused(buf, n, "am_order_t");
    /* a negative string length (sender's length field sits after fingerprint and utime) */
    buf[16] = 0xff;
    assert_int_not_equal(marie_typeinfo_check(marie_typeinfo_find("am_order_t"), buf, (size_t)n), 0);
    free(buf);
}

static void test_status_with_components(void **state)
{
    marie_am_component_status_t cs[2] = {
        {.name = "a", .group = "", .state = "running", .comp_state = 2, .pid = 10, .config_hash = "abc",
         .limits = "memory 64M (cgroup)", .limit_breaches = 2},
        {.name = "b", .group = "g", .state = "stopped", .comp_state = -1, .config_hash = "", .limits = ""},
    };
    char *hosts[] = {"h1", "h2"};
    marie_am_status_t st = {.host = "h1", .system = "s", .system_hash = "x", .profile = "", .nhosts = 2,
                            .hosts = hosts, .ncomponents = 2, .components = cs, .balance_leader = "h1",
                            .balance_term = 3, .balance_last = ""};
    uint8_t *buf;
    int n;
    ENCODE(marie_am_status_t, &st, buf, n);
    expect_all_truncations_refused(buf, n, "am_status_t");
    free(buf);
}

static void test_reply_request_log_event_heartbeat(void **state)
{
    char *hosts[] = {"h1"};
    marie_am_reply_t r = {.host = "h1", .sender = "s", .reason = "ok", .ok = 1, .nhosts = 1, .hosts = hosts};
    uint8_t *buf;
    int n;
    ENCODE(marie_am_reply_t, &r, buf, n);
    expect_all_truncations_refused(buf, n, "am_reply_t");
    free(buf);
    marie_am_status_request_t rq = {.utime = 1, .sender = "ops@laptop", .host = "*"};
    ENCODE(marie_am_status_request_t, &rq, buf, n);
    expect_all_truncations_refused(buf, n, "am_status_request_t");
    free(buf);
    marie_log_line_t l = {.host = "h", .component = "c", .text = "hello"};
    ENCODE(marie_log_line_t, &l, buf, n);
    expect_all_truncations_refused(buf, n, "log_line_t");
    free(buf);
    marie_event_t e = {.source = "s", .kind = "k", .text = "t"};
    ENCODE(marie_event_t, &e, buf, n);
    expect_all_truncations_refused(buf, n, "event_t");
    free(buf);
    marie_counter_t counters[2] = {{.name = "x", .value = 1}, {.name = "yy", .value = 2}};
    marie_heartbeat_t hb = {.component = "c", .host = "h", .reason = "", .ncounters = 2, .counters = counters};
    ENCODE(marie_heartbeat_t, &hb, buf, n);
    expect_all_truncations_refused(buf, n, "heartbeat_t");
    free(buf);
}

static void test_huge_count_refused(void **state)
{
    static uint8_t none[1];
    marie_am_order_t o = {.sender = "s", .host = "*", .arg = "", .system_path = "", .system_text = "", .mac = none};
    uint8_t *buf;
    int n;
    ENCODE(marie_am_order_t, &o, buf, n);
    /* ntargets follows fingerprint(8) utime(8) sender(4+2) seq(8) host(4+2) op(1) */
    int at = 8 + 8 + 6 + 8 + 6 + 1;
    buf[at] = 0x7f;
    assert_int_not_equal(marie_typeinfo_check(marie_typeinfo_find("am_order_t"), buf, (size_t)n), 0);
    buf[at] = 0x80;
    assert_int_not_equal(marie_typeinfo_check(marie_typeinfo_find("am_order_t"), buf, (size_t)n), 0);
    free(buf);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_order),
        cmocka_unit_test(test_status_with_components),
        cmocka_unit_test(test_reply_request_log_event_heartbeat),
        cmocka_unit_test(test_huge_count_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
