/* test_lifecycle: the example components driven through all eight management functions over
 * LCM, as separate processes: replies, refusals, heartbeats, malformed orders, SIGTERM, and
 * signed orders captured before a restart. */
#include <errno.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmocka.h>
#include <lcm/lcm.h>

#include "core/auth.h"
#include "core/component.h"
#include "tests/udp.h"

typedef struct {
    lcm_t *lcm;
    /* latest heartbeat of the component under test */
    marie_heartbeat_t hb;
    int have_hb;
    int64_t hb_count;
    /* latest reply */
    marie_lifecycle_reply_t reply;
    int have_reply;
    int64_t example_msgs;
    marie_heartbeat_t_subscription_t *hb_sub;
    marie_lifecycle_reply_t_subscription_t *reply_sub;
    marie_counter_t_subscription_t *example_sub;
    int64_t last_example_value;
    const char *who;
} bus_t;

static void on_hb(const lcm_recv_buf_t *rb, const char *ch, const marie_heartbeat_t *m, void *user)
{
    bus_t *b = user;
    if (strcmp(m->component, b->who) != 0)
        return;
    if (b->have_hb)
        marie_heartbeat_t_decode_cleanup(&b->hb);
    marie_heartbeat_t_decode(rb->data, 0, (int)rb->data_size, &b->hb);
    b->have_hb = 1;
    b->hb_count++;
}

static void on_reply(const lcm_recv_buf_t *rb, const char *ch, const marie_lifecycle_reply_t *m, void *user)
{
    bus_t *b = user;
    if (strcmp(m->component, b->who) != 0)
        return;
    if (b->have_reply)
        marie_lifecycle_reply_t_decode_cleanup(&b->reply);
    marie_lifecycle_reply_t_decode(rb->data, 0, (int)rb->data_size, &b->reply);
    b->have_reply = 1;
}

static void on_example(const lcm_recv_buf_t *rb, const char *ch, const marie_counter_t *m, void *user)
{
    bus_t *b = user;
    b->example_msgs++;
    b->last_example_value = m->value;
}

static void pump(bus_t *b, int ms)
{
    int64_t end = marie_mono_us() + ms * 1000LL;
    while (marie_mono_us() < end)
        lcm_handle_timeout(b->lcm, 10);
}

/* Waits until the component's heartbeat shows `state` (5 s at most). */
static int wait_state(bus_t *b, int state)
{
    int64_t end = marie_mono_us() + 5000000;
    while (marie_mono_us() < end) {
        if (b->have_hb && b->hb.state == state)
            return 1;
        lcm_handle_timeout(b->lcm, 20);
    }
    return 0;
}

static int64_t next_id = 100;

/* Waits for the reply to request `id` (-1: any reply). 1 accepted, 0 refused, -1 no reply in 5 s. */
static int wait_reply(bus_t *b, int64_t id)
{
    int64_t end = marie_mono_us() + 5000000;
    while (marie_mono_us() < end) {
        lcm_handle_timeout(b->lcm, 20);
        if (b->have_reply && (id < 0 || b->reply.request_id == id))
            return b->reply.ok ? 1 : 0;
    }
    return -1;
}

/* Publishes a command as it is (an attacker replays captured bytes so) and waits for the reply. */
static int publish_order(bus_t *b, const marie_lifecycle_command_t *m)
{
    b->have_reply = 0;
    marie_lifecycle_command_t_publish(b->lcm, MARIE_CH_LIFECYCLE, m);
    return wait_reply(b, m->request_id);
}

/* Sends a command, signed with `a` unless it is NULL, and waits for the reply to it. */
static int send_order(bus_t *b, const char *target, marie_auth_t *a, int64_t seq, int cmd)
{
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    marie_lifecycle_command_t m = {
        .utime = marie_wall_us(), .request_id = ++next_id, .sender = "test", .target = (char *)target,
        .command = (int8_t)cmd, .seq = seq,
    };
    if (a)
        marie_auth_sign_command(a, &m, mac);
    return publish_order(b, &m);
}

static int order(bus_t *b, const char *target, int cmd)
{
    return send_order(b, target, NULL, 0, cmd);
}

