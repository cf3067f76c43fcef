/* test_config_entry: a component that reads only its own entry of the system file (the lines
 * marie-am gives it) gets the configuration the whole file gives, with the same lines in its
 * messages, and reads the whole file when the entry cannot be trusted. */
#include <dirent.h>
#include <dlfcn.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cmocka.h>

#include "core/config.h"
#include "core/file.h"

/* Every component of path (with profile) read alone as marie-am would start it: the same
 * configuration hash, the same settings, the same line of its entry. The number compared, or
 * -1 when the whole file does not load (a file made to fail). */
static int compare_file(const char *path, const char *profile)
{
    marie_errors_t e = {0};
    marie_system_t *all = marie_system_load(path, profile, &e);
    marie_errors_clear(&e);
    if (!all)
        return -1;
    size_t len;
    char *text = marie_file_read(path, 16 << 20, &len);
    assert_non_null(text);
    uint64_t h = marie_text_hash(text, len);
    free(text);
    int n = 0;
    for (size_t i = 0; i < all->ncomponents; i++) {
        const marie_component_cfg_t *a = &all->components[i];
        char spec[96];
        assert_int_equal(marie_system_entry_spec(all, a->name, h, spec, sizeof spec), 0);
        marie_system_t *one = marie_system_load_entry(path, NULL, profile, a->name, spec);
        if (!one)
            fail_msg("%s (profile %s): %s did not load alone (spec %s)", path, profile ? profile : "-", a->name, spec);
        const marie_component_cfg_t *b = marie_system_component(one, a->name);
        assert_non_null(b);
        assert_int_equal(one->ncomponents, 1);
        assert_string_equal(marie_component_hash(a), marie_component_hash(b));
        char *diff = marie_component_differences(all, a, one, b);
        assert_string_equal(diff, "");
        free(diff);
        assert_int_equal(a->line, b->line);
        assert_int_equal(a->col, b->col);
        assert_int_equal(a->ndepends, b->ndepends);
        marie_system_destroy(one);
        n++;
    }
    marie_system_destroy(all);
    return n;
}

/* Each profile of the file's `profiles:` and none. */
static int compare_profiles(const char *path)
{
    marie_errors_t e = {0};
    marie_doc_t *d = marie_doc_load(path, &e);
    marie_errors_clear(&e);
    const marie_node_t *p = d ? marie_node_get(marie_doc_root(d), "profiles") : NULL;
    int n = compare_file(path, NULL);
    for (size_t i = 0; n >= 0 && p && p->kind == MARIE_NODE_MAP && i < p->n; i++) {
        int k = compare_file(path, p->items[i]->key);
        n += k > 0 ? k : 0;
    }
    marie_doc_destroy(d);
    return n;
}

static void shipped_systems_read_alone_as_whole(void **state)
{
    int n = compare_profiles("config/spartacus.yaml") + compare_profiles("config/small-robot.yaml");
    assert_true(n > 60);
}

static void test_systems_read_alone_as_whole(void **state)
{
    static const char *const dirs[] = {"tests/data/core", "tests/data/managers", "tests/data/ca",
                                       "tests/data/viewer", "tests/data/python", "tests/data/vision", NULL};
    int files = 0, comps = 0;
    for (int k = 0; dirs[k]; k++) {
        DIR *dir = opendir(dirs[k]);
        assert_non_null(dir);
        for (struct dirent *de; (de = readdir(dir));) {
            size_t l = strlen(de->d_name);
            if (l < 6 || strcmp(de->d_name + l - 5, ".yaml") != 0)
                continue;
            char path[512];
            snprintf(path, sizeof path, "%s/%s", dirs[k], de->d_name);
            int n = compare_profiles(path);
            files += n > 0;
            comps += n > 0 ? n : 0;
        }
        closedir(dir);
    }
    assert_true(files >= 10);
    assert_true(comps >= 30);
}

static char tmp[64];

