/* test_auth: order signing: good orders pass; unsigned, forged, replayed, stale and
 * far-future orders and unsafe key files are refused. */
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
#include "core/time.h"

#define S 1000000LL      /* one second in microseconds */

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

/* An order sent at `seq` microseconds of the sender's clock (utime the same). */
static marie_am_order_t make_order(int64_t seq)
{
    static char *targets[] = {"planner"};
    marie_am_order_t o = {
        .utime = seq, .sender = "ops@laptop", .seq = seq, .host = "*", .op = MARIE_AM_ORDER_T_OP_START,
        .ntargets = 1, .targets = targets, .arg = "", .system_path = "", .system_text = "",
    };
    return o;
}

/* A signed order with these times, checked by r. */
static marie_auth_result_t check_at(marie_auth_t *a, marie_replay_t *r, int64_t utime, int64_t seq)
{
    marie_am_order_t o = make_order(seq);
    o.utime = utime;
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    assert_int_equal(marie_auth_sign_order(a, &o, mac), 0);
    return marie_auth_check_order(a, r, &o);
}

static void test_signed_order_accepted_once(void **state)
{
    marie_auth_t *a = fresh_key("k1");
    marie_replay_t *r = marie_replay_create(NULL);
    int64_t t = marie_replay_epoch(r) + S;
    marie_am_order_t o = make_order(t + 100);
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    assert_int_equal(marie_auth_sign_order(a, &o, mac), 0);
    assert_int_equal(marie_auth_check_order(a, r, &o), MARIE_AUTH_OK);
    /* the very same order again is a replay */
    assert_int_equal(marie_auth_check_order(a, r, &o), MARIE_AUTH_REPLAYED);
    /* an older seq, properly signed, too */
    marie_am_order_t old = make_order(t + 99);
    marie_auth_sign_order(a, &old, mac);
    assert_int_equal(marie_auth_check_order(a, r, &old), MARIE_AUTH_REPLAYED);
    marie_am_order_t next = make_order(t + 101);
    marie_auth_sign_order(a, &next, mac);
    assert_int_equal(marie_auth_check_order(a, r, &next), MARIE_AUTH_OK);
    marie_replay_destroy(r);
    marie_auth_destroy(a);
}

