/* test_sharedmap_damage: a SharedMap log hit by byte flips, zeroed ranges and cut-outs keeps
 * every record that was not touched; the damaged file is kept aside, the loss counted and
 * located; strict mode refuses; old-format logs are still read. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "ca/sharedmap.h"
#include "ca/sharedmap_log.h"
#include "lcmtypes/marie_event_t.h"
#include "lcmtypes/marie_pose2d_t.h"
#include "tests/ca/sharedmap_damage.h"
#include "tests/fails.h"

#define ROUNDS 300
#define NKEYS 24

static char dir[256], path[300];

static int setup(void **state)
{
    snprintf(dir, sizeof dir, "/tmp/marie-test-smd-XXXXXX");
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/map.log", dir);
    return 0;
}

static int teardown(void **state)
{
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    return system(cmd);
}

static uint64_t rng = 88172645463325252ull;     /* fixed seed: every run sees the same damage */
static uint32_t rnd(uint32_t n)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (uint32_t)(rng % n);
}

static void log_random(smd_log_t *l, int nrec)
{
    smd_init(l);
    for (int i = 0; i < nrec; i++) {
        char key[16];
        uint8_t data[SMD_MAXDATA];
        snprintf(key, sizeof key, "key%02u", rnd(NKEYS));
        size_t len = 8 + rnd(80);
        for (size_t k = 0; k < len; k++)
            data[k] = (uint8_t)rnd(256);
        smd_add(l, rnd(6) == 0 ? SHAREDMAP_LOG_DEL : SHAREDMAP_LOG_SET, key, data, len);
    }
}

