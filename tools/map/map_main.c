/* marie-map: `marie map save NAME` waits for the next map on the bus (marie.occupancy_grid_t)
 * and writes it as NAME.yaml + NAME.pgm, which the localizer, planner and simulator load;
 * `marie map compare BUILT WORLD` judges a built map against the world it was built in;
 * `marie map eval RUN.lcm` scores a recorded run's poses against a reference (map_eval.c). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <lcm/lcm.h>

#include "core/config.h"
#include "core/loop.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_occupancy_grid_t.h"
#include "proto/am_proto.h"
#include "map/mapeval.h"
#include "map/occmap.h"
#include "core/version.h"
#include "tools/map/map_tool.h"

typedef struct {
    marie_occupancy_grid_t grid;
    bool have;
    int bad;
} mapsave_t;

static void on_map(const lcm_recv_buf_t *rbuf, const char *channel, void *user)
{
    mapsave_t *s = user;
    if (s->have)
        return;
    marie_occupancy_grid_t g;
    if (marie_decode_input(&marie_type_occupancy_grid_t, rbuf->data, rbuf->data_size, &g, NULL) != 0) {
        s->bad++;
        return;
    }
    if (g.width <= 0 || g.height <= 0 || (int64_t)g.width * g.height != g.ncells || !(g.resolution > 0) ||
        (int64_t)g.width * g.height > (1 << 28)) {
        s->bad++;
        marie_type_occupancy_grid_t.decode_cleanup(&g);
        return;
    }
    s->grid = g;
    s->have = true;
}

/* A map is larger than the kernel's default socket buffer holds: ask for more unless the URL
 * already says how much. */
static char *url_with_buffer(const char *url)
{
    size_t n = strlen(url) + 64;
    char *u = malloc(n);
    if (!u)
        return NULL;
    if (strncmp(url, "udpm://", 7) != 0 || strstr(url, "recv_buf_size"))
        snprintf(u, n, "%s", url);
    else
        snprintf(u, n, "%s%srecv_buf_size=8388608", url, strchr(url, '?') ? "&" : "?");
    return u;
}

static int usage_to(FILE *out, int status)
{
    fprintf(out, "usage: marie map save NAME [--channel MAP] [--wait S] [--url URL]\n"
                    "  writes NAME.yaml and NAME.pgm from the next map on the channel\n"
                    "       marie map compare BUILT.yaml WORLD.yaml [--start X Y]\n"
                    "  precision and recall of BUILT's occupied cells against WORLD's walls (within one\n"
                    "  cell), coverage of WORLD's free space reachable from (X, Y) (default 0 0);\n"
                    "  then the same after the best alignment within 0.5 m and 0.03 rad\n"
                    "       marie map eval RUN.lcm [--reference LOG] [--png FILE] [--format json] ...\n"
                    "  the mapper's POSE in RUN against a reference trajectory (REFERENCE): ATE after\n"
                    "  the best rigid alignment, relation errors over 1 m and 5 m of path (--help: all options)\n");
    return status;
}

static int usage(void) { return usage_to(stderr, MARIE_EXIT_USAGE); }

static int write_map(const marie_occupancy_grid_t *g, const char *name)
{
    occmap_t *m = occmap_from_cells(g->width, g->height, g->resolution, g->origin.x, g->origin.y, g->origin.theta,
                                    g->cells);
    if (!m) {
        fprintf(stderr, "marie: map save: cannot use the map: %s\n", strerror(errno));
        return MARIE_EXIT_FAIL;
    }
    size_t len = strlen(name);
    char *yaml = malloc(len + 6);
    int rc = MARIE_EXIT_FAIL;
    if (!yaml)
        goto out;
    snprintf(yaml, len + 6, "%s%s", name, len > 5 && strcmp(name + len - 5, ".yaml") == 0 ? "" : ".yaml");
    if (occmap_save(m, yaml) != 0) {
        fprintf(stderr, "marie: map save: %s: %s\n", yaml, strerror(errno));
        goto out;
    }
    long occ = 0, fr = 0, unk = 0;
    for (size_t i = 0; i < (size_t)m->width * m->height; i++) {
        int8_t v = m->cells[i];
        uint8_t px = occmap_save_pixel(v);
        occ += px == 0 || (v >= 65 && v <= 100);
        fr += v >= 0 && v < 20;
        unk += v < 0 || v > 100 || (v >= 20 && v < 65);
    }
    printf("map saved: %s (%d x %d cells at %.3f m, origin %.2f %.2f): %ld occupied, %ld free, %ld unknown\n", yaml,
           m->width, m->height, m->resolution, m->origin_x, m->origin_y, occ, fr, unk);
    rc = MARIE_EXIT_OK;
out:
    free(yaml);
    occmap_destroy(m);
    return rc;
}

