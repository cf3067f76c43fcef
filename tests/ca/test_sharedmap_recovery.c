/* test_sharedmap_recovery: a marie-ca sharedmap started on a damaged log keeps serving its
 * intact records and says what it lost (warning event, heartbeat counter); with strict_log it
 * refuses to start; state files never land in the working directory by default. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include "ca/sharedmap.h"
#include "ca/sharedmap_client.h"
#include "core/component.h"
#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_pose2d_t.h"
#include "lcmtypes/marie_switch_select_t.h"
#include "tests/ca/ca_test.h"
#include "tests/fails.h"

static char dir[256], path[300], state_arg[400];
static pid_t pids[2];       /* stopped by teardown too, so a failed case leaves no process */

static int setup(void **state)
{
    cat_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/map.log", dir);
    snprintf(state_arg, sizeof state_arg, "state_file=%s", path);
    return 0;
}

static int teardown(void **state)
{
    for (int i = 0; i < 2; i++)
        if (pids[i] > 0 && cat_alive(pids[i]))
            cat_stop(pids[i], SIGKILL);
    pids[0] = pids[1] = 0;
    cat_rmdir(dir);
    return 0;
}

/* A 20-key log with one byte of record 5 (key k04) flipped; returns the record's offset. */
static size_t damaged_log(void)
{
    sharedmap_t *sm = sharedmap_open(path, NULL);
    assert_non_null(sm);
    size_t rec5 = 0;
    for (int i = 0; i < 20; i++) {
        struct stat st;
        assert_int_equal(stat(path, &st), 0);
        if (i == 4)
            rec5 = (size_t)st.st_size;
        char key[16];
        uint8_t buf[64];
        marie_pose2d_t p = { .x = i };
        snprintf(key, sizeof key, "k%02d", i);
        int n = marie_pose2d_t_encode(buf, 0, sizeof buf, &p);
        assert_int_equal(sharedmap_set(sm, key, "marie.pose2d_t", buf, (size_t)n, i), 0);
    }
    sharedmap_close(sm);
    int fd = open(path, O_RDWR);
    uint8_t b;
    assert_int_equal(pread(fd, &b, 1, (off_t)rec5 + 40), 1);
    b ^= 0x10;
    assert_int_equal(pwrite(fd, &b, 1, (off_t)rec5 + 40), 1);
    close(fd);
    return rec5;
}

static int count_prefix(const char *d, const char *prefix)
{
    DIR *dd = opendir(d);
    assert_non_null(dd);
    struct dirent *e;
    int n = 0;
    while ((e = readdir(dd)))
        n += e->d_name[0] != '.' && strncmp(e->d_name, prefix, strlen(prefix)) == 0;
    closedir(dd);
    return n;
}

typedef struct {
    int8_t severity;
    char text[1024];
    int seen;
} damage_event_t;

static void on_event(const lcm_recv_buf_t *rbuf, const char *channel, const marie_event_t *ev, void *user)
{
    damage_event_t *d = user;
    if (strcmp(ev->kind, "sharedmap_log_damaged") == 0) {
        d->seen++;
        d->severity = ev->severity;
        snprintf(d->text, sizeof d->text, "%s", ev->text);
    }
}

static bool got_event(void *user) { return ((damage_event_t *)user)->seen > 0; }

static void test_damaged_log_is_recovered_and_reported(void **state)
{
    size_t rec5 = damaged_log();
    cat_bus_t *bus = cat_bus_create();
    damage_event_t ev = { 0 };
    marie_event_t_subscription_t *sub = marie_event_t_subscribe(cat_lcm(bus), MARIE_CH_EVENT, on_event, &ev);
    const char *args[] = { "sharedmap", "--name", "smr", "--param", state_arg, NULL };
    pid_t pid = pids[0] = cat_spawn(args);
    assert_true(cat_wait_running(bus, "smr", 5000));
    assert_true(cat_spin(bus, 5000, got_event, &ev));
    /* a warning that says how much was lost, where, and where the damaged file went */
    assert_int_equal(ev.severity, MARIE_EVENT_T_SEV_WARN);
    char where[64];
    snprintf(where, sizeof where, "at offset %zu+", rec5);
    assert_non_null(strstr(ev.text, "1 record ("));
    assert_non_null(strstr(ev.text, where));
    assert_non_null(strstr(ev.text, ".corrupt-"));
    int64_t seen = 0;
    assert_true(cat_wait_counter(bus, "smr", "log_records_skipped", 1, 5000, &seen));
    assert_int_equal(seen, 1);
    /* the 19 intact records are served, the damaged one is gone */
    sharedmap_client_t *cl = sharedmap_client_create(cat_lcm(bus), NULL, "t");
    marie_pose2d_t p;
    assert_int_equal(sharedmap_client_get(cl, "k19", &marie_type_pose2d_t, &p, 2000, NULL), 0);
    assert_true(p.x == 19);
    assert_int_equal(sharedmap_client_get(cl, "k05", &marie_type_pose2d_t, &p, 2000, NULL), 0);
    assert_fails(sharedmap_client_get(cl, "k04", &marie_type_pose2d_t, &p, 2000, NULL), ENOENT);
    char **keys;
    size_t n;
    assert_int_equal(sharedmap_client_list(cl, "", &keys, &n, 2000), 0);
    assert_int_equal(n, 19);
    sharedmap_client_free_keys(keys, n);
    assert_int_equal(count_prefix(dir, "map.log.corrupt-"), 1);
    sharedmap_client_destroy(cl);
    int st = cat_stop(pid, SIGTERM);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);
    marie_event_t_unsubscribe(cat_lcm(bus), sub);
    cat_bus_destroy(bus);
}