static void write_file(const char *p, const void *buf, size_t len)
{
    int fd = open(p, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    assert_true(fd >= 0);
    assert_true(write(fd, buf, len) == (ssize_t)len);
    close(fd);
}

static size_t read_file(const char *p, uint8_t *buf, size_t cap)
{
    int fd = open(p, O_RDONLY);
    assert_true(fd >= 0);
    ssize_t n = read(fd, buf, cap);
    close(fd);
    assert_true(n >= 0);
    return (size_t)n;
}

/* A place after the magic, and a stretch of 1..300 bytes. */
static size_t somewhere(size_t len) { return SHAREDMAP_LOG_MAGIC_LEN + rnd((uint32_t)(len - SHAREDMAP_LOG_MAGIC_LEN)); }
static size_t some_bytes(void) { return 1 + rnd(300); }

static void assert_map_is(const sharedmap_t *sm, const smd_log_t *l)
{
    char why[200] = "";
    if (smd_check_map(sm, l, why, sizeof why) < 0)
        fail_msg("%s", why);
}

/* The files kept aside in dir (NAME.corrupt-*); the first one's name goes to first. */
static int kept_aside(char *first, size_t cap)
{
    DIR *d = opendir(dir);
    struct dirent *e;
    int n = 0;
    while ((e = readdir(d))) {
        if (strncmp(e->d_name, "map.log.corrupt-", 16) == 0) {
            if (n++ == 0)
                snprintf(first, cap, "%s/%s", dir, e->d_name);
        }
    }
    closedir(d);
    return n;
}

static void clean_dir(void)
{
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -f %s/map.log*", dir);
    assert_int_equal(system(cmd), 0);
}

/* ---- the cases ---- */

static smd_log_t lg;
static uint8_t img[sizeof lg.img], back[sizeof lg.img];

static size_t file_size(const char *p)
{
    struct stat st;
    assert_int_equal(stat(p, &st), 0);
    return (size_t)st.st_size;
}

/* The case of the report: one byte of record 2 of a 300-key log written by a SharedMap.
 * Before, the map started empty and the file was cut to 8 bytes. */
static void test_one_byte_in_record_2_loses_record_2_only(void **state)
{
    sharedmap_t *sm = sharedmap_open(path, NULL);
    assert_non_null(sm);
    size_t rec2 = 0, rec150 = 0;
    for (int i = 0; i < 300; i++) {
        char key[16];
        uint8_t buf[64];
        marie_pose2d_t p = { .x = i };
        snprintf(key, sizeof key, "k%03d", i);
        if (i == 1)
            rec2 = file_size(path);
        if (i == 150)
            rec150 = file_size(path);
        int n = marie_pose2d_t_encode(buf, 0, sizeof buf, &p);
        assert_int_equal(sharedmap_set(sm, key, "marie.pose2d_t", buf, (size_t)n, i), 0);
    }
    sharedmap_close(sm);
    static uint8_t big[300 * 200];
    size_t len = read_file(path, big, sizeof big);
    big[rec2 + 30] ^= 0x01;
    write_file(path, big, len);

    sm = sharedmap_open(path, NULL);
    assert_non_null(sm);
    assert_int_equal(sharedmap_size(sm), 299);
    assert_fails(sharedmap_get(sm, "k001", NULL), ENOENT);
    assert_int_equal(sharedmap_get(sm, "k299", NULL), 0);
    const sharedmap_replay_t *rep = sharedmap_load_report(sm);
    assert_int_equal(rep->records_skipped, 1);
    assert_int_equal(rep->nranges, 1);
    assert_int_equal(rep->ranges[0].off, (int64_t)rec2);
    assert_int_equal(sharedmap_stats(sm)->records_skipped, 1);
    /* the damaged file is kept as it was */
    char aside[600];
    assert_int_equal(kept_aside(aside, sizeof aside), 1);
    assert_string_equal(sharedmap_kept_aside(sm), aside);
    static uint8_t got[sizeof big];
    assert_int_equal(read_file(aside, got, sizeof got), len);
    assert_memory_equal(got, big, len);
    sharedmap_close(sm);

    /* the log itself is clean again: nothing more lost, nothing more kept aside */
    sm = sharedmap_open(path, NULL);
    assert_int_equal(sharedmap_size(sm), 299);
    assert_int_equal(sharedmap_load_report(sm)->nranges, 0);
    assert_null(sharedmap_kept_aside(sm));
    assert_int_equal(kept_aside(aside, sizeof aside), 1);
    sharedmap_close(sm);

    /* 40 zeroed bytes in the middle lose the records they hit, not the second half */
    len = read_file(path, big, sizeof big);
    memset(big + rec150 + 10, 0, 40);
    write_file(path, big, len);
    sm = sharedmap_open(path, NULL);
    assert_true(sharedmap_size(sm) >= 297);
    assert_int_equal(sharedmap_get(sm, "k299", NULL), 0);
    assert_int_equal(sharedmap_load_report(sm)->records_skipped, 299 - (int64_t)sharedmap_size(sm));
    sharedmap_close(sm);
}

static void test_random_damage_keeps_every_untouched_record(void **state)
{
    int rounds_damaged = 0, rounds_tail = 0, rounds_exact = 0;
    int64_t lost = 0;
    for (int round = 0; round < ROUNDS; round++) {
        clean_dir();
        log_random(&lg, 20 + (int)rnd(SMD_MAXREC - 20));
        memcpy(img, lg.img, lg.len);
        size_t len = lg.len;
        int kinds = 1 + (int)rnd(3);
        for (int k = 0; k < kinds; k++) {
            switch (rnd(3)) {
            case 0: img[somewhere(len)] ^= (uint8_t)(1 + rnd(255)); break;
            case 1: smd_zero(img, len, somewhere(len), some_bytes()); break;
            default: len = smd_cut(&lg, img, len, somewhere(len), some_bytes()); break;
            }
        }
        int touched = smd_mark_touched(&lg, img, len);
        int last_touched = lg.r[lg.n - 1].touched;
        write_file(path, img, len);

        sharedmap_t *sm = sharedmap_open(path, NULL);
        assert_non_null(sm);
        assert_map_is(sm, &lg);
        const sharedmap_replay_t *rep = sharedmap_load_report(sm);
        char aside[600] = "";
        int naside = kept_aside(aside, sizeof aside);
        if (touched == 0) {
            assert_int_equal(rep->nranges, 0);
            assert_int_equal(naside, 0);
        } else if (!last_touched) {
            /* damage between intact records: exactly the touched ones are counted */
            assert_int_equal(rep->records_skipped, touched);
            assert_true(rep->nranges >= 1);
            rounds_exact++;
        } else {
            /* damage up to the end may look like the torn write of a crash */
            assert_true(rep->records_skipped <= touched);
            assert_true(rep->nranges >= 1 || rep->torn_bytes > 0);
            rounds_tail++;
        }
        assert_int_equal(sharedmap_stats(sm)->records_skipped, rep->records_skipped);
        if (rep->nranges > 0) {
            /* kept aside byte for byte, and the log rewritten without the damage */
            rounds_damaged++;
            lost += rep->records_skipped;
            assert_int_equal(naside, 1);
            assert_int_equal(read_file(aside, back, sizeof back), len);
            assert_memory_equal(back, img, len);
            sharedmap_close(sm);
            sm = sharedmap_open(path, NULL);
            assert_int_equal(sharedmap_load_report(sm)->nranges, 0);
            assert_int_equal(sharedmap_load_report(sm)->torn_bytes, 0);
            assert_map_is(sm, &lg);
        } else {
            assert_int_equal(naside, 0);
        }
        sharedmap_close(sm);
    }
    printf("# %d rounds: %d with damage reported (%lld records lost), %d counted exactly, %d at the end\n",
           ROUNDS, rounds_damaged, (long long)lost, rounds_exact, rounds_tail);
    assert_true(rounds_exact > ROUNDS / 2);
}

static void test_strict_refuses_and_leaves_the_file(void **state)
{
    log_random(&lg, 50);
    memcpy(img, lg.img, lg.len);
    img[lg.r[10].off + 28] ^= 0x80;
    write_file(path, img, lg.len);
    errno = 0;
    assert_null(sharedmap_open_flags(path, SHAREDMAP_STRICT, NULL));
    assert_int_equal(errno, EBADMSG);
    char aside[600];
    assert_int_equal(kept_aside(aside, sizeof aside), 0);
    assert_int_equal(read_file(path, back, sizeof back), lg.len);
    assert_memory_equal(back, img, lg.len);
    /* a torn tail is no damage: strict mode starts */
    write_file(path, lg.img, lg.len - 7);
    sharedmap_t *sm = sharedmap_open_flags(path, SHAREDMAP_STRICT, NULL);
    assert_non_null(sm);
    assert_int_equal(sharedmap_load_report(sm)->records, lg.n - 1);
    assert_true(sharedmap_stats(sm)->tail_bytes_dropped > 0);
    sharedmap_close(sm);
}

/* A cut on record boundaries leaves no damaged byte; the sequence numbers still tell. */
static void test_whole_records_cut_out_are_counted(void **state)
{
    log_random(&lg, 40);
    size_t a = lg.r[5].off, b = lg.r[8].off, len = lg.len - (b - a);
    memcpy(img, lg.img, a);
    memcpy(img + a, lg.img + b, lg.len - b);
    write_file(path, img, len);
    sharedmap_t *sm = sharedmap_open(path, NULL);
    const sharedmap_replay_t *rep = sharedmap_load_report(sm);
    assert_int_equal(rep->records_skipped, 3);
    assert_int_equal(rep->bytes_skipped, 0);
    assert_int_equal(rep->ranges[0].off, (int64_t)a);
    sharedmap_close(sm);
}

/* Damage that removes nothing: a record written twice, bytes inserted between two records,
 * two records swapped. Every record is intact and must be replayed, in sequence order (the
 * swapped pair sets one key, so the order shows in the value); the reader used to accept
 * after damage only a record whose number skipped one, and lost the intact record after it. */
static size_t image_with(int kind, smd_log_t *l, uint8_t *out)
{
    smd_init(l);
    for (int i = 0; i < 30; i++) {
        uint8_t data[16];
        char key[16];
        memset(data, i, sizeof data);
        snprintf(key, sizeof key, "key%02d", i == 11 ? 10 : i);   /* 10 and 11 set one key */
        smd_add(l, SHAREDMAP_LOG_SET, key, data, sizeof data);
    }
    const smd_rec_t *a = &l->r[10], *b = &l->r[11];
    size_t n = 0;
    memcpy(out, l->img, b->off);
    n = b->off;
    if (kind == 0) {                    /* record 10 twice */
        memcpy(out + n, l->img + a->off, a->size);
        n += a->size;
    } else if (kind == 1) {             /* 37 stray bytes */
        for (int i = 0; i < 37; i++)
            out[n++] = (uint8_t)(0xA7 ^ (i * 29));
    } else {                            /* 11 before 10 */
        n = a->off;
        memcpy(out + n, l->img + b->off, b->size);
        memcpy(out + n + b->size, l->img + a->off, a->size);
        n += a->size + b->size;
    }
    memcpy(out + n, l->img + b->off + (kind == 2 ? b->size : 0), l->len - b->off - (kind == 2 ? b->size : 0));
    return n + l->len - b->off - (kind == 2 ? b->size : 0);
}

static void test_damage_that_removes_nothing_keeps_every_record(void **state)
{
    static const char *what[] = { "a record written twice", "bytes inserted between records",
                                  "two records swapped" };
    for (int kind = 0; kind < 3; kind++) {
        clean_dir();
        size_t len = image_with(kind, &lg, img);
        write_file(path, img, len);
        sharedmap_t *sm = sharedmap_open(path, NULL);
        assert_non_null(sm);
        print_message("%s: %lld records replayed, %lld lost\n", what[kind],
                      (long long)sharedmap_load_report(sm)->records,
                      (long long)sharedmap_load_report(sm)->records_skipped);
        assert_map_is(sm, &lg);         /* all 30, in their order */
        const sharedmap_replay_t *rep = sharedmap_load_report(sm);
        assert_int_equal(rep->records, 30);
        assert_int_equal(rep->records_skipped, 0);
        assert_int_equal(rep->duplicates, kind == 0);
        assert_int_equal(rep->bytes_skipped, kind == 1 ? 37 : 0);
        assert_int_equal(rep->reordered, kind == 2);
        /* still damage: kept aside as found, the log rewritten clean */
        char aside[600];
        assert_int_equal(kept_aside(aside, sizeof aside), 1);
        sharedmap_close(sm);
        sm = sharedmap_open(path, NULL);
        assert_false(sharedmap_log_damaged(sharedmap_load_report(sm)));
        assert_map_is(sm, &lg);
        sharedmap_close(sm);
    }
}

typedef struct {
    char kind[64];
    int64_t severity;
    char text[600];
} last_event_t;

static void note_event(void *user, ca_note_kind_t kind, const char *counter, int64_t n, const char *text)
{
    last_event_t *e = user;
    if (kind != CA_NOTE_EVENT)
        return;
    snprintf(e->kind, sizeof e->kind, "%s", counter);
    e->severity = n;
    snprintf(e->text, sizeof e->text, "%s", text ? text : "");
}

/* The SharedMap notes the last record it acknowledged (beside the log, in FILE.lock): a log
 * cut after a clean stop lost acknowledged records, which a torn tail alone would pass off
 * as the write a crash cut short. That is damage, at warn. */
static void test_acknowledged_records_cut_off_are_damage(void **state)
{
    for (int whole = 0; whole < 2; whole++) {
        clean_dir();
        sharedmap_t *sm = sharedmap_open(path, NULL);
        assert_non_null(sm);
        size_t last = 0;
        for (int i = 0; i < 6; i++) {
            uint8_t buf[64];
            char key[16];
            marie_pose2d_t p = { .x = i };
            snprintf(key, sizeof key, "k%d", i);
            int n = marie_pose2d_t_encode(buf, 0, sizeof buf, &p);
            last = file_size(path);
            assert_int_equal(sharedmap_set(sm, key, "marie.pose2d_t", buf, (size_t)n, i), 0);
        }
        sharedmap_close(sm);
        /* the last record loses its end, or goes whole */
        assert_int_equal(truncate(path, whole ? (off_t)last : (off_t)file_size(path) - 5), 0);
        last_event_t ev = { "" };
        ca_sink_t sink = { .note = note_event, .user = &ev };
        sm = sharedmap_open(path, &sink);
        assert_non_null(sm);
        const sharedmap_replay_t *rep = sharedmap_load_report(sm);
        print_message("%s\n", ev.text);
        assert_int_equal(sharedmap_size(sm), 5);
        assert_int_equal(rep->acked_lost, 1);
        assert_int_equal(rep->records_skipped, 1);
        assert_int_equal(rep->torn_bytes, 0);
        assert_string_equal(ev.kind, "sharedmap_log_damaged");
        assert_int_equal(ev.severity, MARIE_EVENT_T_SEV_WARN);
        assert_non_null(strstr(ev.text, "1 acknowledged"));
        char aside[600];
        assert_int_equal(kept_aside(aside, sizeof aside), 1);
        sharedmap_close(sm);
    }
}

/* Logs written before records carried a marker are read and rewritten in today's format. */
static void test_old_format_is_read_and_migrated(void **state)
{
    uint8_t old[4096];
    size_t n = read_file("tests/data/ca/sharedmap-v1.log", old, sizeof old);
    assert_memory_equal(old, "MARIESM1", 8);
    write_file(path, old, n);
    sharedmap_t *sm = sharedmap_open(path, NULL);
    assert_non_null(sm);
    assert_int_equal(sharedmap_load_report(sm)->format, 1);
    assert_int_equal(sharedmap_size(sm), 2);
    assert_int_equal(sharedmap_version(sm), 5);
    sharedmap_value_t v;
    marie_pose2d_t p;
    assert_int_equal(sharedmap_get(sm, "robot/pose", &v), 0);
    assert_true(marie_pose2d_t_decode(v.data, 0, (int)v.len, &p) >= 0 && p.x == 10 && p.y == 20);
    assert_int_equal(sharedmap_get(sm, "mission/goal", &v), 0);
    assert_fails(sharedmap_get(sm, "dock/pose", NULL), ENOENT);
    sharedmap_close(sm);
    n = read_file(path, old, sizeof old);
    assert_memory_equal(old, sharedmap_log_magic, SHAREDMAP_LOG_MAGIC_LEN);
    sm = sharedmap_open(path, NULL);
    assert_int_equal(sharedmap_load_report(sm)->format, 2);
    assert_int_equal(sharedmap_size(sm), 2);
    sharedmap_close(sm);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_one_byte_in_record_2_loses_record_2_only, setup, teardown),
        cmocka_unit_test_setup_teardown(test_random_damage_keeps_every_untouched_record, setup, teardown),
        cmocka_unit_test_setup_teardown(test_strict_refuses_and_leaves_the_file, setup, teardown),
        cmocka_unit_test_setup_teardown(test_whole_records_cut_out_are_counted, setup, teardown),
        cmocka_unit_test_setup_teardown(test_damage_that_removes_nothing_keeps_every_record, setup, teardown),
        cmocka_unit_test_setup_teardown(test_acknowledged_records_cut_off_are_damage, setup, teardown),
        cmocka_unit_test_setup_teardown(test_old_format_is_read_and_migrated, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
