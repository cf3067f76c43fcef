/* test_sharedmap_crash: a writer sets keys while the SharedMap process is killed with SIGKILL
 * at random moments and restarted; every acknowledged write must still be there. SIGKILL
 * keeps the page cache, so the second case plays a power loss: a preloaded shim
 * (syncshim.c, SYNCSHIM_CACHE) holds every write until its fsync/fdatasync, and what was
 * not synced dies with the process. */
#include <errno.h>
#include <limits.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>

#include "ca/sharedmap_client.h"
#include "core/time.h"
#include "lcmtypes/marie_pose2d_t.h"
#include "tests/ca/ca_test.h"

#define ROUNDS 30
#define MAX_WRITES 100000

static cat_bus_t *bus;
static sharedmap_client_t *cl;
static char dir[256], state_arg[400];
static int power_loss;
static pid_t current;       /* the running SharedMap, killed by teardown if a case fails */

static pid_t spawn(const char *const *args)
{
    if (!power_loss)
        return cat_spawn(args);
    char rel[PATH_MAX], shim[PATH_MAX];
    const char *b = getenv("B");
    snprintf(rel, sizeof rel, "%s/tests/libca_syncshim.so", b && *b ? b : "build");
    assert_non_null(realpath(rel, shim));
    const char *asan = getenv("ASAN_OPTIONS");
    char *asan_old = asan ? strdup(asan) : NULL, asan_new[512];
    snprintf(asan_new, sizeof asan_new, "%s%sverify_asan_link_order=0", asan ? asan : "", asan && *asan ? ":" : "");
    setenv("ASAN_OPTIONS", asan_new, 1);
    setenv("LD_PRELOAD", shim, 1);
    setenv("SYNCSHIM_DIR", dir, 1);
    setenv("SYNCSHIM_CACHE", "1", 1);
    pid_t pid = cat_spawn(args);
    unsetenv("LD_PRELOAD");
    unsetenv("SYNCSHIM_DIR");
    unsetenv("SYNCSHIM_CACHE");
    if (asan_old)
        setenv("ASAN_OPTIONS", asan_old, 1);
    else
        unsetenv("ASAN_OPTIONS");
    free(asan_old);
    return pid;
}

static pid_t start(void)
{
    const char *args[] = { "sharedmap", "--name", "smc", "--param", state_arg,
                           "--param", "snapshot_channel=none",
                           /* compact often, so kills also land in compactions */
                           "--param", "compact_min_records=64", NULL };
    pid_t pid = current = spawn(args);
    /* up when it answers */
    marie_pose2d_t p;
    int rc = -1;
    errno = ETIMEDOUT;
    for (int i = 0; i < 50 && rc < 0 && errno == ETIMEDOUT; i++)
        rc = sharedmap_client_get(cl, "counter", &marie_type_pose2d_t, &p, 100, NULL);
    assert_true(rc == 0 || errno == ENOENT);
    if (rc == 0)
        marie_pose2d_t_decode_cleanup(&p);
    return pid;
}

/* Kill `pid` with SIGKILL after a random delay, from another process so the writer is
 * mid-request when it happens. */
static pid_t killer(pid_t pid, int delay_us)
{
    pid_t k = fork();
    if (k == 0) {
        usleep((useconds_t)delay_us);
        kill(pid, SIGKILL);
        _exit(0);
    }
    return k;
}

static struct { int round, i; double x; } acked[MAX_WRITES];

