/* test_sharedmap_durability: every write a SharedMap acknowledges is on disk before the
 * acknowledgement leaves: a preloaded shim (syncshim.c) traces the process's log writes,
 * syncs, renames and sent datagrams in order. SIGKILL keeps the page cache, so only this
 * ordering shows a missing fdatasync. */
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
#include "lcmtypes/marie_pose2d_t.h"
#include "tests/ca/ca_test.h"

#define WRITES 200

typedef struct {
    int writes, syncs, dir_syncs, renames, links, sends, sends_unsynced, closed_unsynced;
} trace_t;

static pid_t pid;           /* killed by teardown if the case fails before stopping it */

static int teardown(void **state)
{
    if (pid > 0 && cat_alive(pid))
        cat_stop(pid, SIGKILL);
    pid = 0;
    return 0;
}

static void read_trace(const char *path, trace_t *t)
{
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char line[160];
    memset(t, 0, sizeof *t);
    while (fgets(line, sizeof line, f)) {
        switch (line[0]) {
        case 'W': t->writes++; break;
        case 'S': t->syncs++; break;
        case 'D': t->dir_syncs++; break;
        case 'R': t->renames++; break;
        case 'L': t->links++; break;
        case 'C': t->closed_unsynced++; break;
        case 'N': line[1] == '!' ? t->sends_unsynced++ : t->sends++; break;
        }
    }
    fclose(f);
}

static void test_every_ack_follows_its_sync(void **state)
{
    char dir[256], state_arg[400], trace_path[400], shim[PATH_MAX], shim_rel[PATH_MAX];
    const char *b = getenv("B");
    snprintf(shim_rel, sizeof shim_rel, "%s/tests/libca_syncshim.so", b && *b ? b : "build");
    assert_non_null(realpath(shim_rel, shim));
    cat_tmpdir(dir, sizeof dir);
    snprintf(state_arg, sizeof state_arg, "state_file=%s/map.log", dir);
    snprintf(trace_path, sizeof trace_path, "%s.trace", dir);
    unlink(trace_path);

    cat_bus_t *bus = cat_bus_create();
    sharedmap_client_t *cl = sharedmap_client_create(cat_lcm(bus), NULL, "writer");
    /* only the SharedMap process runs with the shim */
    setenv("LD_PRELOAD", shim, 1);
    setenv("SYNCSHIM_DIR", dir, 1);
    setenv("SYNCSHIM_TRACE", trace_path, 1);
    /* SAN builds: the shim comes before the sanitizer's runtime */
    const char *asan = getenv("ASAN_OPTIONS");
    char *asan_old = asan ? strdup(asan) : NULL, asan_new[512];
    snprintf(asan_new, sizeof asan_new, "%s%sverify_asan_link_order=0", asan ? asan : "", asan && *asan ? ":" : "");
    setenv("ASAN_OPTIONS", asan_new, 1);
    const char *args[] = { "sharedmap", "--name", "smd", "--param", state_arg,
                           /* compact often: renames must be synced before the next ack too */
                           "--param", "compact_min_records=16", NULL };
    pid = cat_spawn(args);
    unsetenv("LD_PRELOAD");
    unsetenv("SYNCSHIM_DIR");
    unsetenv("SYNCSHIM_TRACE");
    if (asan_old)
        setenv("ASAN_OPTIONS", asan_old, 1);
    else
        unsetenv("ASAN_OPTIONS");
    free(asan_old);
    assert_true(cat_wait_running(bus, "smd", 5000));

    int acked = 0;
    for (int i = 0; i < WRITES; i++) {
        char key[32];
        snprintf(key, sizeof key, "k%02d", i % 20);
        marie_pose2d_t v = { .x = i };
        int rc = i % 10 == 9 ? sharedmap_client_delete(cl, key, 2000)
                             : sharedmap_client_set(cl, key, &marie_type_pose2d_t, &v, 2000);
        assert_true(rc == 0 || errno == ENOENT);
        acked += rc == 0;
    }
    int st = cat_stop(pid, SIGTERM);
    assert_true(WIFEXITED(st) && WEXITSTATUS(st) == 0);

    trace_t t;
    read_trace(trace_path, &t);
    printf("# %d acknowledged changes: %d log writes, %d syncs, %d renames, %d directory syncs, "
           "%d datagrams, %d sent before a sync\n", acked, t.writes, t.syncs, t.renames, t.dir_syncs,
           t.sends, t.sends_unsynced);
    /* the shim saw the log: a write and a sync per acknowledged change, and compactions */
    assert_true(acked > WRITES / 2);
    assert_true(t.writes >= acked);
    assert_true(t.syncs >= acked);
    assert_true(t.renames >= 1 && t.dir_syncs >= t.renames);
    assert_true(t.sends >= acked);
    /* no datagram (no reply) left while a write or a rename was still in the page cache */
    assert_int_equal(t.sends_unsynced, 0);
    assert_int_equal(t.closed_unsynced, 0);

    sharedmap_client_destroy(cl);
    cat_bus_destroy(bus);
    unlink(trace_path);
    cat_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_teardown(test_every_ack_follows_its_sync, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