/* The value of a named counter in the last heartbeat, -1 when absent. */
static int64_t counter_of(const bus_t *b, const char *name)
{
    for (int i = 0; i < b->hb.ncounters; i++)
        if (strcmp(b->hb.counters[i].name, name) == 0)
            return b->hb.counters[i].value;
    return -1;
}

static void expect_clean_exit(pid_t pid)
{
    int status;
    assert_int_equal(waitpid(pid, &status, 0), pid);
    assert_true(WIFEXITED(status));
    assert_int_equal(WEXITSTATUS(status), 0);
}

/* Runs $B/bin/PROG with the given arguments (NULL-terminated). */
static pid_t spawn_argv(const char *prog, char *const *args)
{
    pid_t pid = fork();
    if (pid == 0) {
        char path[256];
        snprintf(path, sizeof path, "%s/bin/%s", getenv("B") ? getenv("B") : "build", prog);
        execv(path, args);
        _exit(127);
    }
    return pid;
}

static pid_t spawn(const char *prog, const char *name, const char *extra)
{
    char *args[] = {(char *)prog, "--name", (char *)name, "--hold", (char *)extra, NULL};
    return spawn_argv(prog, args);
}

static void bus_open(bus_t *b, const char *who)
{
    memset(b, 0, sizeof *b);
    b->who = who;
    b->lcm = lcm_create(NULL);
    assert_non_null(b->lcm);
    b->hb_sub = marie_heartbeat_t_subscribe(b->lcm, MARIE_CH_HEARTBEAT, on_hb, b);
    b->reply_sub = marie_lifecycle_reply_t_subscribe(b->lcm, MARIE_CH_LIFECYCLE_REPLY, on_reply, b);
    b->example_sub = marie_counter_t_subscribe(b->lcm, "EXAMPLE", on_example, b);
}

static void bus_close(bus_t *b)
{
    if (b->have_hb)
        marie_heartbeat_t_decode_cleanup(&b->hb);
    if (b->have_reply)
        marie_lifecycle_reply_t_decode_cleanup(&b->reply);
    marie_heartbeat_t_unsubscribe(b->lcm, b->hb_sub);
    marie_lifecycle_reply_t_unsubscribe(b->lcm, b->reply_sub);
    marie_counter_t_unsubscribe(b->lcm, b->example_sub);
    lcm_destroy(b->lcm);
}

static void eight_management_functions_over_lcm(void **state)
{
    bus_t b;
    bus_open(&b, "prod");
    pid_t pid = spawn("marie-example-producer", "prod", "--param=rate_hz=50");
    assert_true(wait_state(&b, MARIE_STATE_CREATED));
    assert_int_equal(b.hb.pid, pid);
    assert_string_equal(b.hb.component, "prod");

    /* start before init is refused, with a reason, and the state does not change */
    assert_int_equal(order(&b, "prod", MARIE_CMD_START), 0);
    assert_non_null(strstr(b.reply.reason, "start refused in state created"));
    assert_int_equal(b.reply.state, MARIE_STATE_CREATED);

    assert_int_equal(order(&b, "prod", MARIE_CMD_INIT), 1);
    assert_int_equal(b.reply.state, MARIE_STATE_READY);
    pump(&b, 200);
    assert_int_equal(b.example_msgs, 0);  /* ready is not running: nothing published */

    assert_int_equal(order(&b, "prod", MARIE_CMD_START), 1);
    assert_int_equal(b.reply.state, MARIE_STATE_RUNNING);
    pump(&b, 300);
    assert_true(b.example_msgs > 0);

    assert_int_equal(order(&b, "prod", MARIE_CMD_PAUSE), 1);
    assert_int_equal(b.reply.state, MARIE_STATE_PAUSED);
    pump(&b, 50);
    int64_t during_pause = b.example_msgs;
    pump(&b, 300);
    assert_int_equal(b.example_msgs, during_pause);
    assert_int_equal(order(&b, "prod", MARIE_CMD_PAUSE), 0);  /* already paused */

    assert_int_equal(order(&b, "prod", MARIE_CMD_RESUME), 1);
    pump(&b, 300);
    assert_true(b.example_msgs > during_pause);

    assert_int_equal(order(&b, "prod", MARIE_CMD_STOP), 1);
    assert_int_equal(b.reply.state, MARIE_STATE_READY);
    assert_int_equal(order(&b, "prod", MARIE_CMD_RESTART), 1);
    assert_int_equal(b.reply.state, MARIE_STATE_RUNNING);

    assert_int_equal(order(&b, "prod", MARIE_CMD_ABORT), 1);
    assert_int_equal(b.reply.state, MARIE_STATE_FAILED);
    assert_true(wait_state(&b, MARIE_STATE_FAILED));
    assert_string_equal(b.hb.reason, "abort");
    assert_int_equal(order(&b, "prod", MARIE_CMD_RESUME), 0);  /* failed cannot resume */
    /* restart from failed initialises again */
    assert_int_equal(order(&b, "prod", MARIE_CMD_RESTART), 1);
    assert_int_equal(b.reply.state, MARIE_STATE_RUNNING);

    /* the heartbeat carries the counters */
    pump(&b, 1200);
    assert_true(b.hb.msgs_out > 0);
    assert_true(b.hb.uptime_us > 0);
    assert_true(b.hb.seq > 1);

    assert_int_equal(order(&b, "prod", MARIE_CMD_QUIT), 1);
    assert_int_equal(b.reply.state, MARIE_STATE_EXITED);
    expect_clean_exit(pid);
    assert_true(wait_state(&b, MARIE_STATE_EXITED));
    bus_close(&b);
}