static void test_unsigned_refused(void **state)
{
    marie_auth_t *a = fresh_key("k2");
    marie_replay_t *r = marie_replay_create(NULL);
    marie_am_order_t o = make_order(marie_wall_us() + S);
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
    errno = 0;
    assert_int_equal(marie_auth_keygen(p), -1);
    assert_int_equal(errno, EEXIST);
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
    int64_t t = marie_replay_epoch(r) + S;
    marie_am_order_t o = make_order(t);
    uint8_t mac[32];
    marie_auth_sign_order(a, &o, mac);
    assert_int_equal(marie_auth_check_order(a, r, &o), MARIE_AUTH_OK);
    marie_replay_destroy(r);
    r = marie_replay_create(p);
    assert_int_equal(marie_replay_last(r, "ops@laptop"), t);
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

/* The testers' cases: a receiver with a fresh state directory refuses a captured order 1000 s
 * old, orders dated 1970 or 2100, and a seq of INT64_MAX, and none of them moves the sender's
 * mark: the same sender's next real order is obeyed. */
static void test_window_refuses_old_and_far_orders(void **state)
{
    char p[128];
    key_path(p, sizeof p, "fresh-state");
    unlink(p);
    marie_auth_t *a = fresh_key("k8");
    marie_replay_t *r = marie_replay_create(p);
    int64_t now = marie_wall_us();
    const int64_t y2100 = 4102444800LL * S;
    assert_int_equal(check_at(a, r, now - 1000 * S, now - 1000 * S), MARIE_AUTH_STALE);
    assert_int_equal(check_at(a, r, 0, now + S), MARIE_AUTH_STALE);
    assert_int_equal(check_at(a, r, y2100, now + S), MARIE_AUTH_FUTURE);
    assert_int_equal(check_at(a, r, now + S, y2100), MARIE_AUTH_FUTURE);
    assert_int_equal(check_at(a, r, now + S, INT64_MAX), MARIE_AUTH_FUTURE);
    assert_int_equal(check_at(a, r, now + S, INT64_MIN), MARIE_AUTH_STALE);
    assert_int_equal(marie_replay_last(r, "ops@laptop"), 0);
    /* not locked out, and nothing far-future was written down */
    assert_int_equal(check_at(a, r, now + S, now + S), MARIE_AUTH_OK);
    marie_replay_destroy(r);
    r = marie_replay_create(p);
    assert_int_equal(marie_replay_last(r, "ops@laptop"), now + S);
    assert_int_equal(check_at(a, r, now + 2 * S, now + 2 * S), MARIE_AUTH_OK);
    marie_replay_destroy(r);
    marie_auth_destroy(a);
}

/* A file written by an older marie may hold a mark of INT64_MAX: it is dropped on load. */
static void test_far_future_mark_in_old_file_dropped(void **state)
{
    char p[128];
    key_path(p, sizeof p, "old-seq");
    FILE *f = fopen(p, "w");
    assert_non_null(f);
    fprintf(f, "9223372036854775807 ops@laptop\n");
    fclose(f);
    marie_auth_t *a = fresh_key("k9");
    marie_replay_t *r = marie_replay_create(p);
    assert_int_equal(marie_replay_last(r, "ops@laptop"), 0);
    int64_t now = marie_wall_us();
    assert_int_equal(check_at(a, r, now + S, now + S), MARIE_AUTH_OK);
    marie_replay_destroy(r);
    marie_auth_destroy(a);
}

/* A receiver created after an order was signed never obeys it, with or without a file: what a
 * restarted component or manager sees when a captured order is sent again. */
static void test_order_signed_before_receiver_started_refused(void **state)
{
    char p[128];
    key_path(p, sizeof p, "restart-seq");
    unlink(p);
    marie_auth_t *a = fresh_key("k10");
    marie_replay_t *before = marie_replay_create(p);
    marie_am_order_t o = make_order(marie_wall_us() + 1);
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    marie_auth_sign_order(a, &o, mac);
    assert_int_equal(marie_auth_check_order(a, before, &o), MARIE_AUTH_OK);
    marie_replay_destroy(before);
    usleep(2000);
    marie_replay_t *mem = marie_replay_create(NULL);
    assert_true(marie_replay_epoch(mem) > o.seq);
    assert_int_equal(marie_auth_check_order(a, mem, &o), MARIE_AUTH_REPLAYED);
    unlink(p);
    marie_replay_t *fresh = marie_replay_create(p);
    assert_int_equal(marie_auth_check_order(a, fresh, &o), MARIE_AUTH_REPLAYED);
    /* a lifecycle command the same */
    marie_lifecycle_command_t c = {.utime = o.seq, .request_id = 2, .sender = "marie-am@onboard1",
                                   .target = "planner", .command = 4, .seq = o.seq};
    marie_auth_sign_command(a, &c, mac);
    assert_int_equal(marie_auth_check_command(a, mem, &c), MARIE_AUTH_REPLAYED);
    c.utime = c.seq = marie_wall_us() + 1;
    marie_auth_sign_command(a, &c, mac);
    assert_int_equal(marie_auth_check_command(a, mem, &c), MARIE_AUTH_OK);
    marie_replay_destroy(mem);
    marie_replay_destroy(fresh);
    marie_auth_destroy(a);
}

/* Clocks that differ by less than the skew are fine either way once the receiver has run a
 * while; just beyond the window they are not. Window here: lifetime 1 s, skew 1 s. */
static void test_bounded_skew_accepted(void **state)
{
    marie_auth_t *a = fresh_key("k11");
    marie_replay_t *r = marie_replay_create_window(NULL, S, S);
    assert_non_null(r);
    assert_null(marie_replay_create_window(NULL, -1, S));
    usleep(2500000);          /* past the epoch: a lagging sender's orders are after it */
    int64_t now = marie_wall_us();
    assert_int_equal(check_at(a, r, now - 1500000, now - 1500000), MARIE_AUTH_OK);    /* 1.5 s behind */
    now = marie_wall_us();
    assert_int_equal(check_at(a, r, now + 500000, now + 500000), MARIE_AUTH_OK);      /* 0.5 s ahead */
    now = marie_wall_us();
    assert_int_equal(check_at(a, r, now - 2600000, now + 600000), MARIE_AUTH_STALE);  /* 2.6 s old */
    assert_int_equal(check_at(a, r, now + 1600000, now + 600000), MARIE_AUTH_FUTURE); /* 1.6 s ahead */
    marie_replay_destroy(r);
    /* the default window: 5 s of skew */
    r = marie_replay_create(NULL);
    now = marie_wall_us();
    assert_int_equal(check_at(a, r, now + 3 * S, now + 3 * S), MARIE_AUTH_OK);
    assert_int_equal(check_at(a, r, now + 7 * S, now + 7 * S), MARIE_AUTH_FUTURE);
    assert_int_equal(check_at(a, r, now - 20 * S, now - 20 * S), MARIE_AUTH_STALE);
    marie_replay_destroy(r);
    marie_auth_destroy(a);
}

/* A sender whose seq file holds a number no receiver would accept starts again from its clock. */
static void test_next_seq_recovers_from_far_future_file(void **state)
{
    char p[128];
    key_path(p, sizeof p, "poisoned-seq");
    FILE *f = fopen(p, "w");
    assert_non_null(f);
    fprintf(f, "9223372036854775806\n");
    fclose(f);
    int64_t s = marie_auth_next_seq(p);
    int64_t now = marie_wall_us();
    assert_true(s <= now && s > now - 10 * S);
    assert_true(marie_auth_next_seq(p) > s);
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
        cmocka_unit_test(test_window_refuses_old_and_far_orders),
        cmocka_unit_test(test_far_future_mark_in_old_file_dropped),
        cmocka_unit_test(test_order_signed_before_receiver_started_refused),
        cmocka_unit_test(test_bounded_skew_accepted),
        cmocka_unit_test(test_next_seq_recovers_from_far_future_file),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
