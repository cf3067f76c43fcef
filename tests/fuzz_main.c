/* fuzz_main: replays a fuzz target's seed corpus (tests/data/fuzz/NAME/) and a fixed number of
 * seeded random mutations of it, so every make test exercises the parser under ASan/UBSan.
 * It is one case per target: OK means no crash, no sanitizer report and no broken property
 * (targets abort() when one of their invariants fails); no corpus is a failure. */
#include <dirent.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static size_t load(const char *path, uint8_t **out)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return 0;
    size_t cap = 4096, n = 0;
    uint8_t *buf = malloc(cap);
    size_t r;
    while (buf && (r = fread(buf + n, 1, cap - n, f)) > 0) {
        n += r;
        if (n == cap) {
            uint8_t *nb = realloc(buf, cap *= 2);
            if (!nb) { free(buf); buf = NULL; n = 0; break; }
            buf = nb;
        }
    }
    fclose(f);
    *out = buf;
    return n;
}

int main(int argc, char **argv)
{
    const char *name = strrchr(argv[0], '/');
    name = name ? name + 1 : argv[0];
    if (strncmp(name, "fuzz_", 5) == 0)
        name += 5;
    char dir[512];
    snprintf(dir, sizeof dir, "%s", argc > 1 ? argv[1] : "");
    if (!dir[0])
        snprintf(dir, sizeof dir, "tests/data/fuzz/%s", name);
    int iterations = getenv("FUZZ_ITERATIONS") ? atoi(getenv("FUZZ_ITERATIONS")) : 20000;

    uint8_t *seeds[256];
    size_t lens[256];
    int nseeds = 0;
    DIR *d = opendir(dir);
    struct dirent *e;
    while (d && (e = readdir(d)) && nseeds < 256) {
        if (e->d_name[0] == '.')
            continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        lens[nseeds] = load(path, &seeds[nseeds]);
        if (seeds[nseeds])
            nseeds++;
    }
    if (d)
        closedir(d);
    printf("[ RUN      ] %s corpus (%d files in %s)\n", name, nseeds, dir);
    if (nseeds == 0) {
        /* mutations of nothing are random bytes: a target whose corpus went missing would
         * quietly stop exercising anything past its first check */
        printf("[  FAILED  ] %s corpus: no seed files in %s\n", name, dir);
        return 1;
    }
    for (int i = 0; i < nseeds; i++)
        LLVMFuzzerTestOneInput(seeds[i], lens[i]);

    /* Mutations: byte flips, truncations, splices and random bytes, from a fixed seed. */
    srand(12345);
    uint8_t *buf = malloc(65536);
    for (int it = 0; buf && it < iterations; it++) {
        size_t n;
        if (nseeds == 0 || rand() % 8 == 0) {
            n = (size_t)(rand() % 512);
            for (size_t k = 0; k < n; k++)
                buf[k] = (uint8_t)rand();
        } else {
            int s = rand() % nseeds;
            n = lens[s] < 65536 ? lens[s] : 65536;
            memcpy(buf, seeds[s], n);
            int edits = 1 + rand() % 8;
            for (int k = 0; k < edits && n > 0; k++) {
                switch (rand() % 4) {
                case 0: buf[rand() % n] ^= (uint8_t)(1u << (rand() % 8)); break;
                case 1: buf[rand() % n] = (uint8_t)rand(); break;
                case 2: n = (size_t)rand() % n; break;
                case 3: { int o = rand() % nseeds; size_t at = (size_t)rand() % n;
                          size_t m = lens[o] < 65536 - at ? lens[o] : 65536 - at;
                          memcpy(buf + at, seeds[o], m); if (at + m > n) n = at + m; } break;
                }
            }
        }
        LLVMFuzzerTestOneInput(buf, n);
    }
    free(buf);
    for (int i = 0; i < nseeds; i++)
        free(seeds[i]);
    printf("[       OK ] %s corpus (%d files) and %d mutations\n", name, nseeds, iterations);
    return 0;
}