static void run(int rounds)
{
    bus = cat_bus_create();
    cl = sharedmap_client_create(cat_lcm(bus), NULL, "writer");
    cat_tmpdir(dir, sizeof dir);
    snprintf(state_arg, sizeof state_arg, "state_file=%s/map.log", dir);
    srand((unsigned)getpid());
    int nacked = 0, unknown = 0, in_compaction = 0;
    double counter_acked = 0, counter_sent = 0;
    int64_t t0 = marie_mono_us();

    for (int round = 0; round < rounds; round++) {
        pid_t pid = start();
        /* every acknowledged write so far is there, and the counter is not older than the
         * last acknowledged value (nor newer than the last sent one) */
        marie_pose2d_t p;
        if (counter_acked > 0) {
            assert_int_equal(sharedmap_client_get(cl, "counter", &marie_type_pose2d_t, &p, 1000, NULL), 0);
            assert_true(p.x >= counter_acked && p.x <= counter_sent);
        }
        char **keys;
        size_t nkeys;
        assert_int_equal(sharedmap_client_list(cl, "", &keys, &nkeys, 2000), 0);
        int present = 0;
        for (int a = 0, k = 0; a < nacked; a++) {
            char key[64];
            snprintf(key, sizeof key, "r%02d/k%05d", acked[a].round, acked[a].i);
            while (k < (int)nkeys && strcmp(keys[k], key) < 0)
                k++;
            present += k < (int)nkeys && strcmp(keys[k], key) == 0;
        }
        sharedmap_client_free_keys(keys, nkeys);
        assert_int_equal(present, nacked);

        pid_t k = killer(pid, 20000 + rand() % 300000);
        for (int i = 0; nacked < MAX_WRITES; i++) {
            char key[64];
            snprintf(key, sizeof key, "r%02d/k%05d", round, i);
            marie_pose2d_t v = { .x = round * 100000 + i };
            int rc;
            if (i % 4 == 0) {
                rc = sharedmap_client_set(cl, key, &marie_type_pose2d_t, &v, 150);
                if (rc == 0)
                    acked[nacked++] = (typeof(acked[0])){ round, i, v.x };
            } else {
                counter_sent = v.x;
                rc = sharedmap_client_set(cl, "counter", &marie_type_pose2d_t, &v, 150);
                if (rc == 0)
                    counter_acked = v.x;
            }
            if (rc < 0 && errno == ETIMEDOUT) {
                unknown++;
                break;
            }
            assert_int_equal(rc, 0);
        }
        waitpid(k, NULL, 0);
        int st;
        waitpid(pid, &st, 0);
        assert_true(WIFSIGNALED(st) && WTERMSIG(st) == SIGKILL);
        /* a leftover temporary file: the kill landed in a compaction */
        char tmp[400];
        snprintf(tmp, sizeof tmp, "%s/map.log.tmp", dir);
        if (access(tmp, F_OK) == 0) {
            in_compaction++;
            unlink(tmp);
        }
    }

    /* last restart: check every acknowledged value itself */
    pid_t pid = start();
    for (int a = 0; a < nacked; a++) {
        char key[64];
        snprintf(key, sizeof key, "r%02d/k%05d", acked[a].round, acked[a].i);
        marie_pose2d_t p;
        assert_int_equal(sharedmap_client_get(cl, key, &marie_type_pose2d_t, &p, 1000, NULL), 0);
        assert_true(p.x == acked[a].x);
    }
    cat_stop(pid, SIGTERM);
    printf("# %s: %d rounds, %d acknowledged writes kept, %d writes cut by a kill, %d kills during a "
           "compaction, %.1f s\n", power_loss ? "power loss" : "SIGKILL", rounds, nacked, unknown,
           in_compaction, (marie_mono_us() - t0) / 1e6);
    assert_true(nacked > rounds);
    sharedmap_client_destroy(cl);
    cat_bus_destroy(bus);
    cat_rmdir(dir);
}

static int teardown(void **state)
{
    if (current > 0 && cat_alive(current))
        cat_stop(current, SIGKILL);
    current = 0;
    power_loss = 0;
    return 0;
}

static void test_acknowledged_writes_survive_sigkill(void **state)
{
    power_loss = 0;
    run(ROUNDS);
}

static void test_acknowledged_writes_survive_power_loss(void **state)
{
    power_loss = 1;
    run(ROUNDS / 2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_acknowledged_writes_survive_sigkill, teardown),
        cmocka_unit_test_teardown(test_acknowledged_writes_survive_power_loss, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