static void malformed_orders_are_answered_counted_and_survived(void **state)
{
    bus_t b;
    bus_open(&b, "prod2");
    pid_t pid = spawn("marie-example-producer", "prod2", "--param=rate_hz=50");
    assert_true(wait_state(&b, MARIE_STATE_CREATED));
    /* Garbage on the lifecycle channel: a reply saying so, and a bad_input count. */
    static const unsigned char junk[] = {0xde, 0xad, 0xbe, 0xef, 1, 2, 3};
    b.have_reply = 0;
    lcm_publish(b.lcm, MARIE_CH_LIFECYCLE, junk, sizeof junk);
    assert_int_equal(wait_reply(&b, -1), 0);
    assert_string_equal(b.reply.reason, "malformed lifecycle command");
    /* An unknown command number is refused. */
    assert_int_equal(order(&b, "prod2", 42), 0);
    assert_string_equal(b.reply.reason, "unknown command");
    /* Orders for another component are ignored by this one. */
    assert_int_equal(order(&b, "someone-else", MARIE_CMD_INIT), -1);
    /* A datagram on the bus that is not an LCM message (a fragment of a message of 0 fragments):
     * counted by the component's bus reader. */
    int fd = test_udp_socket();
    static const unsigned char frag[] = {'L', 'C', '0', '3', 0, 0, 0, 1, 0, 0, 0, 9, 0, 0, 0, 0, 0, 0, 0, 0,
                                         'M', 'A', 'R', 'I', 'E', 0, 'x'};
    assert_int_equal(test_udp_send(fd, frag, sizeof frag), (ssize_t)sizeof frag);
    close(fd);
    /* Still alive and counting. */
    assert_int_equal(order(&b, "prod2", MARIE_CMD_INIT), 1);
    pump(&b, 1100);
    assert_true(b.hb.bad_input >= 3);
    assert_true(counter_of(&b, "bad_lifecycle") >= 2);
    assert_int_equal(counter_of(&b, "bus_malformed"), 1);
    /* SIGTERM is quit: exit status 0 and a last heartbeat saying exited. */
    kill(pid, SIGTERM);
    expect_clean_exit(pid);
    assert_true(wait_state(&b, MARIE_STATE_EXITED));
    bus_close(&b);
}

static void event_port_holds_notes_until_running_and_counts_losses(void **state)
{
    bus_t b;
    bus_open(&b, "cons");
    pid_t pid = spawn("marie-example-consumer", "cons", NULL);
    assert_true(wait_state(&b, MARIE_STATE_CREATED));
    assert_int_equal(order(&b, "cons", MARIE_CMD_INIT), 1);
    /* 300 notes while ready: the event queue holds 256 and counts the rest as lost. */
    for (int i = 0; i < 300; i++) {
        marie_event_t ev = {.utime = marie_wall_us(), .source = "test", .seq = i + 1, .kind = "note", .text = ""};
        marie_event_t_publish(b.lcm, "EXAMPLE_NOTES", &ev);
        if (i % 50 == 49)
            pump(&b, 20);
    }
    pump(&b, 200);
    assert_int_equal(order(&b, "cons", MARIE_CMD_START), 1);
    pump(&b, 1200);
    assert_int_equal(counter_of(&b, "notes"), 256);
    assert_int_equal(counter_of(&b, "events_lost"), 44);
    assert_int_equal(b.hb.drops, 44);
    assert_int_equal(order(&b, "cons", MARIE_CMD_QUIT), 1);
    waitpid(pid, NULL, 0);
    bus_close(&b);
}