static int have_map(void *user) { return ((mapsave_t *)user)->have; }

static int compare(int argc, char **argv)
{
    const char *built_path = NULL, *world_path = NULL;
    double sx = 0, sy = 0;
    for (int i = 2; i < argc; i++) {
        if (strcmp(argv[i], "--start") == 0 && i + 2 < argc) {
            sx = atof(argv[++i]);
            sy = atof(argv[++i]);
        } else if (argv[i][0] != '-' && !built_path) {
            built_path = argv[i];
        } else if (argv[i][0] != '-' && !world_path) {
            world_path = argv[i];
        } else {
            return usage();
        }
    }
    if (!built_path || !world_path)
        return usage();
    marie_errors_t errs = { 0 };
    occmap_t *built = occmap_load(built_path, &errs), *world = built ? occmap_load(world_path, &errs) : NULL;
    int rc = MARIE_EXIT_FAIL;
    if (!built || !world) {
        marie_errors_print(&errs, stderr);
        goto out;
    }
    mapeval_judgement_t j;
    if (mapeval_judge(world, built, sx, sy, &j) < 0) {
        fprintf(stderr, "marie: map compare: out of memory\n");
        goto out;
    }
    printf("precision %.3f recall %.3f coverage %.3f (built occupied %ld, visible walls %ld, reachable free %ld)\n",
           j.raw.precision, j.raw.recall, j.raw.coverage, j.raw.map_occupied, j.raw.truth_walls, j.raw.truth_free);
    printf("aligned by (%.2f m, %.2f m, %.3f rad): aprecision %.3f arecall %.3f acoverage %.3f\n", j.dx, j.dy, j.th,
           j.aligned.precision, j.aligned.recall, j.aligned.coverage);
    rc = MARIE_EXIT_OK;
out:
    marie_errors_clear(&errs);
    occmap_destroy(built);
    occmap_destroy(world);
    return rc;
}

int main(int argc, char **argv)
{
    marie_version_exit("marie-map", argc, argv);
    if (argc >= 2 && strcmp(argv[1], "eval") == 0)
        return map_eval_main(argc - 1, argv + 1);      /* its own options, --help among them */
    for (int i = 1; i < argc; i++)
        if (strcmp(argv[i], "--help") == 0)
            return usage_to(stdout, MARIE_EXIT_OK);
    const char *channel = "MAP", *name = NULL;
    const char *url = getenv("LCM_DEFAULT_URL") ? getenv("LCM_DEFAULT_URL") : marie_default_url();
    double wait_s = 6;          /* the mapper sends its map again every 5 s */
    if (argc >= 2 && strcmp(argv[1], "compare") == 0)
        return compare(argc, argv);
    if (argc < 3 || strcmp(argv[1], "save") != 0)
        return usage();
    for (int i = 2; i < argc; i++) {
        if (strcmp(argv[i], "--channel") == 0 && i + 1 < argc)
            channel = argv[++i];
        else if (strcmp(argv[i], "--url") == 0 && i + 1 < argc)
            url = argv[++i];
        else if (strcmp(argv[i], "--wait") == 0 && i + 1 < argc)
            wait_s = atof(argv[++i]);
        else if (argv[i][0] != '-' && !name)
            name = argv[i];
        else
            return usage();
    }
    if (!name || !*name || !(wait_s > 0))
        return usage();
    char *u = url_with_buffer(url);
    lcm_t *lcm = u ? marie_bus_create(u) : NULL;
    free(u);
    if (!lcm) {
        fprintf(stderr, "marie: map save: cannot open the bus at %s\n", url);
        return MARIE_EXIT_FAIL;
    }
    mapsave_t s = { 0 };
    marie_bus_subscribe(lcm, channel, on_map, &s);
    marie_loop_t *loop = marie_loop_create();
    if (!loop || marie_loop_add_bus(loop, lcm, 1) < 0) {
        fprintf(stderr, "marie: map save: out of memory\n");
        marie_loop_destroy(loop);
        marie_bus_destroy(lcm);
        return MARIE_EXIT_FAIL;
    }
    marie_loop_run_until(loop, wait_s > 86400 ? 86400000 : (int)(wait_s * 1000), have_map, &s);
    marie_loop_destroy(loop);
    marie_bus_destroy(lcm);
    if (!s.have) {
        fprintf(stderr, "marie: map save: no map on %s within %.1f s%s\n", channel, wait_s,
                s.bad ? " (malformed maps were refused)" : "");
        return MARIE_EXIT_TIMEOUT;
    }
    int rc = write_map(&s.grid, name);
    marie_type_occupancy_grid_t.decode_cleanup(&s.grid);
    return rc;
}