static void write_text(const char *text)
{
    FILE *f = fopen(tmp, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

static marie_system_t *load_whole(void)
{
    marie_errors_t e = {0};
    marie_system_t *s = marie_system_load(tmp, NULL, &e);
    marie_errors_print(&e, stderr);
    marie_errors_clear(&e);
    assert_non_null(s);
    return s;
}

static const char *const three =
    "system: t\nhosts: [h]\ncomponents:\n"
    "  a:\n    exec: x\n    depends: [c]\n    params: {rate: 1}\n"
    "  # a comment between entries\n"
    "  b:\n    exec: |\n      y\n    host: h\n"
    "  c: {exec: z}\n"
    "profiles:\n  p:\n    params: {a: {rate: 2}, b: {rate: 3}}\n";

/* The entry read alone is its own lines; the others, a dependency named, a profile's params for
 * them, are not read and not refused. */
static void an_entry_alone_keeps_its_lines(void **state)
{
    write_text(three);
    marie_system_t *s = load_whole();
    size_t len;
    char *text = marie_file_read(tmp, 1 << 20, &len), spec[96];
    assert_int_equal(marie_system_entry_spec(s, "a", marie_text_hash(text, len), spec, sizeof spec), 0);
    marie_system_t *one = marie_system_load_entry(tmp, "origin.yaml", "p", "a", spec);
    assert_non_null(one);
    const marie_component_cfg_t *a = marie_system_component(one, "a");
    assert_non_null(a);
    assert_null(marie_system_component(one, "b"));
    assert_int_equal(a->line, 4);
    assert_string_equal(a->file, "origin.yaml");
    const marie_node_t *rate = marie_node_get(a->params, "rate");
    assert_string_equal(rate->value, "2");
    assert_int_equal(rate->line, 16);
    marie_system_destroy(one);
    /* the last entry, on one line, up to the next key of the file */
    assert_int_equal(marie_system_entry_spec(s, "c", marie_text_hash(text, len), spec, sizeof spec), 0);
    assert_non_null(one = marie_system_load_entry(tmp, NULL, NULL, "c", spec));
    assert_string_equal(marie_system_component(one, "c")->exec, "z");
    marie_system_destroy(one);
    /* b's block scalar is its own */
    assert_int_equal(marie_system_entry_spec(s, "b", marie_text_hash(text, len), spec, sizeof spec), 0);
    assert_non_null(one = marie_system_load_entry(tmp, NULL, NULL, "b", spec));
    assert_string_equal(marie_system_component(one, "b")->exec, "y\n");
    marie_system_destroy(one);
    /* another name than the spec's: not found alone, read whole */
    assert_null(marie_system_load_entry(tmp, NULL, NULL, "zz", spec));
    free(text);
    marie_system_destroy(s);
}

/* The file changed since the manager read it: the lines may no longer be the entry's. */
static void a_changed_file_is_read_whole(void **state)
{
    write_text(three);
    marie_system_t *s = load_whole();
    size_t len;
    char *text = marie_file_read(tmp, 1 << 20, &len), spec[96];
    assert_int_equal(marie_system_entry_spec(s, "b", marie_text_hash(text, len), spec, sizeof spec), 0);
    text[len - 4] = '4';        /* profile p's b: {rate: 4} */
    FILE *f = fopen(tmp, "w");
    fwrite(text, 1, len, f);
    fclose(f);
    assert_null(marie_system_load_entry(tmp, NULL, "p", "b", spec));
    assert_null(marie_system_load_entry(tmp, NULL, "p", "b", "nonsense"));
    assert_null(marie_system_load_entry(tmp, NULL, "p", "b", NULL));
    free(text);
    marie_system_destroy(s);
}

/* An edit anywhere in the text (one byte changed, in the 8-byte steps or the tail; two bytes
 * swapped; a byte added) changes the hash the manager passes, so the entry's lines are not
 * trusted. */
static void any_edit_changes_the_text_hash(void **state)
{
    char text[] = "system: t\nhosts: [h]\ncomponents:\n  a:\n    exec: x\n";
    size_t len = strlen(text);
    uint64_t h = marie_text_hash(text, len);
    for (size_t i = 0; i < len; i++) {
        char was = text[i];
        text[i] ^= 0x01;
        assert_true(marie_text_hash(text, len) != h);
        text[i] = was;
        if (i + 1 < len && text[i] != text[i + 1]) {
            text[i] = text[i + 1], text[i + 1] = was;
            assert_true(marie_text_hash(text, len) != h);
            text[i + 1] = text[i], text[i] = was;
        }
    }
    assert_true(marie_text_hash(text, len - 1) != h);
    assert_int_equal(marie_text_hash(text, len), h);
}

/* Entries that share lines cannot be cut apart by lines: no spec, the whole file is read. */
static void entries_sharing_lines_have_no_spec(void **state)
{
    write_text("system: t\nhosts: [h]\ncomponents: {a: {exec: x}, b: {exec: y}}\n");
    marie_system_t *s = load_whole();
    char spec[96];
    assert_int_equal(marie_system_entry_spec(s, "a", 1, spec, sizeof spec), -1);
    marie_system_destroy(s);
    write_text("system: t\nhosts: [h]\ncomponents:\n  a: {exec: x}\n  b: {exec: y}\n");
    s = load_whole();
    assert_int_equal(marie_system_entry_spec(s, "a", 1, spec, sizeof spec), 0);
    assert_int_equal(marie_system_entry_spec(s, "a", 1, spec, 8), -1);     /* too small */
    marie_system_destroy(s);
}

static bool libfyaml_mapped(void)
{
    void *lib = dlopen("libfyaml.so.0", RTLD_LAZY | RTLD_NOLOAD);
    if (lib)
        dlclose(lib);
    return lib != NULL;
}

/* A component's start reads its entry: in the plain block YAML of marie-am's usual files, without
 * mapping libfyaml at all (core/config_plain.c); anything else through libfyaml as before. */
static void a_plain_entry_is_read_without_libfyaml(void **state)
{
    write_text("system: t   # plain\nhosts: [h]\ncomponents:\n"
               "  a:\n    exec: /usr/bin/x\n    host: h\n    stop_timeout: 1\n"
               "  b:\n    exec: /usr/bin/y\n    host: h\n    depends: [a]\n    params:\n      rate: 2.5\n");
    marie_yaml_unload();
    assert_false(libfyaml_mapped());
    marie_system_t *s = load_whole();
    size_t len;
    char *text = marie_file_read(tmp, 1 << 20, &len), spec[96];
    assert_int_equal(marie_system_entry_spec(s, "b", marie_text_hash(text, len), spec, sizeof spec), 0);
    marie_system_t *one = marie_system_load_entry(tmp, NULL, NULL, "b", spec);
    assert_non_null(one);
    const marie_node_t *rate = marie_node_get(marie_system_component(one, "b")->params, "rate");
    assert_string_equal(rate->value, "2.5");
    assert_int_equal(rate->line, 13);
    assert_int_equal(rate->col, 13);
    assert_false(libfyaml_mapped());
    marie_system_destroy(one);
    marie_system_destroy(s);
    free(text);
    write_text(three);          /* flow mappings, a block scalar: libfyaml's */
    marie_system_destroy(load_whole());
    assert_true(libfyaml_mapped());
    marie_yaml_unload();
}

int main(void)
{
    snprintf(tmp, sizeof tmp, "/tmp/test_config_entry_%d.yaml", (int)getpid());
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(shipped_systems_read_alone_as_whole),
        cmocka_unit_test(test_systems_read_alone_as_whole),
        cmocka_unit_test(an_entry_alone_keeps_its_lines),
        cmocka_unit_test(a_changed_file_is_read_whole),
        cmocka_unit_test(any_edit_changes_the_text_hash),
        cmocka_unit_test(entries_sharing_lines_have_no_spec),
        cmocka_unit_test(a_plain_entry_is_read_without_libfyaml),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    unlink(tmp);
    return rc;
}