static void group_orders_reach_every_member(void **state)
{
    /* A producer and a consumer in one group of a system file; one order to the group moves both. */
    bus_t a, c;
    bus_open(&a, "producer");
    bus_open(&c, "consumer");
    char *sys = "--system=tests/data/core/system_ok.yaml";
    char *pargs[] = {"p", sys, "--name", "producer", "--hold", NULL};
    char *cargs[] = {"c", sys, "--name", "consumer", "--hold", NULL};
    pid_t p1 = spawn_argv("marie-example-producer", pargs);
    pid_t p2 = spawn_argv("marie-example-consumer", cargs);
    assert_true(wait_state(&a, MARIE_STATE_CREATED));
    assert_true(wait_state(&c, MARIE_STATE_CREATED));
    assert_true(order(&a, "demo", MARIE_CMD_INIT) >= 0);
    assert_true(wait_state(&a, MARIE_STATE_READY));
    assert_true(wait_state(&c, MARIE_STATE_READY));
    order(&a, "*", MARIE_CMD_QUIT);
    expect_clean_exit(p1);
    expect_clean_exit(p2);
    bus_close(&a);
    bus_close(&c);
}

static void with_a_key_only_signed_fresh_orders_are_obeyed(void **state)
{
    char key[] = "/tmp/marie-test-key-XXXXXX", other[] = "/tmp/marie-test-key2-XXXXXX";
    close(mkstemp(key));
    close(mkstemp(other));
    unlink(key);   /* keygen refuses to overwrite a file */
    unlink(other);
    assert_int_equal(marie_auth_keygen(key), 0);
    assert_int_equal(marie_auth_keygen(other), 0);
    char err[256];
    marie_auth_t *good = marie_auth_load(key, err, sizeof err), *bad = marie_auth_load(other, err, sizeof err);
    assert_non_null(good);
    assert_non_null(bad);
    bus_t b;
    bus_open(&b, "guarded");
    setenv("MARIE_KEY", key, 1);
    pid_t pid = spawn("marie-example-producer", "guarded", "--param=rate_hz=20");
    unsetenv("MARIE_KEY");
    assert_true(wait_state(&b, MARIE_STATE_CREATED));
    assert_int_equal(send_order(&b, "guarded", NULL, 0, MARIE_CMD_INIT), 0);
    assert_string_equal(b.reply.reason, "order refused: unsigned");
    int64_t seq = marie_wall_us();
    assert_int_equal(send_order(&b, "guarded", bad, seq, MARIE_CMD_INIT), 0);
    assert_string_equal(b.reply.reason, "order refused: forged");
    assert_int_equal(b.reply.state, MARIE_STATE_CREATED);
    assert_int_equal(send_order(&b, "guarded", good, seq, MARIE_CMD_INIT), 1);
    assert_int_equal(b.reply.state, MARIE_STATE_READY);
    /* The same sequence number again is a replay, even correctly signed. */
    assert_int_equal(send_order(&b, "guarded", good, seq, MARIE_CMD_START), 0);
    assert_string_equal(b.reply.reason, "order refused: replayed");
    /* An order signed 1000 s ago, or dated 2100, is refused whatever its seq. */
    assert_int_equal(send_order(&b, "guarded", good, marie_wall_us() - 1000000000LL, MARIE_CMD_START), 0);
    assert_string_equal(b.reply.reason, "order refused: stale");
    assert_int_equal(send_order(&b, "guarded", good, INT64_MAX, MARIE_CMD_START), 0);
    assert_string_equal(b.reply.reason, "order refused: future");
    assert_int_equal(b.reply.state, MARIE_STATE_READY);
    assert_int_equal(send_order(&b, "guarded", good, marie_wall_us(), MARIE_CMD_QUIT), 1);
    expect_clean_exit(pid);
    marie_auth_destroy(good);
    marie_auth_destroy(bad);
    unlink(key);
    unlink(other);
    bus_close(&b);
}

