/* test_auth: order signing: good orders pass; unsigned, forged, replayed orders and unsafe
 * key files are refused. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <cmocka.h>

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "core/auth.h"

static char dir[64];

static int setup(void **state)
{
    snprintf(dir, sizeof dir, "/tmp/marie-test-auth-XXXXXX");
    return mkdtemp(dir) ? 0 : -1;
}

static int teardown(void **state)
{
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    return system(cmd);
}

static void key_path(char *buf, size_t len, const char *name)
{
    snprintf(buf, len, "%s/%s", dir, name);
}

static marie_auth_t *fresh_key(const char *name)
{
    char p[128];
    key_path(p, sizeof p, name);
    unlink(p);
    assert_int_equal(marie_auth_keygen(p), 0);
    char err[256];
    marie_auth_t *a = marie_auth_load(p, err, sizeof err);
    assert_non_null(a);
    return a;
}

static marie_am_order_t make_order(int64_t seq)
{
    static char *targets[] = {"planner"};
    marie_am_order_t o = {
        .utime = 1, .sender = "ops@laptop", .seq = seq, .host = "*", .op = MARIE_AM_ORDER_T_OP_START,
        .ntargets = 1, .targets = targets, .arg = "", .system_path = "", .system_text = "",
    };
    return o;
}

static void test_signed_order_accepted_once(void **state)
{
    marie_auth_t *a = fresh_key("k1");
    marie_replay_t *r = marie_replay_create(NULL);
    marie_am_order_t o = make_order(100);
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    assert_int_equal(marie_auth_sign_order(a, &o, mac), 0);
    assert_int_equal(marie_auth_check_order(a, r, &o), MARIE_AUTH_OK);
    /* the very same order again is a replay */
    assert_int_equal(marie_auth_check_order(a, r, &o), MARIE_AUTH_REPLAYED);
    /* an older seq, properly signed, too */
    marie_am_order_t old = make_order(99);
    marie_auth_sign_order(a, &old, mac);
    assert_int_equal(marie_auth_check_order(a, r, &old), MARIE_AUTH_REPLAYED);
    marie_am_order_t next = make_order(101);
    marie_auth_sign_order(a, &next, mac);
    assert_int_equal(marie_auth_check_order(a, r, &next), MARIE_AUTH_OK);
    marie_replay_destroy(r);
    marie_auth_destroy(a);
}

static void test_unsigned_refused(void **state)
{
    marie_auth_t *a = fresh_key("k2");
    marie_replay_t *r = marie_replay_create(NULL);
    marie_am_order_t o = make_order(5);
    assert_int_equal(marie_auth_check_order(a, r, &o), MARIE_AUTH_UNSIGNED);
    /* and a receiver without a key refuses signed orders too */
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    marie_auth_sign_order(a, &o, mac);
    assert_int_equal(marie_auth_check_order(NULL, r, &o), MARIE_AUTH_NOKEY);
    /* refusals do not advance the replay table */
    assert_int_equal(marie_replay_last(r, "ops@laptop"), 0);
    marie_replay_destroy(r);
    marie_auth_destroy(a);
}

static void test_forged_refused(void **state)
{
    marie_auth_t *a = fresh_key("k3");
    marie_auth_t *other = fresh_key("k4");
    marie_replay_t *r = marie_replay_create(NULL);
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    /* signed with another key */
    marie_am_order_t o = make_order(10);
    marie_auth_sign_order(other, &o, mac);
    assert_int_equal(marie_auth_check_order(a, r, &o), MARIE_AUTH_FORGED);
    /* a field changed after signing: every field is covered */
    marie_am_order_t p = make_order(11);
    marie_auth_sign_order(a, &p, mac);
    p.op = MARIE_AM_ORDER_T_OP_STOP;
    assert_int_equal(marie_auth_check_order(a, r, &p), MARIE_AUTH_FORGED);
    p = make_order(12);
    marie_auth_sign_order(a, &p, mac);
    p.seq = 13;
    assert_int_equal(marie_auth_check_order(a, r, &p), MARIE_AUTH_FORGED);
    p = make_order(14);
    marie_auth_sign_order(a, &p, mac);
    mac[0] ^= 1;
    assert_int_equal(marie_auth_check_order(a, r, &p), MARIE_AUTH_FORGED);
    p.mac_len = 16;
    assert_int_equal(marie_auth_check_order(a, r, &p), MARIE_AUTH_FORGED);
    marie_replay_destroy(r);
    marie_auth_destroy(a);
    marie_auth_destroy(other);
}