static void test_strict_log_refuses_to_start(void **state)
{
    damaged_log();
    struct stat before, after;
    assert_int_equal(stat(path, &before), 0);
    cat_bus_t *bus = cat_bus_create();
    const char *args[] = { "sharedmap", "--name", "sms", "--param", state_arg,
                           "--param", "strict_log=true", NULL };
    pid_t pid = pids[0] = cat_spawn(args);
    char reason[256] = "";
    assert_true(cat_wait_state(bus, "sms", MARIE_STATE_FAILED, 5000, reason, sizeof reason));
    assert_non_null(strstr(reason, "damaged"));
    /* the log is left exactly as it was */
    assert_int_equal(stat(path, &after), 0);
    assert_int_equal(after.st_size, before.st_size);
    assert_int_equal(after.st_ino, before.st_ino);
    assert_int_equal(count_prefix(dir, "map.log.corrupt-"), 0);
    cat_stop(pid, SIGTERM);
    cat_bus_destroy(bus);
}

/* With no state_file and no MARIE_STATE_DIR, nothing is written in the working directory
 * (a sharedmap.sharedmap.lock once appeared in a source tree this way). */
static void test_state_never_defaults_to_the_working_directory(void **state)
{
    char cwd[400], sdir[400], here[PATH_MAX], bdir[PATH_MAX];
    snprintf(cwd, sizeof cwd, "%s/cwd", dir);
    snprintf(sdir, sizeof sdir, "%s/state", dir);
    assert_int_equal(mkdir(cwd, 0755), 0);
    const char *b = getenv("B");
    assert_non_null(realpath(b && *b ? b : "build", bdir));
    assert_non_null(getcwd(here, sizeof here));
    char *saved_b = b ? strdup(b) : NULL, *saved_sd = getenv("MARIE_STATE_DIR") ? strdup(getenv("MARIE_STATE_DIR")) : NULL;
    setenv("B", bdir, 1);
    unsetenv("MARIE_STATE_DIR");
    setenv("STATE_DIRECTORY", sdir, 1);     /* as systemd's StateDirectory= would */
    assert_int_equal(chdir(cwd), 0);

    cat_bus_t *bus = cat_bus_create();
    const char *sm_args[] = { "sharedmap", "--name", "smw", NULL };
    const char *sw_args[] = { "switch", "--name", "sww", "--param", "output=CMD",
                              "--param", "inputs={a: CMD_A, b: CMD_B}", NULL };
    pid_t sm = pids[0] = cat_spawn(sm_args), sw = pids[1] = cat_spawn(sw_args);
    assert_true(cat_wait_running(bus, "smw", 5000));
    assert_true(cat_wait_running(bus, "sww", 5000));
    sharedmap_client_t *cl = sharedmap_client_create(cat_lcm(bus), NULL, "t");
    marie_pose2d_t p = { .x = 1 };
    assert_int_equal(sharedmap_client_set(cl, "k", &marie_type_pose2d_t, &p, 2000), 0);
    sharedmap_client_destroy(cl);
    /* a selection is persisted before it takes effect */
    char swfile[500];
    snprintf(swfile, sizeof swfile, "%s/sww.switch", sdir);
    marie_switch_select_t sel = { .request_id = 1, .requester = "t", .input = "b" };
    for (int i = 0; i < 30 && access(swfile, F_OK) != 0; i++) {
        marie_switch_select_t_publish(cat_lcm(bus), "CMD.SELECT", &sel);
        cat_spin(bus, 100, NULL, NULL);
    }
    cat_stop(sm, SIGTERM);
    cat_stop(sw, SIGTERM);
    cat_bus_destroy(bus);

    assert_int_equal(chdir(here), 0);
    unsetenv("STATE_DIRECTORY");
    if (saved_b)
        setenv("B", saved_b, 1);
    if (saved_sd)
        setenv("MARIE_STATE_DIR", saved_sd, 1);
    free(saved_b);
    free(saved_sd);
    assert_int_equal(count_prefix(cwd, ""), 0);
    assert_int_equal(count_prefix(sdir, "smw.sharedmap"), 2);    /* the log and its .lock */
    assert_int_equal(count_prefix(sdir, "sww.switch"), 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_damaged_log_is_recovered_and_reported, setup, teardown),
        cmocka_unit_test_setup_teardown(test_strict_log_refuses_to_start, setup, teardown),
        cmocka_unit_test_setup_teardown(test_state_never_defaults_to_the_working_directory, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
