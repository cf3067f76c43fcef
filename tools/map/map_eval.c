/* map_eval: `marie map eval RUN.lcm`: the mapper's poses (POSE) recorded in RUN scored against a
 * reference trajectory (REFERENCE: an imported log's own estimate, or any pose_cov_t channel): ATE
 * after the best rigid SE(2) alignment, relation errors over 1 m and 5 m of path; and the run's
 * last map drawn with both trajectories (docs/mapping.md, "Scoring a robot's log"). */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <getopt.h>

#include "core/buf.h"
#include "core/cli.h"
#include "core/lcmlog.h"
#include "core/typeinfo.h"
#include "lcmtypes/marie_types.h"
#include "proto/am_proto.h"
#include "map/occmap.h"
#include "map/trajeval.h"
#include "tools/map/map_tool.h"

typedef struct {
    const char *pose_ch, *ref_ch, *map_ch, *update_ch;
    bool want_ref, want_run;    /* what this file is read for */
    traj_pose_t *est, *ref;
    size_t nest, nref, cap_est, cap_ref;
    occmap_t *map;
    int64_t map_utime;
    int64_t bad;                /* records that did not decode, or say nothing usable */
} eval_t;

static bool is(const lcmlog_event_t *ev, const char *ch)
{
    return ch && ev->channel_len == strlen(ch) && memcmp(ev->channel, ch, ev->channel_len) == 0;
}

static int add(traj_pose_t **a, size_t *n, size_t *cap, const marie_pose_cov_t *p)
{
    if (*n && p->utime <= (*a)[*n - 1].utime)
        return 0;               /* out of order or repeated: the first of an instant counts */
    if (MARIE_GROW(*a, *cap, *n + 1) < 0)
        return -1;
    (*a)[(*n)++] = (traj_pose_t){ p->utime, p->pose.x, p->pose.y, p->pose.theta };
    return 0;
}

static void on_pose(eval_t *e, const lcmlog_event_t *ev, bool reference)
{
    marie_pose_cov_t p;
    if (marie_decode_input(&marie_type_pose_cov_t, ev->data, ev->data_len, &p, NULL) != 0) {
        e->bad++;
        return;
    }
    if (reference ? add(&e->ref, &e->nref, &e->cap_ref, &p) : add(&e->est, &e->nest, &e->cap_est, &p))
        e->bad++;
    marie_pose_cov_t_decode_cleanup(&p);
}

/* A whole map replaces the one held; an update (MAP_UPDATE) to it is written into it. */
static void on_map(eval_t *e, const lcmlog_event_t *ev)
{
    marie_occupancy_grid_t g;
    if (marie_decode_checked(&marie_type_occupancy_grid_t, ev->data, ev->data_len, &g) != 0) {
        e->bad++;
        return;
    }
    occmap_t *m = occmap_from_cells(g.width, g.height, g.resolution, g.origin.x, g.origin.y, g.origin.theta, g.cells);
    if (m) {
        occmap_destroy(e->map);
        e->map = m;
        e->map_utime = g.utime;
    } else {
        e->bad++;
    }
    marie_type_occupancy_grid_t.decode_cleanup(&g);
}

static void on_update(eval_t *e, const lcmlog_event_t *ev)
{
    marie_occupancy_grid_update_t u;
    if (marie_decode_checked(&marie_type_occupancy_grid_update_t, ev->data, ev->data_len, &u) != 0) {
        e->bad++;
        return;
    }
    occmap_t *m = e->map;
    if (m && u.map_utime == e->map_utime && u.x >= 0 && u.y >= 0 && u.width >= 0 && u.height >= 0 &&
        (int64_t)u.width * u.height == u.ncells && u.x <= m->width - u.width && u.y <= m->height - u.height)
        for (int y = 0; y < u.height; y++)
            memcpy(m->cells + (size_t)(u.y + y) * m->width + u.x, u.cells + (size_t)y * u.width, (size_t)u.width);
    marie_type_occupancy_grid_update_t.decode_cleanup(&u);
}

static void on_event(void *user, const lcmlog_event_t *ev)
{
    eval_t *e = user;
    if (e->want_run && is(ev, e->pose_ch))
        on_pose(e, ev, false);
    else if (e->want_ref && is(ev, e->ref_ch))
        on_pose(e, ev, true);
    else if (e->want_run && is(ev, e->map_ch))
        on_map(e, ev);
    else if (e->want_run && is(ev, e->update_ch))
        on_update(e, ev);
}

static int read_log(const char *path, eval_t *e)
{
    FILE *f = fopen(path, "rb");
    if (!f) {
        fprintf(stderr, "marie: map eval: %s: %s\n", path, strerror(errno));
        return -1;
    }
    lcmlog_parser_t *lp = lcmlog_parser_create(on_event, NULL, e);
    unsigned char buf[65536];
    size_t got;
    int rc = lp ? 0 : -1;
    while (rc == 0 && (got = fread(buf, 1, sizeof buf, f)) > 0)
        rc = lcmlog_parser_feed(lp, buf, got);
    if (lp) {
        lcmlog_parser_finish(lp);
        if (lcmlog_parser_stats(lp)->corrupt)
            fprintf(stderr, "marie: map eval: %s: %lld damaged stretches skipped\n", path,
                    (long long)lcmlog_parser_stats(lp)->corrupt);
    }
    lcmlog_parser_destroy(lp);
    fclose(f);
    return rc;
}

