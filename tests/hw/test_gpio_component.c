/* test_gpio_component: marie-gpio on a machine without the configured GPIO chip stays up as
 * failed and says why in its heartbeat (the manager decides about restarts). */
#include <poll.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <cmocka.h>
#include <lcm/lcm.h>

#include "lcmtypes/marie_heartbeat_t.h"

typedef struct {
    int state;
    char reason[256];
    int beats;
} seen_t;

static void on_hb(const lcm_recv_buf_t *rb, const char *ch, const marie_heartbeat_t *m, void *user)
{
    seen_t *s = user;
    if (strcmp(m->component, "estop") != 0)
        return;
    s->beats++;
    s->state = m->state;
    snprintf(s->reason, sizeof s->reason, "%s", m->reason ? m->reason : "");
}

static int64_t mono_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

static void test_missing_chip_fails_with_reason(void **state)
{
    const char *b = getenv("B") ? getenv("B") : "build";
    char prog[256];
    snprintf(prog, sizeof prog, "%s/bin/marie-gpio", b);
    lcm_t *lcm = lcm_create(NULL);
    assert_non_null(lcm);
    seen_t s = { .state = -1 };
    marie_heartbeat_t_subscription_t *sub = marie_heartbeat_t_subscribe(lcm, "MARIE_HEARTBEAT", on_hb, &s);
    pid_t pid = fork();
    if (pid == 0) {
        execl(prog, prog, "--name", "estop", "--param", "chip=/dev/no-such-gpiochip", NULL);
        _exit(127);
    }
    int64_t end = mono_ms() + 10000;
    while (mono_ms() < end && !(s.state == 4 && s.beats >= 2)) {
        struct pollfd p = { .fd = lcm_get_fileno(lcm), .events = POLLIN };
        if (poll(&p, 1, 50) > 0)
            lcm_handle(lcm);
    }
    /* Still alive: a failed component keeps reporting until told to quit. */
    assert_int_equal(waitpid(pid, NULL, WNOHANG), 0);
    kill(pid, SIGTERM);
    int st = 0;
    waitpid(pid, &st, 0);
    marie_heartbeat_t_unsubscribe(lcm, sub);
    lcm_destroy(lcm);
    print_message("state %d reason '%s'\n", s.state, s.reason);
    assert_int_equal(s.state, 4);       /* failed */
    assert_non_null(strstr(s.reason, "/dev/no-such-gpiochip"));
    assert_true(WIFEXITED(st));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_missing_chip_fails_with_reason),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