static void test_key_file_modes(void **state)
{
    char p[128], err[256];
    key_path(p, sizeof p, "k5");
    unlink(p);
    assert_int_equal(marie_auth_keygen(p), 0);
    struct stat st;
    assert_int_equal(stat(p, &st), 0);
    assert_int_equal(st.st_mode & 0777, 0600);
    /* keygen never overwrites */
    assert_int_equal(marie_auth_keygen(p), -EEXIST);
    chmod(p, 0644);
    assert_null(marie_auth_load(p, err, sizeof err));
    assert_int_equal(errno, EACCES);
    assert_non_null(strstr(err, "0644"));
    chmod(p, 0640);
    assert_null(marie_auth_load(p, err, sizeof err));
    chmod(p, 0400);
    marie_auth_t *a = marie_auth_load(p, err, sizeof err);
    assert_non_null(a);
    marie_auth_destroy(a);
    /* missing file, bad content */
    key_path(p, sizeof p, "missing");
    assert_null(marie_auth_load(p, err, sizeof err));
    key_path(p, sizeof p, "bad");
    int fd = open(p, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    assert_true(write(fd, "not a key\n", 10) == 10);
    close(fd);
    assert_null(marie_auth_load(p, err, sizeof err));
    assert_int_equal(errno, EINVAL);
}

static void test_same_key_hex_and_raw(void **state)
{
    uint8_t key[32];
    for (int i = 0; i < 32; i++)
        key[i] = (uint8_t)(i * 7 + 1);
    char p[128], hex[80];
    key_path(p, sizeof p, "hex");
    for (int i = 0; i < 32; i++)
        sprintf(hex + 2 * i, "%02X", key[i]);
    strcat(hex, "\n");
    int fd = open(p, O_WRONLY | O_CREAT | O_TRUNC, 0600);
    assert_true(write(fd, hex, strlen(hex)) == (ssize_t)strlen(hex));
    close(fd);
    marie_auth_t *a = marie_auth_load(p, NULL, 0);
    marie_auth_t *b = marie_auth_from_key(key);
    assert_non_null(a);
    marie_am_order_t o = make_order(1);
    uint8_t mac[32];
    marie_auth_sign_order(b, &o, mac);
    assert_int_equal(marie_auth_check_order(a, NULL, &o), MARIE_AUTH_OK);
    marie_auth_destroy(a);
    marie_auth_destroy(b);
}

static void test_replay_table_survives_restart(void **state)
{
    char p[128];
    key_path(p, sizeof p, "seq");
    marie_auth_t *a = fresh_key("k6");
    marie_replay_t *r = marie_replay_create(p);
    marie_am_order_t o = make_order(500);
    uint8_t mac[32];
    marie_auth_sign_order(a, &o, mac);
    assert_int_equal(marie_auth_check_order(a, r, &o), MARIE_AUTH_OK);
    marie_replay_destroy(r);
    r = marie_replay_create(p);
    assert_int_equal(marie_replay_last(r, "ops@laptop"), 500);
    assert_int_equal(marie_auth_check_order(a, r, &o), MARIE_AUTH_REPLAYED);
    marie_replay_destroy(r);
    marie_auth_destroy(a);
}

static void test_lifecycle_commands_signed(void **state)
{
    marie_auth_t *a = fresh_key("k7");
    marie_lifecycle_command_t c = {.utime = 1, .request_id = 2, .sender = "marie-am@onboard1",
                                   .target = "planner", .command = 4, .seq = 9};
    uint8_t mac[32];
    assert_int_equal(marie_auth_check_command(a, NULL, &c), MARIE_AUTH_UNSIGNED);
    marie_auth_sign_command(a, &c, mac);
    assert_int_equal(marie_auth_check_command(a, NULL, &c), MARIE_AUTH_OK);
    c.command = 8;
    assert_int_equal(marie_auth_check_command(a, NULL, &c), MARIE_AUTH_FORGED);
    marie_auth_destroy(a);
}

static void test_next_seq_strictly_increases(void **state)
{
    char p[128];
    key_path(p, sizeof p, "myseq");
    int64_t last = 0;
    for (int i = 0; i < 200; i++) {
        int64_t s = marie_auth_next_seq(p);
        assert_true(s > last);
        last = s;
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_signed_order_accepted_once),
        cmocka_unit_test(test_unsigned_refused),
        cmocka_unit_test(test_forged_refused),
        cmocka_unit_test(test_key_file_modes),
        cmocka_unit_test(test_same_key_hex_and_raw),
        cmocka_unit_test(test_replay_table_survives_restart),
        cmocka_unit_test(test_lifecycle_commands_signed),
        cmocka_unit_test(test_next_seq_strictly_increases),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