static void print_text(const trajeval_t *t, size_t nest, size_t nref)
{
    printf("%zu poses, %zu paired with the %zu of the reference (%.1f m of reference path)\n", nest, t->pairs, nref,
           t->path);
    printf("ATE %.3f m RMS, %.3f m max, after aligning by (%.3f m, %.3f m, %.4f rad)\n", t->ate_rms, t->ate_max,
           t->align[0], t->align[1], t->align[2]);
    for (int i = 0; i < t->nrel; i++)
        printf("relation error over %g m of path: %.4f m, %.4f rad mean (max %.3f m, %.3f rad) over %zu relations\n",
               t->rel[i].dist, t->rel[i].trans_mean, t->rel[i].rot_mean, t->rel[i].trans_max, t->rel[i].rot_max,
               t->rel[i].n);
}

static void print_json(const trajeval_t *t, size_t nest, size_t nref, const char *png)
{
    printf("{\"poses\": %zu, \"reference\": %zu, \"pairs\": %zu, \"path\": %.3f, \"ate_rms\": %.4f, \"ate_max\": %.4f, "
           "\"re1\": %.5f, \"re1_rot\": %.5f, \"re5\": %.5f, \"re5_rot\": %.5f, \"picture\": \"%s\"}\n",
           nest, nref, t->pairs, t->path, t->ate_rms, t->ate_max, t->rel[0].trans_mean, t->rel[0].rot_mean,
           t->rel[1].trans_mean, t->rel[1].rot_mean, png ? png : "");
}

/* The scores of the paired poses, and the picture. */
static int score(eval_t *e, const char *png, bool json)
{
    traj_pose_t *pe = malloc((e->nest + 1) * sizeof *pe), *pr = malloc((e->nest + 1) * sizeof *pr);
    int rc = MARIE_EXIT_FAIL;
    trajeval_t t;
    const double d[2] = { 1, 5 };
    size_t n = pe && pr ? trajeval_pair(e->est, e->nest, e->ref, e->nref, 500000, pe, pr) : 0;
    if (trajeval_run(pe, pr, n, d, 2, &t) < 0) {
        fprintf(stderr, "marie: map eval: %zu poses and %zu reference poses, %zu at the same instants: too few to score\n",
                e->nest, e->nref, n);
        goto out;
    }
    if (png && !e->map)
        fprintf(stderr, "marie: map eval: no map in the run: no picture\n");
    if (png && e->map && map_picture_write(png, e->map, pe, pr, n, t.align) < 0) {
        fprintf(stderr, "marie: map eval: %s: cannot write the picture\n", png);
        goto out;
    }
    json ? print_json(&t, e->nest, e->nref, e->map ? png : NULL) : print_text(&t, e->nest, e->nref);
    rc = MARIE_EXIT_OK;
out:
    free(pe);
    free(pr);
    return rc;
}

int map_eval_main(int argc, char **argv)
{
    eval_t e = { .pose_ch = "POSE", .ref_ch = "REFERENCE", .map_ch = "MAP", .update_ch = "MAP_UPDATE" };
    const char *ref_file = NULL, *png = NULL;
    const char *format = "text";
    const marie_cli_opt_t opts[] = {
        { "reference", MARIE_CLI_STRING, &ref_file, 0, 0, "LOG  where the reference trajectory is (default: RUN itself)" },
        { "pose", MARIE_CLI_STRING, &e.pose_ch, 0, 0, "CH   the mapper's poses (POSE)" },
        { "ref", MARIE_CLI_STRING, &e.ref_ch, 0, 0, "CH   the reference's poses (REFERENCE)" },
        { "map", MARIE_CLI_STRING, &e.map_ch, 0, 0, "CH   the mapper's map (MAP, and MAP_UPDATE)" },
        { "png", MARIE_CLI_STRING, &png, 0, 0, "FILE the map with both trajectories, as PNG" },
        { "format", MARIE_CLI_STRING, &format, 0, 0, "F    text, or json: the figures as one JSON object" },
        { NULL },
    };
    int rc = marie_cli_parse("marie map eval", opts, argc, argv);
    if (rc >= 0)
        return rc;
    bool json = strcmp(format, "json") == 0;
    if (optind != argc - 1 || (!json && strcmp(format, "text") != 0)) {
        fprintf(stderr, "usage: marie map eval RUN.lcm [OPTION VALUE]...\n");
        marie_cli_usage("marie map eval", opts, stderr);
        return MARIE_EXIT_USAGE;
    }
    const char *run = argv[optind];
    e.want_run = true;
    e.want_ref = !ref_file;
    rc = read_log(run, &e) < 0 ? MARIE_EXIT_FAIL : MARIE_EXIT_OK;
    if (rc == MARIE_EXIT_OK && ref_file) {
        e.want_run = false;
        e.want_ref = true;
        rc = read_log(ref_file, &e) < 0 ? MARIE_EXIT_FAIL : MARIE_EXIT_OK;
    }
    if (e.bad)
        fprintf(stderr, "marie: map eval: %lld records refused (not decodable, or out of order)\n", (long long)e.bad);
    if (rc == MARIE_EXIT_OK)
        rc = score(&e, png, json);
    free(e.est);
    free(e.ref);
    occmap_destroy(e.map);
    return rc;
}