/* Runs the producer as `name` with the key, and brings it to running with signed orders. */
static pid_t spawn_guarded_running(bus_t *b, const char *name, const char *key, marie_auth_t *a)
{
    setenv("MARIE_KEY", key, 1);
    pid_t pid = spawn("marie-example-producer", name, "--param=rate_hz=20");
    unsetenv("MARIE_KEY");
    if (b->have_hb)
        marie_heartbeat_t_decode_cleanup(&b->hb);
    b->have_hb = 0;
    assert_true(wait_state(b, MARIE_STATE_CREATED));
    assert_int_equal(b->hb.pid, pid);
    assert_int_equal(send_order(b, name, a, marie_wall_us(), MARIE_CMD_INIT), 1);
    assert_int_equal(send_order(b, name, a, marie_wall_us(), MARIE_CMD_START), 1);
    assert_int_equal(b->reply.state, MARIE_STATE_RUNNING);
    return pid;
}

static void captured_order_refused_after_component_restart(void **state)
{
    char key[] = "/tmp/marie-test-key3-XXXXXX";
    close(mkstemp(key));
    unlink(key);
    assert_int_equal(marie_auth_keygen(key), 0);
    marie_auth_t *a = marie_auth_load(key, NULL, 0);
    assert_non_null(a);
    bus_t b;
    bus_open(&b, "restarted");
    pid_t pid = spawn_guarded_running(&b, "restarted", key, a);
    /* the manager's signed pause, as anyone on the LAN can capture it */
    uint8_t mac[MARIE_AUTH_MAC_LEN];
    marie_lifecycle_command_t pause = {
        .utime = marie_wall_us(), .request_id = ++next_id, .sender = "marie-am@test", .target = "restarted",
        .command = MARIE_CMD_PAUSE, .seq = marie_wall_us(),
    };
    marie_auth_sign_command(a, &pause, mac);
    assert_int_equal(publish_order(&b, &pause), 1);
    assert_int_equal(b.reply.state, MARIE_STATE_PAUSED);
    assert_int_equal(publish_order(&b, &pause), 0);   /* at once again: a replay */
    assert_string_equal(b.reply.reason, "order refused: replayed");
    /* the component restarts (its manager's doing, or a crash) and runs again */
    kill(pid, SIGTERM);
    expect_clean_exit(pid);
    pid = spawn_guarded_running(&b, "restarted", key, a);
    /* the captured pause, still well within the order lifetime, is not obeyed */
    assert_int_equal(publish_order(&b, &pause), 0);
    assert_string_equal(b.reply.reason, "order refused: replayed");
    assert_int_equal(b.reply.state, MARIE_STATE_RUNNING);
    int64_t end = marie_mono_us() + 5000000;       /* the next heartbeat counts the refusal */
    while (counter_of(&b, "refused_orders") < 1 && marie_mono_us() < end)
        lcm_handle_timeout(b.lcm, 20);
    assert_true(counter_of(&b, "refused_orders") >= 1);
    assert_int_equal(b.hb.state, MARIE_STATE_RUNNING);
    /* while a fresh pause from the same sender is */
    pause.utime = pause.seq = marie_wall_us();
    pause.request_id = ++next_id;
    marie_auth_sign_command(a, &pause, mac);
    assert_int_equal(publish_order(&b, &pause), 1);
    assert_int_equal(b.reply.state, MARIE_STATE_PAUSED);
    assert_int_equal(send_order(&b, "restarted", a, marie_wall_us(), MARIE_CMD_QUIT), 1);
    expect_clean_exit(pid);
    marie_auth_destroy(a);
    unlink(key);
    bus_close(&b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(eight_management_functions_over_lcm),
        cmocka_unit_test(malformed_orders_are_answered_counted_and_survived),
        cmocka_unit_test(event_port_holds_notes_until_running_and_counts_losses),
        cmocka_unit_test(group_orders_reach_every_member),
        cmocka_unit_test(with_a_key_only_signed_fresh_orders_are_obeyed),
        cmocka_unit_test(captured_order_refused_after_component_restart),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
